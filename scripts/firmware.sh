#!/usr/bin/env bash
# The main job: build the echoloc firmware for the default board (QEMU
# mps2-an386, Cortex-M4F), run it under QEMU (bounded by `timeout` in the
# runner), and print its findings, then its flash/RAM sizes.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

target=thumbv7em-none-eabihf
# Its findings are printed whether it passes or not: a failing run's FAIL
# lines are the reason (under `set -e` a bare `out=$(…)` would exit first).
status=0
out=$(cargo run -q -p qemu-mps2-an386 --target "$target" --release) || status=$?
echo "$out"
if [ "$status" -ne 0 ]; then
  echo "FAIL: the firmware run exited with status $status (its lines above say why)" >&2
  exit "$status"
fi
echo
echo "budgets (issue #11) against the committed snapshot:"
bash scripts/metrics.sh <<<"$out"
elf="target/$target/release/qemu-mps2-an386"
host=$(rustc -vV | sed -n 's/^host: //p')
size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
echo "sizes of $elf (text = flash code+rodata, data = flash and RAM, bss = RAM):"
"$size" -A "$elf" | awk 'NR<=2 || /^\.(vector_table|text|rodata|data|bss|uninit)/'
