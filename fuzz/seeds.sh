#!/usr/bin/env bash
# Seed corpora from the project's own files: the compiled maps, the board's
# scenario (whole and cut short), link frames, the office GeoJSON and small
# GeoJSON shapes, and the shared ROS maps cropped small (YAML, 0x00, image).
# Usage: bash fuzz/seeds.sh DIR
set -euo pipefail
cd "$(dirname "$0")/.."
d=${1:?usage: fuzz/seeds.sh DIR}
mkdir -p "$d/compiled_map" "$d/scenario" "$d/link_frames" "$d/predict_ekf" "$d/geojson" "$d/ros_map" "$d/bag"
# A small ROS 2 bag (the first 48 readings of the hand-made depot log, written
# by the independent writer with PyPI's rosbags, when it is installed).
bagtmp=$(mktemp -d)
head -n 50 lab/tests/data/depot-hand.csv >"$bagtmp/log.csv"
if python3 scripts/fixture-bag.py "$bagtmp/log.csv" "$bagtmp/bag" --form range >/dev/null 2>&1; then
  cp "$bagtmp"/bag/*.mcap "$d/bag/range.mcap"
fi
if python3 scripts/fixture-bag.py "$bagtmp/log.csv" "$bagtmp/cloud" --form cloud >/dev/null 2>&1; then
  cp "$bagtmp"/cloud/*.mcap "$d/bag/cloud.mcap"
fi
rm -rf "$bagtmp"
cp maps/office.geojson "$d/geojson/"
cp boards/qemu-mps2-an386/office.map boards/qemu-mps2-an386/depot.map "$d/compiled_map/"
head -c 4000 boards/qemu-mps2-an386/depot.scn >"$d/scenario/depot_head.scn"
python3 - "$d" <<'PY'
import struct, sys, zlib
d = sys.argv[1]
src = open("boards/qemu-mps2-an386/depot.scn", "rb").read()
head = struct.unpack_from("<H", src, 6)[0]
# The board's scenario cut to its first 40 records, re-sealed: small enough to replay fast.
n = 40
b = bytearray(src[:head + 40 * n])
struct.pack_into("<I", b, 16, n)
b += struct.pack("<I", zlib.crc32(bytes(b)) & 0xFFFFFFFF)
open(f"{d}/scenario/depot40.scn", "wb").write(b)
# Link frames: 0x00, COBS(version 1, postcard(msg), CRC-32 LE), 0x00.
def cobs(data):
    out, block = bytearray(), bytearray()
    for x in data:
        if x == 0:
            out.append(len(block) + 1); out += block; block = bytearray()
        else:
            block.append(x)
            if len(block) == 254:
                out.append(255); out += block; block = bytearray()
    out.append(len(block) + 1); out += block
    return bytes(out)
def frame(payload):
    body = bytes([1]) + payload
    return b"\x00" + cobs(body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)) + b"\x00"
# ToController::Odometry { time_us: varint, x, y, theta: f32 } is variant 0; End is variant 2.
odo = bytes([0, 0xE8, 0x07]) + struct.pack("<fff", 1.5, -0.25, 0.1)
open(f"{d}/link_frames/odometry_end.bin", "wb").write(frame(odo) + frame(bytes([2])) + b"\x17\x42\x00")
# predict_ekf: a map byte, a pose, a start and sigma, then a few readings.
vals = [0.0, 4000.0, 4000.0, 0.3, 4.0, 4.0, 0.0, 0.1, 0.1, 0.05] + [0.02, 0.0, 0.01, 1500.0] * 8
open(f"{d}/predict_ekf/office.bin", "wb").write(b"\x00\x00\x00\x00" + struct.pack(f"<{len(vals) - 1}f", *vals[1:]))
# GeoJSON: a polygon with a hole, walls, a multipolygon (metres).
shapes = {
    "hole": '{"type":"Polygon","coordinates":[[[0,0],[4,0],[4,3],[0,3],[0,0]],[[1,1],[2,1],[2,2],[1,2],[1,1]]]}',
    "walls": '{"type":"Feature","geometry":{"type":"MultiLineString","coordinates":[[[0,0],[5,0],[5,5]],[[7,1],[7,6]]]}}',
    "multi": '{"type":"FeatureCollection","features":[{"type":"Feature","geometry":{"type":"MultiPolygon","coordinates":[[[[0,0],[1,0],[0.5,1],[0,0]]],[[[3,3],[5,3],[5,4],[4,3.5],[3,4],[3,3]]]]}}]}',
}
for k, v in shapes.items():
    open(f"{d}/geojson/{k}.geojson", "w").write(v)
# ROS maps: each shared map's YAML, 0x00, a 64x64 crop of its image as PGM
# (P5) and as PNG (grey, 8-bit), so both decoders are reached.
def pgm(path):
    b = open(path, "rb").read()
    tok, pos = [], 2
    while len(tok) < 3:
        while b[pos:pos + 1].isspace(): pos += 1
        if b[pos:pos + 1] == b"#":
            while b[pos:pos + 1] != b"\n": pos += 1
            continue
        s = pos
        while not b[pos:pos + 1].isspace(): pos += 1
        tok.append(int(b[s:pos]))
    w, h, _ = tok
    return w, h, b[pos + 1:pos + 1 + w * h]
def png(w, h, rows):
    def chunk(t, data):
        return struct.pack(">I", len(data)) + t + data + struct.pack(">I", zlib.crc32(t + data) & 0xFFFFFFFF)
    raw = b"".join(b"\x00" + r for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
for name in ["depot", "tb3_sandbox"]:
    y = open(f"../shared/data/maps/{name}.yaml").read()
    w, h, px = pgm(f"../shared/data/maps/{name}.pgm")
    n = 64
    x0, y0 = max(0, w // 2 - n // 2), max(0, h // 2 - n // 2)
    rows = [px[(y0 + r) * w + x0:(y0 + r) * w + x0 + n] for r in range(min(n, h))]
    crop = b"P5\n%d %d\n255\n" % (len(rows[0]), len(rows)) + b"".join(rows)
    open(f"{d}/ros_map/{name}_pgm.bin", "wb").write(y.encode() + b"\x00" + crop)
    open(f"{d}/ros_map/{name}_png.bin", "wb").write(y.encode() + b"\x00" + png(len(rows[0]), len(rows), rows))
PY
