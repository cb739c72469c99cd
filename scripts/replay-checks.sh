#!/usr/bin/env bash
# The whole loop on the board (issue #12), against planted failures: the
# `replay` firmware reads a scenario from the flash partition at
# 0x0030_0000 (QEMU's generic loader puts the file there) and replays it
# through the ring driver, prediction, verdicts and the EKF.
#
#   1. the committed depot scenario: must pass (exit 0);
#   2. the same with its ground truth shifted by 1 m in x: must fail (exit 1,
#      "beyond the scenario's bounds");
#   3. the same with one bit flipped: must be refused (CRC);
#   4. a scenario made on another map (the office): must be refused (MapMismatch).
#
# The planted copies are made here in Python from the format in
# docs/scenario.md (zlib's CRC-32 is the format's), not by the project's writer.
set -euo pipefail
cd "$(dirname "$0")/.."
target=thumbv7em-none-eabihf
elf=${CARGO_TARGET_DIR:-target}/$target/release/replay
out=target/replay-checks
mkdir -p "$out"
cargo build -q -p qemu-mps2-an386 --bin replay --target "$target" --release

run() { # file -> output, exit code in $rc
  set +e
  log=$(timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
    -icount shift=0 -semihosting-config enable=on,target=native \
    -device "loader,file=$1,addr=0x00300000" -kernel "$elf" 2>&1)
  rc=$?
  set -e
}

python3 - boards/qemu-mps2-an386/depot.scn "$out" <<'PY'
import struct, sys, zlib
src, out = sys.argv[1], sys.argv[2]
b = bytearray(open(src, "rb").read())
head = struct.unpack_from("<H", b, 6)[0]
n = struct.unpack_from("<I", b, 16)[0]
def seal(buf):
    struct.pack_into("<I", buf, len(buf) - 4, zlib.crc32(bytes(buf[:-4])) & 0xFFFFFFFF)
    return buf
assert struct.unpack_from("<I", b, len(b) - 4)[0] == zlib.crc32(bytes(b[:-4])), "CRC of the committed scenario"
shifted = bytearray(b)
for i in range(n):
    o = head + 40 * i + 28  # true pose x, m
    struct.pack_into("<f", shifted, o, struct.unpack_from("<f", shifted, o)[0] + 1.0)
open(f"{out}/shifted.scn", "wb").write(seal(shifted))
flipped = bytearray(b)
flipped[head + 40 * (n // 2) + 12] ^= 0x04  # one echo time, CRC left as it was
open(f"{out}/flipped.scn", "wb").write(flipped)
other = bytearray(b)
struct.pack_into("<I", other, 8, 0xDEADBEEF)  # made on another map
open(f"{out}/other-map.scn", "wb").write(seal(other))
PY

fail=0
check() { # name file want-rc pattern
  run "$2"
  if [ "$rc" -ne "$3" ] || ! grep -q "$4" <<<"$log"; then
    echo "$log"
    echo "replay check '$1': exit code $rc (want $3), output lacks '$4'"
    fail=1
  else
    echo "replay check '$1': exit code $rc, '$(grep -m1 "$4" <<<"$log")'"
  fi
}
check "committed depot scenario" boards/qemu-mps2-an386/depot.scn 0 "within the scenario's bounds"
check "truth shifted by 1 m" "$out/shifted.scn" 1 "FAIL: pose error beyond the scenario's bounds"
check "one bit flipped" "$out/flipped.scn" 1 "FAIL: scenario refused: damaged"
check "made on another map" "$out/other-map.scn" 1 "FAIL: scenario refused: scenario: made on the map with CRC 0xdeadbeef"
exit $fail
