#!/usr/bin/env bash
# Records with one `servo` and replays with another: every data channel must be identical, bit
# for bit (`servo replay` re-runs a recording from its embedded configuration, seed and input
# files and compares). For a change that must not change what runs compute:
#   scripts/same_recordings.sh /path/to/old/servo target/release/servo
set -euo pipefail
old=$(realpath "$1") new=$(realpath "$2") here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d) && trap 'rm -rf "$work"' EXIT && cd "$work"
printf '[run]\npractice_seed = 7\nduration_s = 0.2\n' > practice.toml
record() { # NAME ARGS...: the old servo records NAME.mcap
  local name=$1; shift
  "$old" "$@" > "$name.txt" 2>&1 || { cat "$name.txt"; exit 1; }
}
record run run -q --duration 0.2 --out run.mcap
record sine run -q -c "$here/examples/sine_heavy_stage.toml" --duration 0.2 --out sine.mcap
record cut run -q -c "$here/examples/intermittent_cut.toml" --duration 0.2 --out cut.mcap
record zpetc run -q --duration 0.2 --feedforward zpetc --scenario sine --amplitude 1e-6 \
  --frequency 500 --out zpetc.mcap
record practice run -q -c practice.toml --out practice.mcap
record hil run --hil --duration 0.2 --out hil.mcap
record machine machine --duration 0.3 --out-dir machine
record prescription machine -c "$here/examples/prescriptions/cut-gentle.toml" --duration 0.3 \
  --out-dir prescription
for f in run sine cut zpetc practice hil machine/machine prescription/machine; do
  report=$("$new" replay "$f.mcap" --out "$f.replayed.mcap")
  line=$(grep "data channels" <<< "$report") design=$(grep "  design " <<< "$report" || true)
  echo "$f.mcap:$line"
  echo "$f.mcap:$design"
  # The replay runs the recorded deployment: a design that changed form shows only here.
  ! grep -q "another form" <<< "$design" || { echo "the design changed form: $f"; exit 1; }
  grep -q "identical, bit for bit" <<< "$line" || { echo "differs: $f"; exit 1; }
done
echo "every recording of $old replays bit for bit with $new"
