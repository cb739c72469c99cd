#!/usr/bin/env bash
# The benchmark's windows on the emulated Cortex-M4 (issue #13 item 4):
# `echoloc-lab bench --export-windows` writes the depot windows it timed,
# with its answers and the occupancy grid; the `bench_windows` firmware
# reads them from the flash partition at 0x0030_0000 and counts
# instructions per window for echoloc's exact nearest obstacle, its full
# prediction and a 1° Bresenham fan on the grid, checking its answers
# against the host's. Both half-angles. Deterministic (-icount shift=0).
# Usage: bash scripts/bench-m4.sh [POSES]
set -euo pipefail
cd "$(dirname "$0")/.."
poses=${1:-500}
target=thumbv7em-none-eabihf
out=target/bench-m4
mkdir -p "$out"
source scripts/lab-tool.sh
lab_build
cargo build -q -p qemu-mps2-an386 --bin bench_windows --target "$target" --release
lab=$LAB
elf=${CARGO_TARGET_DIR:-target}/$target/release/bench_windows
for half in 15 30; do
  "$lab" bench --map boards/qemu-mps2-an386/depot.map --poses "$poses" --rounds 1 --half-angles-deg "$half" \
    --export-windows "$out/windows_$half.bin" --json >"$out/host_$half.json"
  log=$(timeout 300 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
    -icount shift=0 -semihosting-config enable=on,target=native \
    -device "loader,file=$out/windows_$half.bin,addr=0x00300000" -kernel "$elf" 2>&1) || {
    echo "$log"
    echo "FAIL: bench_windows at $half deg" >&2
    exit 1
  }
  echo "== half-angle $half deg"
  echo "$log" | grep -v calibration
  python3 - "$log" <<'PY'
import sys
m = {l.split()[1]: int(l.split()[2]) for l in sys.argv[1].splitlines() if l.startswith("metric ")}
full, exact, fan = m["bench_full_insns_per_window"], m["bench_exact_insns_per_window"], m["bench_bresenham_insns_per_window"]
print(f"M4 ratios: 1-degree Bresenham fan / full prediction = {fan / full:.2f}; / exact nearest = {fan / exact:.2f}")
PY
done
