#!/usr/bin/env bash
# Every check CI runs, in order. Installs what a fresh machine lacks first.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each step's wall time, printed at the end, so CI readers
# see where the 45 minutes go.
step_name="" step_start=$SECONDS
timings=()
step_done() {
  [ -n "$step_name" ] && timings+=("$(printf '%5d s  %s' $((SECONDS - step_start)) "${step_name:0:70}")")
  return 0
}
step() {
  step_done
  step_name="$*" step_start=$SECONDS
  printf '\n== %s\n' "$*"
}

step "set-up: what a fresh machine lacks"
bash scripts/setup.sh

# Real data the tests read (DESIGN §9): the shared folder beside the repository.
for f in ../shared/data/maps/depot.yaml ../shared/data/maps/tb3_sandbox.yaml ../shared/data/sonar/scitos-g5-ring24.csv ../shared/data/real/intel-corrected.log.gz; do
  if [ ! -f "$f" ]; then
    echo "missing $f: check out the project's shared/ folder beside this repository (CI has it there)" >&2
    exit 1
  fi
done
thumbs=(thumbv7em-none-eabihf thumbv6m-none-eabi)
# The scripts' short cases run the lab tool the host tests built (dev profile)
# rather than compiling it again in release (scripts/lab-tool.sh).
export ECHOLOC_LAB_PROFILE=dev

step "format"
cargo fmt --all -- --check

step "clippy: host crates (all targets), core on the thumb targets (plain, defmt, async), boards"
cargo clippy -q --all-targets -- -D warnings
for t in "${thumbs[@]}"; do
  cargo clippy -q -p echoloc --target "$t" -- -D warnings
  cargo clippy -q -p echoloc --target "$t" --features defmt -- -D warnings
  cargo clippy -q -p echoloc --target "$t" --features async,defmt -- -D warnings
done
cargo clippy -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf -- -D warnings
cargo clippy -q -p stm32f4-sonar --target thumbv7em-none-eabihf -- -D warnings
cargo clippy -q -p panic-never --target thumbv7em-none-eabihf -- -D warnings
cargo clippy -q -p stack-paint --target thumbv7em-none-eabihf -- -D warnings

step "core builds for the thumb targets"
for t in "${thumbs[@]}"; do
  cargo build -q -p echoloc --target "$t" --release
  cargo build -q -p echoloc --target "$t" --release --features defmt
  cargo build -q -p echoloc --target "$t" --release --features async
done

step "no panic path in the core (issue #14): the panic-never board links; with a planted panic it must not; no overflow check left anywhere in the core paths (issue #30), and a planted one is found"
bash scripts/panic-never.sh
bash scripts/panic-never.sh --plant
bash scripts/panic-never.sh --overflow
bash scripts/panic-never.sh --overflow --plant

step "the setup waits for another package manager's lock (issue #30)"
bash scripts/apt-lock-check.sh

step "boards build"
cargo build -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf --release
cargo build -q -p stm32f4-sonar --target thumbv7em-none-eabihf --release

step "host tests (unit, integration, property, doc)"
cargo test -q --workspace 2>&1 | tee target/host-tests.log
# One closing line for CI readers: the sum over every test binary.
awk '/^test result:/ { p += $4; f += $6 } END { printf "host tests: %d passed, %d failed\n", p, f }' target/host-tests.log

step "bring your own robot (issue #16): a ROS map compiled by build.rs and read in place; the verdicts example"
# Without -p: the default members' features, as the host tests built them,
# so nothing but the example's own program is compiled again (with -p the
# lab was rebuilt for its own feature set: 203 s in a clean run).
cargo run -q --bin map-at-build-time
cargo run -q --example verdicts -- examples/map-at-build-time/map/room.yaml 2.5,2,0 1760,-,-,3230 | tee target/verdicts.txt
grep -q "Confirmed" target/verdicts.txt

step "QEMU firmware runs (timeout in the runner): main with its metrics, the depot map, one kappa, the EKF"
out=$(cargo run -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf --release 2>&1) || {
  echo "$out"
  echo "firmware exited non-zero"
  exit 1
}
echo "$out"
# The budgets against the committed snapshot: fails when a figure grew by more than 5 %.
bash scripts/metrics.sh <<<"$out"
# Static worst-case stack bounds (issue #30): each at least its painted mark, none grown past
# boards/stack-bounds.txt, the STM32 stack below its statics (flip-link); the parsed frames
# against LLVM's -Z emit-stack-sizes (nightly, installed when absent).
bash scripts/stack-bound.sh --cross-check <<<"$out"
grep -q "corrupted blob: refused" <<<"$out"
grep -q "stack high-water mark" <<<"$out"
grep -q "ring16 PseudoPaths" <<<"$out"
# A HardFault must end the run with exit code 1, never 0 (nor a hang).
set +e
fault=$(cargo run -q -p qemu-mps2-an386 --bin hardfault --target thumbv7em-none-eabihf --release 2>&1)
rc=$?
set -e
echo "$fault"
if [ "$rc" -ne 1 ] || ! grep -q "HardFault at pc" <<<"$fault"; then
  echo "the HardFault handler did not exit with failure (exit code $rc)"
  exit 1
fi
for bin in depot kappa_cost ekf_cost place_cost; do
  cargo run -q -p qemu-mps2-an386 --bin "$bin" --target thumbv7em-none-eabihf --release || {
    echo "firmware binary $bin exited non-zero"
    exit 1
  }
done

step "the whole loop against planted failures (issue #12): the depot scenario, its truth shifted by 1 m, a flipped bit, another map"
bash scripts/replay-checks.sh

step "big maps (issue #11 item 5): the depot tiled 1x1, 3x2 and 4x4, imported and run from a flash partition"
bash scripts/big-maps.sh

step "real buildings (issues #35, #49): the ladder script's short case on the Intel and Freiburg 079 lidar runs (the whole tables: docs/real-buildings.md)"
bash scripts/real-buildings.sh --short

step "the truth's lead over the best wrong place (issue #36 item 1): the script's short case (the whole table: docs/localization.md)"
lead=$(bash scripts/mcl-lead.sh --seeds 1 --maps depot --clutter 0.5 2>/dev/null)
echo "$lead"
# Four leads (10 and 40 cycles, 15 and 30 m), each with its runs behind.
grep -Eq '^\| depot \| 0\.5 \| 1 \|( -?[0-9]+ \(-?[0-9]+\) nats \| [01] \|){4}$' <<<"$lead"

step "the benchmark's windows on the M4 (issue #13): answers equal the host's, instructions per window"
bash scripts/bench-m4.sh 300

step "fuzzing (issue #14): every core input path for a short bounded time (installs nightly and cargo-fuzz when absent)"
bash scripts/fuzz.sh 15

step "docs"
RUSTDOCFLAGS="-D warnings" cargo doc -q --no-deps
RUSTDOCFLAGS="-D warnings" cargo doc -q --no-deps -p qemu-mps2-an386 -p stm32f4-sonar --target thumbv7em-none-eabihf

step_done
echo
echo "time per step:"
printf '%s\n' "${timings[@]}"
echo
echo "all checks passed"
