#!/usr/bin/env bash
# Remakes the fuzz targets' seed corpora (fuzz/seeds/<target>/) from our own files and tools:
# the examples, `servo config --dump`, `servo deploy`, `servo synth`, `servo frf`, a short
# recording, and the library-made images, link sessions and client frames
# (crates/fuzz-targets/examples/binary_seeds.rs).
#
# Usage: scripts/fuzz_seeds.sh   (from the repository; builds servo in release)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q --release -p servo-cli
servo=target/release/servo
seeds=fuzz/seeds
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rm -rf "$seeds"
mkdir -p "$seeds"/{run_config,prescription,controller_file,frf_csv,deployment,c_abi_open_toml,mcap}

cp examples/*.toml "$seeds/run_config/"
$servo config --dump > "$seeds/run_config/dump.toml"
$servo config --dump -c examples/intermittent_cut.toml > "$seeds/run_config/intermittent_cut-dump.toml"

cp examples/prescriptions/gentle.toml "$seeds/prescription/"
{ cat examples/prescriptions/cut-gentle.toml; printf '#--gentle.toml--\n'; cat examples/prescriptions/gentle.toml; } \
  > "$seeds/run_config/cut-gentle.toml"
{
  printf 'aperture_radius_mm = 1.0\n[base]\nradius_mm = 100.0\nconic = -1.0\n'
  printf '[grid]\npath = "grid.csv"\npitch_mm = [1.0, 1.0]\n'
  printf '#--grid.csv--\n'
  printf '0,0,0,0\n0,0.001,0.001,0\n0,0.001,0.001,0\n0,0,0,0\n'
} > "$seeds/prescription/with-grid.toml"

$servo deploy -o "$work/pid.toml" > /dev/null
$servo deploy -c examples/h2_at_20khz.toml -o "$work/pid-20khz.toml" > /dev/null
$servo synth h2 -o "$seeds/controller_file/h2.toml" > /dev/null
$servo deploy --controller ss --ss-file "$seeds/controller_file/h2.toml" -o "$work/h2.toml" > /dev/null
cp "$work"/{pid,pid-20khz,h2}.toml "$seeds/deployment/"
cp "$work"/{pid,pid-20khz,h2}.toml "$seeds/c_abi_open_toml/"
(cd "$work" && "$OLDPWD/$servo" tune -o tuned.toml > /dev/null)
cp "$work/tuned.toml" "$seeds/controller_file/"

$servo frf --loop open --points 40 --out-dir "$work/frf" > /dev/null
cp "$work"/frf/*.csv "$seeds/frf_csv/"

$servo run --duration 0.002 -o "$seeds/mcap/short.mcap" > /dev/null
cp crates/recorder/tests/data/v5_sine.mcap "$seeds/mcap/"

cargo run -q --release -p fuzz-targets --example binary_seeds -- "$seeds" "$work"/{pid,pid-20khz,h2}.toml
find "$seeds" -type f | sort | xargs wc -c | tail -n 1
