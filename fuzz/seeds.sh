#!/usr/bin/env bash
# Seed corpora from the project's own files: the compiled maps, the board's
# scenario (whole and cut short), and link frames the lab's tests produce.
# Usage: bash fuzz/seeds.sh DIR
set -euo pipefail
cd "$(dirname "$0")/.."
d=${1:?usage: fuzz/seeds.sh DIR}
mkdir -p "$d/compiled_map" "$d/scenario" "$d/link_frames" "$d/predict_ekf"
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
PY
