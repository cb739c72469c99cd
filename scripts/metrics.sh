#!/usr/bin/env bash
# The firmware's budgets (issue #11) against the committed snapshot.
# Reads the main firmware's output on stdin (or runs it), prints each
# `metric NAME VALUE` beside its snapshot and its budget, and fails when a
# figure grew by more than 5 % over the snapshot. `--update` rewrites the
# snapshot from this run instead (commit it with the change that moved it).
# Usage: cargo run -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf --release | bash scripts/metrics.sh [--update]
set -euo pipefail
cd "$(dirname "$0")/.."
snapshot=boards/qemu-mps2-an386/metrics.txt
if [ -t 0 ]; then
  out=$(cargo run -q -p qemu-mps2-an386 --target thumbv7em-none-eabihf --release)
else
  out=$(cat)
fi
metrics=$(grep '^metric ' <<<"$out" | awk '{ print $2, $3 }')
if [ -z "$metrics" ]; then
  echo "no metric lines in the firmware's output" >&2
  exit 1
fi
if [ "${1:-}" = "--update" ]; then
  {
    echo "# Firmware figures on QEMU mps2-an386 (Cortex-M4F), from the README's main command."
    echo "# scripts/metrics.sh fails when one grows by more than 5 %; --update rewrites this file."
    echo "$metrics"
  } >"$snapshot"
  echo "snapshot updated: $snapshot"
  exit 0
fi
python3 - "$snapshot" <<PY
import sys
snap = {}
for line in open(sys.argv[1]):
    if line.strip() and not line.startswith("#"):
        k, v = line.split()
        snap[k] = float(v)
# The budgets of issue #11 (None: reported, no budget).
budget = {"insns_per_ring": 400_000, "insns_per_window": 25_000, "insns_per_kappa": 150,
          "stack_bytes": 4096, "ram_static_bytes": 32_768,
          # issue #27 raised the code budget from 96 KiB for the localizer,
          # issue #36 item 4 to 120 KiB for its hypothesis bank
          "flash_bytes": 120 * 1024,
          # issue #12: the whole loop against the scenario's ground truth (its own bounds)
          "pose_rmse_m": 0.05, "heading_rmse_deg": 1.0,
          # issue #27: a ring cycle while tracking and while searching with 1 024
          # particles (the mean; the worst is reported beside it), the localizer's state
          # (24 KiB; issue #36 item 4: 32 KiB with the hypotheses)
          "loc_tracking_insns_per_cycle": 400_000, "loc_search_insns_per_cycle": 25_000_000,
          "localizer_state_bytes": 32 * 1024}
fmt = lambda v: f"{v:.6g}" if v != int(v) else str(int(v))
now = {}
for line in """$metrics""".splitlines():
    k, v = line.split()
    now[k] = float(v)
grew = []
print(f"{'metric':<28}{'now':>12}{'snapshot':>12}{'change':>9}{'budget':>10}  ")
for k, v in now.items():
    s = snap.get(k)
    ch = f"{100.0 * (v - s) / s:+.1f}%" if s else "new"
    b = budget.get(k)
    verdict = "" if b is None else ("met" if v <= b else f"MISSED x{v / b:.2f}")
    print(f"{k:<28}{fmt(v):>12}{fmt(s) if s is not None else '-':>12}{ch:>9}{fmt(b) if b is not None else '-':>10}  {verdict}")
    if s is not None and v > s * 1.05:
        grew.append(k)
missing = [k for k in snap if k not in now]
if missing:
    print("metrics missing from this run:", ", ".join(missing))
if grew or missing:
    print("FAIL: grew by more than 5 % over the snapshot:", ", ".join(grew) if grew else "-")
    sys.exit(1)
print("no figure grew by more than 5 % over the snapshot")
PY
