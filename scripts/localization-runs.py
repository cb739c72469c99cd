#!/usr/bin/env python3
"""The many-seed figures of docs/localization.md (issue #27): for a map and N
seeds, one `echoloc-lab simulate` run per seed in one of four kinds, run two at
a time, then a summary.

  python3 scripts/localization-runs.py global depot 50           # --start unknown, 200 m
  python3 scripts/localization-runs.py kidnap depot 50           # carried 2-10 m, turned up to 180 deg, at a random time
  python3 scripts/localization-runs.py clutter depot 50 0.7      # --inconsistent 0.7, tracked from the true start
  python3 scripts/localization-runs.py track depot 80            # the default clutter, tracked from the true start
  python3 scripts/localization-runs.py global depot 50 -- --no-particles   # after "--": more arguments for simulate
  FIELD="400 32" python3 scripts/localization-runs.py global depot 50  # the field at 400 mm nodes, 32 headings
  FIELD_FALLBACK=60 python3 scripts/localization-runs.py global depot 50  # the field's fallback lobe at 60 deg

The map is compiled once (with its localization field) into target/loc-maps/.
Each seed's JSON goes to target/loc-runs/KIND-MAP[-F]/SEED.json; the summary
is printed and written beside them as summary.json.
"""
import json
import os
import random
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# ECHOLOC_LAB=PATH: run that build of the lab tool instead (e.g. another
# commit's, for a before/after table from one script); it is not rebuilt.
LAB = os.environ.get("ECHOLOC_LAB") or os.path.join(ROOT, "target", "release", "echoloc-lab")


def field_args():
    """`FIELD="NODE_MM DIRS"`: the localization field's node spacing and
    headings; `FIELD_FALLBACK=DEG`: its fallback lobe (default: map import's)."""
    args, tag = [], ""
    f = os.environ.get("FIELD", "").split()
    if f:
        if len(f) != 2 or not all(x.isdigit() for x in f):
            raise SystemExit("FIELD must be \"NODE_MM DIRS\", e.g. FIELD=\"400 32\"")
        args, tag = ["--field-node-mm", f[0], "--field-dirs", f[1]], "-field%sx%s" % (f[0], f[1])
    fb = os.environ.get("FIELD_FALLBACK", "")
    if fb:
        if not fb.isdigit():
            raise SystemExit("FIELD_FALLBACK must be whole degrees, e.g. FIELD_FALLBACK=60")
        args, tag = args + ["--field-fallback-deg", fb], tag + "-fallback%s" % fb
    return args, tag


def compile_map(name):
    out_dir = os.path.join(ROOT, "target", "loc-maps")
    os.makedirs(out_dir, exist_ok=True)
    args, tag = field_args()
    out = os.path.join(out_dir, name + tag + ".map")
    src = os.path.join(ROOT, "..", "shared", "data", "maps", name + ".yaml")
    subprocess.run([LAB, "map", "import", src, "-o", out] + args, check=True, stdout=subprocess.DEVNULL)
    return out


def kidnap_for(seed, attempt):
    """A random kidnap: 2-10 m in a random direction, turned up to 180 deg, at 60-360 s.

    A carry must land in free space and the route must go on from there; on a
    small map (tb3_sandbox: the route's free region is a few metres across)
    few 2-10 m carries do, so after SHORT_AFTER failed attempts the carry is
    0.5-2 m instead (counted in the summary as short_carries).
    """
    import math

    r = random.Random(seed * 1000 + attempt)
    d = r.uniform(2.0, 10.0) if attempt < SHORT_AFTER else r.uniform(0.5, 2.0)
    a = r.uniform(-3.14159265, 3.14159265)
    return "%.2f:%.3f,%.3f,%.1f" % (r.uniform(60.0, 360.0), d * math.cos(a), d * math.sin(a), r.uniform(-180.0, 180.0)), d


SHORT_AFTER = 1000
ATTEMPTS = 2000


def one(kind, mapfile, seed, extra, inconsistent, out_dir):
    base = [LAB, "simulate", "--map", mapfile, "--seed", str(seed), "--json"]
    if kind == "global":
        args = base + ["--start", "unknown"]
    elif kind in ("clutter", "track"):
        args = base + ["--inconsistent", str(inconsistent)]
    else:
        args = base
    if kind == "kidnap":
        for attempt in range(ATTEMPTS):
            k, carry = kidnap_for(seed, attempt)
            p = subprocess.run(args + ["--kidnap", k] + extra, capture_output=True, text=True)
            if p.returncode == 0:
                break
            if "kidnap" not in p.stderr:
                raise SystemExit("seed %d: %s" % (seed, p.stderr))
        else:
            raise SystemExit("seed %d: no kidnap lands in free space" % seed)
    else:
        p = subprocess.run(args + extra, capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit("seed %d: %s" % (seed, p.stderr))
    d = json.loads(p.stdout)
    if kind == "kidnap":
        d["kidnap_carry_m"] = round(carry, 3)
    with open(os.path.join(out_dir, "%d.json" % seed), "w") as f:
        json.dump(d, f)
    return seed, d


def summary(kind, runs):
    s = {"runs": len(runs)}
    locs = [(seed, d["localization"], d) for seed, d in runs]
    if kind == "global":
        conv = [(seed, l["first_convergence"]) for seed, l, _ in locs]
        ok = [seed for seed, c in conv if c is not None and c["distance_m"] <= 30.0]
        dists = sorted(c["distance_m"] for _, c in conv if c is not None)
        s["converged_within_30m"] = len(ok)
        s["never_converged"] = [seed for seed, c in conv if c is None]
        s["converged_later"] = [(seed, c["distance_m"]) for seed, c in conv if c is not None and c["distance_m"] > 30.0]
        s["median_distance_m"] = dists[len(dists) // 2] if dists else None
        s["p90_distance_m"] = dists[int(len(dists) * 0.9)] if dists else None
    if kind == "kidnap":
        det = [(seed, k) for seed, l, _ in locs for k in l["kidnaps"]]
        s["kidnaps"] = len(det)
        s["detected_within_5s"] = sum(1 for _, k in det if k["detected_after_s"] is not None and k["detected_after_s"] <= 5.0)
        s["recovered_within_30m"] = sum(
            1 for _, k in det if k["recovered_after_m"] is not None and k["recovered_after_m"] <= 30.0
        )
        s["short_carries"] = [(seed, d["kidnap_carry_m"]) for seed, _, d in locs if d["kidnap_carry_m"] < 2.0]
        s["not_detected_5s"] = [(seed, k["detected_after_s"]) for seed, k in det if not (k["detected_after_s"] is not None and k["detected_after_s"] <= 5.0)]
        s["not_recovered_30m"] = [(seed, k["recovered_after_m"]) for seed, k in det if not (k["recovered_after_m"] is not None and k["recovered_after_m"] <= 30.0)]
    wrong = [(seed, w["time_s"], w["error_m"]) for seed, l, _ in locs for w in l["wrong_handoffs"]]
    s["runs_with_wrong_handoff"] = len({w[0] for w in wrong})
    s["wrong_handoffs"] = wrong
    s["ended_off"] = [seed for seed, l, _ in locs if l["ended_off"]]
    cycles = sum(l["cycles"] for _, l, _ in locs)
    off = sum(l["off_cycles"] for _, l, _ in locs)
    off_known = sum(round((l["off_cycles_known"] or 0) * l["off_cycles"]) for _, l, _ in locs)
    s["off_fraction_of_cycles"] = round(off / max(cycles, 1), 4)
    s["off_cycles"] = off
    s["off_cycles_reported_lost_or_searching"] = round(off_known / off, 4) if off else None
    ins = [(l["tracking_inside_99"], l["modes"]["tracking"]) for _, l, _ in locs if l["tracking_inside_99"] is not None]
    tot = sum(n for _, n in ins)
    s["tracking_inside_99"] = round(sum(f * n for f, n in ins) / tot, 4) if tot else None
    e = [d["ekf"] for _, _, d in locs]
    s["mean_rmse_m"] = round(sum(x["position_rmse_m"] for x in e) / len(e), 4)
    s["mean_heading_rmse_deg"] = round(sum(x["heading_rmse_deg"] for x in e) / len(e), 3)
    s["max_error_over_0_5m"] = [seed for seed, _, d in locs if d["ekf"]["max_position_error_m"] > 0.5]
    s["within_5cm"] = sum(1 for x in e if x["position_rmse_m"] <= 0.05)
    s["within_1deg"] = sum(1 for x in e if x["heading_rmse_deg"] <= 1.0)
    s["mean_confirmed"] = round(sum(d["verdicts"]["confirmed_fraction"] or 0 for _, _, d in locs) / len(locs), 4)
    s["mean_inconsistent"] = round(sum(d["inconsistent_fraction"] for _, _, d in locs) / len(locs), 4)
    return s


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1 :]
    if len(argv) < 3:
        raise SystemExit(__doc__)
    kind, name, n = argv[0], argv[1], int(argv[2])
    first = int(os.environ.get("FIRST_SEED", "1"))
    inconsistent = float(argv[3]) if len(argv) > 3 else 0.5
    if kind not in ("global", "kidnap", "clutter", "track"):
        raise SystemExit(__doc__)
    if not os.environ.get("ECHOLOC_LAB"):
        subprocess.run(["cargo", "build", "-q", "--release", "-p", "echoloc-lab"], cwd=ROOT, check=True)
    mapfile = compile_map(name)
    tag = "%s-%s" % (kind, name) + field_args()[1] + ("-%s" % argv[3] if len(argv) > 3 else "") + ("-" + "_".join(a.strip("-") for a in extra) if extra else "")
    out_dir = os.path.join(ROOT, "target", "loc-runs", os.environ.get("RUNS_TAG", "") + tag)
    os.makedirs(out_dir, exist_ok=True)
    seeds = range(first, first + n)
    with ThreadPoolExecutor(max_workers=int(os.environ.get("JOBS", "2"))) as ex:
        runs = list(ex.map(lambda s: one(kind, mapfile, s, extra, inconsistent, out_dir), seeds))
    for seed, d in runs:
        l = d["localization"]
        print(seed, json.dumps({k: l[k] for k in ("first_convergence", "handoffs", "wrong_handoffs", "off_fraction", "kidnaps", "final_error_m", "modes")}))
    s = summary(kind, runs)
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(s, f, indent=1)
    print(json.dumps(s, indent=1))


if __name__ == "__main__":
    main()
