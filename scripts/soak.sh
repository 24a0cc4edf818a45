#!/bin/sh
# A soak of DURATION seconds (wall time): see scripts/soak.py, which does the work.
#   scripts/soak.sh 3600
exec python3 "$(dirname "$0")/soak.py" "$@"
