#!/usr/bin/env bash
# Issue #47: a floor plan drawn with its doorways and entrance open
# (lab/tests/data/doorways.geojson) finding itself from no pose, with the
# free space the walls enclose with doors closed (--door-mm 1200, the
# default) and with the walls alone (--door-mm 0: on this plan nothing is
# enclosed, so the obstacles' bounding box, the rule before #37).
#   bash scripts/doorways-runs.sh [SEEDS]     # default 10
# Prints one line per run and a summary per setting (docs/maps.md).
set -euo pipefail
cd "$(dirname "$0")/.."
seeds=${1:-10}
cargo build --release -q -p echoloc-lab
lab=target/release/echoloc-lab
out=target/doorways-runs
mkdir -p "$out"
for door in 1200 0; do
  for s in $(seq 1 "$seeds"); do
    echo "$lab simulate --map lab/tests/data/doorways.geojson --seed $s --start unknown --door-mm $door --json > $out/door$door-$s.json"
  done
done | xargs -P 2 -I{} bash -c "{} 2>/dev/null"
python3 - "$out" "$seeds" <<'PY'
import json, sys
out, seeds = sys.argv[1], int(sys.argv[2])
print("door_mm seed found_m handoffs wrong final_m final_mode")
for door in (1200, 0):
    found, wrong, found_d = 0, 0, []
    for s in range(1, seeds + 1):
        j = json.loads(open(f"{out}/door{door}-{s}.json").read().strip().splitlines()[-1])["localization"]
        fc = j.get("first_convergence") or {}
        d = fc.get("distance_m")
        w = len(j.get("wrong_handoffs") or [])
        found += d is not None and d <= 30
        wrong += w > 0
        if d is not None:
            found_d.append(d)
        print(door, s, "-" if d is None else round(d, 1), j["handoffs"], w, j["final_error_m"], j["final_mode"])
    found_d.sort()
    med = found_d[len(found_d) // 2] if found_d else None
    print(f"door_mm {door}: found within 30 m {found}/{seeds}, runs with a wrong hand-off {wrong}/{seeds}, median found at {med} m")
PY
