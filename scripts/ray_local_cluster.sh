#!/usr/bin/env bash
# A Ray cluster on this machine, started as a multi-node cluster's head node is (`ray start
# --head`), for the Ray tests and the study bench.
#   scripts/ray_local_cluster.sh start [CPUS]   prints "ADDRESS TEMP_DIR" (a private temp folder)
#   scripts/ray_local_cluster.sh stop TEMP_DIR  stops it and removes the folder
set -euo pipefail
case "${1:-}" in
start)
    # Token authentication (RAY_AUTH_MODE=token, as the tests run it) needs a token before the
    # head starts; Ray makes one the first time it is asked.
    if [ "${RAY_AUTH_MODE:-}" = token ] && [ -z "${RAY_AUTH_TOKEN:-}" ] &&
        [ ! -s "${RAY_AUTH_TOKEN_PATH:-$HOME/.ray/auth_token}" ]; then
        ray get-auth-token --generate >/dev/null
    fi
    dir=$(mktemp -d)
    chmod 700 "$dir"
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])')
    ip=$(python3 -c 'import socket; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.connect(("192.0.2.1", 9)); print(s.getsockname()[0])' 2>/dev/null || echo 127.0.0.1)
    ray start --head --node-ip-address "$ip" --port "$port" --num-cpus "${2:-2}" \
        --temp-dir "$dir" --include-dashboard false --disable-usage-stats >"$dir/start.log" 2>&1 ||
        { cat "$dir/start.log" >&2; exit 1; }
    echo "$ip:$port $dir"
    ;;
stop)
    ray stop --force >/dev/null 2>&1 || true
    [ -n "${2:-}" ] && rm -rf "$2"
    ;;
*)
    echo "usage: $0 start [CPUS] | stop TEMP_DIR" >&2
    exit 2
    ;;
esac
