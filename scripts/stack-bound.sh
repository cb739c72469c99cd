#!/usr/bin/env bash
# Static worst-case stack bounds of both boards (issue #30 item 2), from the
# release images that run (stable toolchain), by scripts/stack-bound.py:
#   - QEMU mps2-an386: the ring cycle (`ring_cycle`, painted: metric
#     stack_bytes), the whole loop (`replay::run_loop`, painted: metrics
#     loop_stack_bytes and find_stack_bytes) and the whole program (`Reset`,
#     the firmware's last line "stack high-water mark").
#   - STM32F4 sonar: one reading through the controller (`step`, where a ring
#     cycle ends), the whole loop (`main`) and the whole program (`Reset`);
#     no hardware here, so no measurement: its loop logs the painted
#     high-water mark over defmt. Also checks that flip-link placed the stack
#     below .data/.bss.
# Fails when a bound is below the painted mark (the analysis missed
# something), when a bound grew past boards/stack-bounds.txt, or when a
# bounded root became unbounded. `--update` rewrites the snapshot.
# `--cross-check` also builds the QEMU image with nightly's
# `-Z emit-stack-sizes` and compares the frames parsed from its instructions
# with LLVM's own in that image (fails if a parsed frame is smaller); installs
# nightly (as scripts/fuzz.sh does) and its thumbv7em-none-eabihf library when absent.
# Reads the QEMU firmware's output on stdin (as scripts/metrics.sh), or runs it.
# Usage: cargo run -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf --release | bash scripts/stack-bound.sh [--update] [--cross-check]
set -euo pipefail
cd "$(dirname "$0")/.."
update=()
cross=0
for a in "$@"; do
  case "$a" in
    --update) update=(--update) ;;
    --cross-check) cross=1 ;;
    *)
      echo "usage: bash scripts/stack-bound.sh [--update] [--cross-check]" >&2
      exit 2
      ;;
  esac
done
t=thumbv7em-none-eabihf
dir=${CARGO_TARGET_DIR:-target}/$t/release
snapshot=boards/stack-bounds.txt
if [ -t 0 ]; then
  out=$(cargo run -q -p qemu-mps2-an386 --target $t --release)
else
  out=$(cat)
fi
cargo build -q -p qemu-mps2-an386 --bin qemu-mps2-an386 --target $t --release
cargo build -q -p stm32f4-sonar --target $t --release

metric() { awk -v k="$1" '$1 == "metric" && $2 == k { print $3 }' <<<"$out"; }
ring=$(metric stack_bytes)
loop=$(metric loop_stack_bytes)
find=$(metric find_stack_bytes)
whole=$(sed -n 's/^stack high-water mark: \([0-9]*\) of .*/\1/p' <<<"$out")
if [ -z "$ring" ] || [ -z "$loop" ] || [ -z "$find" ] || [ -z "$whole" ]; then
  echo "the firmware's output lacks its stack figures (stack_bytes, loop_stack_bytes, find_stack_bytes, the high-water line)" >&2
  exit 1
fi
# Both replays run the same function (`run_loop`): the bound must cover the deeper.
deeper=$((loop > find ? loop : find))

echo "== qemu-mps2-an386"
python3 scripts/stack-bound.py "$dir/qemu-mps2-an386" --board qemu-mps2-an386 --snapshot "$snapshot" "${update[@]}" \
  --root ring_cycle=qemu_mps2_an386::ring_cycle --measured ring_cycle="$ring" \
  --root loop=qemu_mps2_an386::replay::run_loop --measured loop="$deeper" \
  --root program=Reset --measured program="$whole"

echo
echo "== stm32f4-sonar"
# The panic handler parks at once when entered a second time (its flag), so
# the cycle panic -> defmt -> (logger taken) panic is followed once more, then cut.
python3 scripts/stack-bound.py "$dir/stm32f4-sonar" --board stm32f4-sonar --snapshot "$snapshot" "${update[@]}" \
  --root ring_cycle=stm32f4_sonar::step \
  --root loop=stm32f4_sonar::__cortex_m_rt_main \
  --root program=Reset \
  --reentry-guarded __rustc::rust_begin_unwind --expect-flipped

if [ "$cross" = 1 ]; then
  echo
  echo "== cross-check: the frames parsed from the instructions against LLVM's -Z emit-stack-sizes (nightly, same image)"
  rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
  rustup +nightly target list --installed | grep -qx $t || rustup +nightly target add $t
  ndir=${CARGO_TARGET_DIR:-target}/nightly-stack-sizes
  CARGO_TARGET_DIR=$ndir RUSTFLAGS="-Z emit-stack-sizes" \
    cargo +nightly build -q -p qemu-mps2-an386 --bin qemu-mps2-an386 --target $t --release
  python3 scripts/stack-bound.py "$ndir/$t/release/qemu-mps2-an386" --stack-sizes \
    --root ring_cycle=qemu_mps2_an386::ring_cycle --root loop=qemu_mps2_an386::replay::run_loop --top 0
fi
