#!/usr/bin/env bash
# Fuzzes echoloc's input paths with cargo-fuzz (libFuzzer, nightly):
#   compiled_map  the compiled-map validator, then queries on what it accepts
#   scenario      the scenario reader, then a replay through the driver and controller
#   link_frames   the host link's decoder, both directions, with round trips
#   predict_ekf   prediction and the EKF on the real maps with arbitrary inputs
#   geojson       the GeoJSON importer and the whole map build on what it accepts
#   ros_map       the ROS map_server importer (YAML, 0x00, PGM/PNG image) and the map build
#   bag           ROS 2 bags: a whole MCAP file, and CDR messages of every topic type read
# Seeds come from the project's own files (fuzz/seeds.sh writes them into
# target/fuzz-corpus/). Installs the nightly toolchain and cargo-fuzz when
# absent. Usage: bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
# (default 20 s each, all targets). Fails on the first crash; the crash
# input is kept in fuzz/artifacts/TARGET/ to become a regression test.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-20}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(compiled_map scenario link_frames predict_ekf geojson ros_map bag)
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked
corpus=target/fuzz-corpus
bash fuzz/seeds.sh "$corpus"
for t in "${targets[@]}"; do
  mkdir -p "$corpus/$t"
  echo "== fuzz $t for $secs s"
  if ! log=$(cd fuzz && cargo +nightly fuzz run --debug-assertions "$t" "../$corpus/$t" -- -max_total_time="$secs" -print_final_stats=1 2>&1); then
    echo "$log" | tail -40
    echo "FAIL: fuzz target $t crashed; the input is in fuzz/artifacts/$t/ (make it a regression test)" >&2
    exit 1
  fi
  echo "$log" | grep -E "^#[0-9]+ +DONE|stat::number_of_executed_units|stat::peak_rss" | tail -3
done
