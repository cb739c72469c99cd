#!/usr/bin/env python3
"""Writes lab/tests/data/depot-hand.csv: a hand-made robot log in the plain
log format (docs/log.md), independent of echoloc and its simulator.

A Pioneer-like robot drives 4 m through the depot (ROS map, 5 cm cells) on
a gentle curve. Its sonar ring fires one transducer every 40 ms in the order
the echoloc driver fires a 16-ring (so a board replays it slot for slot).
Each range is the nearest occupied cell within ±12° of the transducer's
axis, by stepping rays 1° apart through the grid in 1 cm steps (no echo
beyond 5 m), plus 8 mm Gaussian noise; a few readings are dropped or made
short (an unmapped person). Odometry has a 2 % distance and a 0.02 rad/m
heading error; the reference pose is the true one.

Usage: python3 scripts/fixture-log.py ../shared/data/maps/depot.pgm > lab/tests/data/depot-hand.csv
"""
import math
import random
import sys

MOUNTS = [(75, 130, 90), (115, 115, 50), (150, 80, 30), (170, 25, 10), (170, -25, -10), (150, -80, -30),
          (115, -115, -50), (75, -130, -90), (-155, -130, -90), (-195, -115, -130), (-230, -80, -150),
          (-250, -25, -170), (-250, 25, 170), (-230, 80, 150), (-195, 115, 130), (-155, 130, 90)]
ORDER = [0, 3, 6, 9, 12, 15, 2, 5, 8, 11, 14, 1, 4, 7, 10, 13]
RES = 0.05


def load(path):
    data = open(path, "rb").read()
    magic, dims, maxval, pixels = data.split(b"\n", 3)
    assert magic == b"P5" and maxval == b"255"
    w, h = map(int, dims.split())
    return w, h, pixels


def occupied(grid, x, y):
    w, h, px = grid
    i, j = int(math.floor(x / RES)), int(math.floor(y / RES))
    if not (0 <= i < w and 0 <= j < h):
        return False
    return px[(h - 1 - j) * w + i] < 100  # trinary: 0 occupied, 205 unknown, 254 free


def sonar(grid, x, y, heading):
    best = None
    for k in range(-12, 13):
        a = heading + math.radians(k)
        c, s = math.cos(a), math.sin(a)
        r = 0.0
        while r < 5.0 and (best is None or r < best):
            if occupied(grid, x + c * r, y + s * r):
                best = r
                break
            r += 0.01
    return best


def main():
    grid = load(sys.argv[1])
    rnd = random.Random(16)
    x, y, th = 6.0, 5.2, 0.0          # truth
    ox, oy, oth = 0.0, 0.0, 0.0       # odometry, from its own origin
    v, w, dt = 0.25, 0.03, 0.04
    print("# depot-hand: 25 ring cycles, written by scripts/fixture-log.py")
    print("time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad,ref_x_m,ref_y_m,ref_theta_rad")
    t = 0.0
    for cycle in range(25):
        for i in ORDER:
            mx, my, mh = MOUNTS[i]
            c, s = math.cos(th), math.sin(th)
            sx, sy = x + c * mx / 1000 - s * my / 1000, y + s * mx / 1000 + c * my / 1000
            r = sonar(grid, sx, sy, th + math.radians(mh))
            cell = ""
            u = rnd.random()
            if r is not None and u > 0.05:
                r += rnd.gauss(0.0, 0.008)
                if u > 0.97:
                    r = min(r, 0.6 + rnd.random())  # somebody walks by
                if r >= 0.45:
                    cell = str(round(r * 1000))
            print(f"{t:.2f},{i},{cell},{ox:.6f},{oy:.6f},{oth:.6f},{x:.6f},{y:.6f},{th:.6f}")
            # Motion to the next firing: truth, then odometry with its errors.
            d, dth = v * dt, w * dt
            x, y, th = x + d * math.cos(th + dth / 2), y + d * math.sin(th + dth / 2), th + dth
            od, odth = d * 1.02, dth + 0.02 * d
            ox, oy, oth = ox + od * math.cos(oth + odth / 2), oy + od * math.sin(oth + odth / 2), oth + odth
            t += dt


if __name__ == "__main__":
    main()
