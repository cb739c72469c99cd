#!/usr/bin/env bash
# The particles' measurement model, judged by how far the true trajectory
# leads the best wrong place (issue #36 item 1): for each map and clutter,
# seeds 1..N of a 40 m simulated run, the truth's summed log-likelihood over
# the first 10 and 40 ring cycles minus that of the best of 20 000 random
# starts beyond 1 m or 20° of the true start, carried by the same motion,
# and the same lead at the first report past 15 m and 30 m of travel
# (lab/examples/mcl_probe.rs). A sample of wrong places, not the sweep's:
# the lead it reports is an upper bound on the lead over every wrong place.
#
#   bash scripts/mcl-lead.sh [--seeds N] [--maps "depot bookstore"] [--clutter "0.5 0.7"] [--import "ARGS"] [--null]
#
# --null (issue #48): instead, the null hypothesis's table: at the first
# report past 30 m, the truth's and the best wrong place's summed lead over
# the null (localize/null.rs), with the beam model as the particles score
# by it and with a reading the place expects nothing of scored as the null
# scores it (HYBRID).
#
# --import: each map compiled first by `echoloc-lab map import MAP.yaml ARGS`
# (e.g. --import "--field-fallback-deg 60") into target/mcl-lead/.
set -euo pipefail
cd "$(dirname "$0")/.."
seeds=10
maps="depot bookstore tb3_sandbox"
clutter="0.5 0.7"
import=
null=
while [ $# -gt 0 ]; do
  case "$1" in
    --seeds) seeds=$2; shift 2 ;;
    --maps) maps=$2; shift 2 ;;
    --clutter) clutter=$2; shift 2 ;;
    --import) import=$2; shift 2 ;;
    --null) null=1; shift ;;
    *) echo "usage: bash scripts/mcl-lead.sh [--seeds N] [--maps \"…\"] [--clutter \"…\"] [--import \"ARGS\"] [--null]" >&2; exit 2 ;;
  esac
done
source scripts/lab-tool.sh
lab_build --example mcl_probe
if [ -n "$import" ]; then
  lab_build
  mkdir -p target/mcl-lead
fi
rows=$(mktemp)
trap 'rm -f "$rows"' EXIT
for map in $maps; do
  src="../shared/data/maps/$map.yaml"
  if [ -n "$import" ]; then
    # shellcheck disable=SC2086 # the arguments are words
    "$LAB" map import "$src" -o "target/mcl-lead/$map.map" $import >/dev/null
    src="target/mcl-lead/$map.map"
  fi
  for inc in $clutter; do
    for seed in $(seq 1 "$seeds"); do
      if [ -n "$null" ]; then
        for scoring in beam hybrid; do
          # The probe takes HYBRID's presence, whatever its value.
          hybrid=(); [ "$scoring" = hybrid ] && hybrid=(HYBRID=1)
          line=$(env "${hybrid[@]}" NTRAJ=3000 "$lab_dir/examples/mcl_probe" "$src" "$seed" "$inc" \
            | awk '/^null after/ && $(NF-1) + 0 >= 30 && !done {print; done = 1}')
          echo "$map $inc $seed $scoring $line" | tee -a "$rows" >&2
        done
        continue
      fi
      out=$(NTRAJ=20000 "$lab_dir/examples/mcl_probe" "$src" "$seed" "$inc" | grep '^lead after' || true)
      l10=$(awk '/after 10 cycles/ {print $5}' <<<"$out")
      l40=$(awk '/after 40 cycles/ {print $5}' <<<"$out")
      # The first report at or past 15 m and 30 m of travel (a report every 10 cycles, ~2 m).
      m15=$(awk '$(NF-1) + 0 >= 15 {print $5; exit}' <<<"$out")
      m30=$(awk '$(NF-1) + 0 >= 30 {print $5; exit}' <<<"$out")
      echo "$map $inc $seed ${l10:-nan} ${l40:-nan} ${m15:-nan} ${m30:-nan}" | tee -a "$rows" >&2
    done
  done
done
if [ -n "$null" ]; then
  python3 - "$rows" <<'PY'
import sys, re, statistics
groups = {}
for l in open(sys.argv[1]):
    w = l.split()
    m = re.search(r"truth - null ([-0-9.]+) nats \(([-0-9.]+) clipped.*best wrong place - null ([-0-9.]+);.*travelled ([0-9.]+) m", l)
    if not m:
        continue
    t, tc, w_, d = (float(x) for x in m.groups())
    groups.setdefault((w[0], w[1], w[3]), []).append((t, tc, w_, d))
print("| map | clutter | scoring | seeds | truth ahead of the null | truth − null: median (min) | clipped at 2 nats: median (min) | best wrong place − null: median (max) |")
print("|---|---|---|---|---|---|---|---|")
for (m, inc, sc), v in groups.items():
    t = [r[0] for r in v]; tc = [r[1] for r in v]; w = [r[2] for r in v]
    print(f"| {m} | {inc} | {sc} | {len(v)} | {sum(x > 0 for x in t)} | {statistics.median(t):.0f} ({min(t):.0f}) | {statistics.median(tc):.0f} ({min(tc):.0f}) | {statistics.median(w):.0f} ({max(w):.0f}) |")
PY
  exit 0
fi
python3 - "$rows" <<'PY'
import sys, math, statistics
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
groups = {}
for m, inc, seed, *leads in rows:
    groups.setdefault((m, inc), []).append([float(x) for x in leads])
print("| map | clutter | seeds | lead after 10 cycles: median (min) | behind | after 40 cycles | behind | after 15 m | behind | after 30 m | behind |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
cell = lambda xs: f"{statistics.median(xs):.0f} ({min(xs):.0f}) nats" if xs else "–"
for (m, inc), v in groups.items():
    cols = []
    for k in range(4):
        xs = [r[k] for r in v if not math.isnan(r[k])]
        cols += [cell(xs), str(sum(x < 0 for x in xs))]
    print(f"| {m} | {inc} | {len(v)} | " + " | ".join(cols) + " |")
PY
