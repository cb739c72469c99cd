#!/usr/bin/env python3
"""The sequential test's bound, calibrated on the simulator (issue #48).

For each map, clutter and seed, a simulated run (`lab/examples/place_probe.rs`,
`echoloc_lab::simulate::places`): a place started at the truth (sigma 10 cm,
3 deg) and 2 000 places started at random free poses (sigma 20 cm, 6 deg), each
tracking itself (the core's `localize::Place`), each with its evidence over
the null hypothesis (each reading's log-ratio clipped to 2 nats) summed since
the start. Every 2 m of travel: the truth's evidence and the best evidence of
the places then more than 1 m or 20 deg from the truth ("wrong").

A wrong hand-off at bound A needs a wrong place A over the null (and over
every other living place): the largest evidence any wrong place reached over
the run is the bound that run would have needed. The truth is found at A
when it leads the null and the best wrong place by A. Printed per map and
clutter: the wrong places' largest evidence (median, max over the seeds),
their largest lead over the truth's place (the summed log-ratio between the
truth and its best alias: the bound the test needs), the runs where the truth leads the null at 30 m, the runs where the truth's
place strayed more than 0.5 m, and for each A the runs where a wrong place
led the null by A (a wrong hand-off if the truth is not among the living
places), where it led the null and the truth by A (a wrong hand-off even if
it is), and the runs found within 30 m and 60 m.

    python3 scripts/place-bound.py [--seeds N] [--maps "depot bookstore"] [--clutter "0.5 0.7"] [--bounds "50 100"] [--dist M]

The lab tool's profile: ECHOLOC_LAB_PROFILE (release by default; scripts/lab-tool.sh).
"""
import argparse
import os
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def probe(exe, map_yaml, seed, clutter, dist):
    env = dict(os.environ, N=os.environ.get("N", "2000"), EVERY="2", DIST=str(dist))
    out = subprocess.run([exe, map_yaml, str(seed), str(clutter)], env=env, check=True,
                         capture_output=True, text=True).stdout
    rows = []
    for line in out.splitlines()[1:]:
        f = line.split("\t")
        rows.append({"m": float(f[0]), "err": float(f[1]), "ev": float(f[4]), "wrong": float(f[5])})
    return rows


def at(rows, m):
    past = [r for r in rows if r["m"] >= m]
    return past[0] if past else None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--maps", default="depot bookstore tb3_sandbox")
    ap.add_argument("--clutter", default="0.5 0.7")
    ap.add_argument("--bounds", default="50 100 150 200")
    ap.add_argument("--dist", type=float, default=60.0)
    a = ap.parse_args()
    profile = os.environ.get("ECHOLOC_LAB_PROFILE", "release")
    subprocess.run(["cargo", "build", "-q", "--profile", profile, "-p", "echoloc-lab", "--example", "place_probe"],
                   cwd=ROOT, check=True)
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    exe = os.path.join(target, "debug" if profile == "dev" else profile, "examples", "place_probe")
    bounds = [float(b) for b in a.bounds.split()]
    head = "| map | clutter | wrong places' largest evidence: median, max | their largest lead over the truth: median, max | truth over the null at 30 m | truth lost (> 0.5 m) |"
    head += "".join(f" A={b:.0f}: a wrong place led the null by A / and the truth / found ≤ 30 m / ≤ 60 m |" for b in bounds)
    print(head)
    print("|" + "---|" * (6 + len(bounds)))
    for m in a.maps.split():
        for c in a.clutter.split():
            runs = [probe(exe, os.path.join(ROOT, "..", "shared", "data", "maps", f"{m}.yaml"), s, c, a.dist)
                    for s in range(1, a.seeds + 1)]
            worst = [max(r["wrong"] for r in rows) for rows in runs]
            over = [max(r["wrong"] - r["ev"] for r in rows) for rows in runs]
            ahead = sum(1 for rows in runs if (at(rows, 30) or {"ev": -1})["ev"] > 0)
            lost = sum(1 for rows in runs if any(r["err"] > 0.5 for r in rows))
            line = f"| {m} | {c} | {statistics.median(worst):.0f}, {max(worst):.0f} | {statistics.median(over):.0f}, {max(over):.0f} | {ahead}/{len(runs)} | {lost}/{len(runs)} |"
            for b in bounds:
                reached = sum(1 for w in worst if w >= b)
                beat = sum(1 for rows in runs if any(r["wrong"] >= b and r["wrong"] - r["ev"] >= b for r in rows))
                found = []
                for rows in runs:
                    f = next((r["m"] for r in rows if r["ev"] >= b and r["ev"] - r["wrong"] >= b and r["err"] <= 0.5), None)
                    found.append(f)
                f30 = sum(1 for f in found if f is not None and f <= 30)
                f60 = sum(1 for f in found if f is not None and f <= 60)
                line += f" {reached} / {beat} / {f30} / {f60} |"
            print(line, flush=True)


if __name__ == "__main__":
    sys.exit(main())
