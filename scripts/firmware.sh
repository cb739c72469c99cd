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
# No soft double precision on the M4F (2026-12-02: 4.7 KiB of flash went to
# it): a `f64` in the core's firmware paths links `__aeabi_d*` and fails here.
nm="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-nm"
soft=$("$nm" "$elf" | grep -E ' __aeabi_d|__(add|sub|mul|div)df3| (sqrt|floor|ceil|round|trunc)$' || true)
if [ -n "$soft" ]; then
  echo "FAIL: $elf links soft f64 (keep the firmware's arithmetic f32 or integer):" >&2
  echo "$soft" >&2
  exit 1
fi
echo "no soft f64 in $elf"
