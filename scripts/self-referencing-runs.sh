#!/usr/bin/env bash
# The many-seed figures of docs/self-referencing.md: for MAP, INCONSISTENT
# and N seeds, one 200 m simulate run per seed, then a summary line.
#   bash scripts/self-referencing-runs.sh depot 0.5 20
#   bash scripts/self-referencing-runs.sh tb3_sandbox 0.5 20
#   bash scripts/self-referencing-runs.sh depot 0.8 50
#   bash scripts/self-referencing-runs.sh depot 0.5 40 --no-recovery   # further arguments go to simulate
#   bash scripts/self-referencing-runs.sh depot 0.5 40 --no-robust
# Each run prints: seed, EKF position RMSE (m), heading RMSE (deg), max
# position error (m), dead reckoning's max error (m), lost raised, cleared,
# cycles lost, cycles, achieved inconsistency, confirmed fraction,
# recoveries.
set -euo pipefail
cd "$(dirname "$0")/.."
map=${1:?map name under ../shared/data/maps}; inc=${2:-0.5}; n=${3:-20}
cargo build -q --release -p echoloc-lab
for s in $(seq 1 "$n"); do
  ./target/release/echoloc-lab simulate --map "../shared/data/maps/$map.yaml" --seed "$s" --inconsistent "$inc" --json "${@:4}" |
    python3 -c "
import json, sys
d = json.load(sys.stdin); e = d['ekf']
print($s, e['position_rmse_m'], e['heading_rmse_deg'], e['max_position_error_m'], d['dead_reckoning']['max_position_error_m'],
      d['lost']['raised'], d['lost']['cleared'], d['lost']['cycles_lost'], d['cycles'], d['inconsistent_fraction'], d['verdicts']['confirmed_fraction'], d['lost']['recoveries'])"
done | tee /dev/stderr | awk '{ n++; if ($4 > 0.5) { d++; ds = ds " " $1 }; rc += $12; if ($2 <= 0.05) p++; if ($3 <= 1.0) h++; sp += $2; sh += $3; lr += $6; lc += $7; cl += $8; cy += $9; cf += $11 }
  END { printf "%d runs: diverged (max > 0.5 m) %d (seeds%s); recoveries %d; position RMSE <= 5 cm %d; heading RMSE <= 1 deg %d; mean RMSE %.3f m, %.2f deg; lost raised %d, cleared %d, cycles lost %d of %d; mean confirmed %.3f\n",
        n, d, ds, rc, p, h, sp / n, sh / n, lr, lc, cl, cy, cf / n }'
