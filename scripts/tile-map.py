#!/usr/bin/env python3
"""Tiles a ROS map_server map NX x NY: writes DST.pgm (the raster repeated)
and DST.yaml (the source's yaml with only the image changed: same
resolution, thresholds, negate, mode and origin).

Usage: tile-map.py SRC NX NY DST   (SRC and DST without extension)
Used by scripts/big-maps.sh and scripts/bench-scaling.sh."""
import sys

src, nx, ny, dst = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
data = open(src + ".pgm", "rb").read()
# P5 header: magic, width, height, maxval, separated by whitespace, with
# optional '#' comments; then one whitespace byte and the raster.
fields, i = [], 0
while len(fields) < 4:
    while data[i:i + 1].isspace():
        i += 1
    if data[i:i + 1] == b"#":
        while data[i:i + 1] not in (b"\n", b"\r", b""):
            i += 1
        continue
    j = i
    while not data[j:j + 1].isspace():
        j += 1
    fields.append(data[i:j])
    i = j
i += 1
if fields[0] != b"P5":
    sys.exit(f"{src}.pgm: not a binary PGM (P5)")
w, h, maxval = int(fields[1]), int(fields[2]), int(fields[3])
bpp = 1 if maxval < 256 else 2
raster = data[i:i + w * h * bpp]
if len(raster) != w * h * bpp:
    sys.exit(f"{src}.pgm: truncated raster")
row = w * bpp
rows = [raster[r * row:(r + 1) * row] * nx for r in range(h)]
with open(dst + ".pgm", "wb") as f:
    f.write(b"P5\n%d %d\n%d\n" % (w * nx, h * ny, maxval))
    f.write(b"".join(rows) * ny)
name = dst.rsplit("/", 1)[-1] + ".pgm"
with open(src + ".yaml") as f, open(dst + ".yaml", "w") as g:
    for line in f:
        g.write(f"image: {name}\n" if line.lstrip().startswith("image:") else line)
print(f"{dst}.pgm: {w * nx} x {h * ny} cells ({nx} x {ny} tiles of {w} x {h})")
