#!/usr/bin/env bash
# Benchmarks against map size (issue #13 item 3): the real depot map (ROS
# map_server, ../shared/data/maps/) tiled 1x1, 2x2, 4x4 and 8x8 (1, 4, 16
# and 64 times the obstacles at the same local density), imported by the
# lab tool, then `echoloc-lab bench` on all four in one run: every method's
# time per window, completeness and memory per map, and the figure
# docs/figures/bench-scaling.png. Outputs go to target/bench-scaling/.
# Timing: run it on a quiet machine; the ratios within one map are measured
# side by side, interleaved, and are what docs/benchmarks.md quotes.
# Usage: bash scripts/bench-scaling.sh [POSES] [ROUNDS]
set -euo pipefail
cd "$(dirname "$0")/.."
poses=${1:-2000}
rounds=${2:-5}
src=../shared/data/maps/depot
out=target/bench-scaling
mkdir -p "$out" docs/figures
cargo build -q --release -p echoloc-lab
lab=${CARGO_TARGET_DIR:-target}/release/echoloc-lab
maps=()
for n in 1 2 4 8; do
  python3 scripts/tile-map.py "$src" "$n" "$n" "$out/depot_${n}x$n"
  "$lab" map import "$out/depot_${n}x$n.yaml" -o "$out/depot_${n}x$n.map" >"$out/depot_${n}x$n.import.json"
  maps+=(--map "$out/depot_${n}x$n.map")
done
"$lab" bench "${maps[@]}" --poses "$poses" --rounds "$rounds" --plot docs/figures/bench-scaling.png --json >"$out/bench.json"
# The figure's data beside it: `bench --from-json` redraws it without re-running.
cp "$out/bench.json" docs/figures/bench-scaling.json
python3 - "$out/bench.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
for r in d["maps"]:
    print(f"\n{r['map']}: {r['pieces']} pieces, {r['windows_per_half_angle']} windows per half-angle, grid {r['grid']}")
    for c in r["reference_check"]:
        print(f"  reference vs brute force ({c['half_angle_deg']} deg): {c['agree']}/{c['sampled']} agree, max diff {c['max_diff_mm']} mm")
    print(f"  {'method':<26}{'half':>6}{'ns/window':>11}{'x echoloc':>11}{'complete':>10}{'bytes':>11}")
    for m in r["methods"]:
        c = "-" if m["completeness"] is None else f"{100 * m['completeness']:.1f}%"
        print(f"  {m['name']:<26}{m['half_angle_deg']:>6.0f}{m['ns_per_window']:>11.0f}{m['ratio_to_echoloc']:>11.2f}{c:>10}{m['bytes']:>11}")
    for s in r.get("summary", []):
        f, p, b = s["fastest_peer"], s["parry2d"], s["bresenham_1deg"]
        print(f"  {s['half_angle_deg']:.0f} deg: full {s['echoloc_full_ns_per_window']:.0f} ns; fastest peer {f['method']} {f['ns_per_window']:.0f} ns ({f['ratio']:.2f}x); "
              f"{p['method']} {p['ratio']:.2f}x; {b['method']} {b['ratio']:.2f}x")
PY
echo
echo "figure: docs/figures/bench-scaling.png; JSON: $out/bench.json"
