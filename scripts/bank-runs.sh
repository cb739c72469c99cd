#!/usr/bin/env bash
# #48's bank of places end to end on the simulator (lab/src/simulate/places.rs
# bank_run, via lab/examples/place_probe.rs with BANK): 1 024 particles
# propose their heaviest cluster each cycle and the node sweep its K best
# places; a place leads when it is the bound (150 nats) ahead of the null
# and every other. Per run: where a place first led (m), how far off it was
# (m, degrees), and at that moment the evidence of a living place near the
# truth and where a proposal first came near it. Then, per map and clutter,
# right (within 0.5 m and 20°) / wrong / none in DIST m.
#
#   SWEEP=K [BOUND=150] [DIST=60] [SEEDS="1 2 …"] [MAPS="depot …"] [CLUTTER="0.5 0.7"] bash scripts/bank-runs.sh
#
# A debug build, as docs/localization.md's tables were made (about 2.5 s a
# run; the figures are the same in release).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p echoloc-lab --example place_probe
probe=target/debug/examples/place_probe
out=$(mktemp)
trap 'rm -f "$out"' EXIT
echo "map clutter seed handoff_m err_m err_deg most_living travelled_m truth_ev truth_proposed_m cluster_w cluster_d"
for m in ${MAPS:-depot bookstore tb3_sandbox}; do
  for cl in ${CLUTTER:-0.5 0.7}; do
    for s in ${SEEDS:-1 2 3 4 5 6 7 8 9 10}; do
      line=$(SWEEP=${SWEEP:-2} BANK=${BOUND:-150} DIST=${DIST:-60} "$probe" "../shared/data/maps/$m.yaml" "$s" "$cl" | tail -1)
      echo "$m $cl $s $line" | tee -a "$out"
    done
  done
done
echo
echo "map clutter: right / wrong / none"
awk '{k=$1" "$2; if (!(k in seen)) {seen[k]=1; order[++n]=k}}
     $4=="-" {none[k]++; next}
     ($5<=0.5 && $6<20 && $6>-20) {right[k]++; next}
     {wrong[k]++}
     END {for (i=1; i<=n; i++) {k=order[i]; printf "%s: %d / %d / %d\n", k, right[k], wrong[k], none[k]}}' "$out"
