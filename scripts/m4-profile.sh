#!/usr/bin/env bash
# Where the Cortex-M4's instructions go: runs the `ring_profile` firmware
# under QEMU with its execution log (-d in_asm,exec,nochain), counts the
# instructions of every executed block and attributes them to the symbol
# that holds the block's address. Prints the top functions (self cost).
# With LINES=1 it also attributes every instruction to its source line
# (innermost inlined frame, by llvm-addr2line) and prints the top lines.
# With PREDICT=1 it attributes each instruction inlined into
# `echoloc::predict::predict` to the line of `predict` it came from (the
# grid walk and candidate keys, their sort, the search call, ...) and every
# other one to the outermost function of its inlined chain: where a
# window's time goes, by the predictor's own steps.
# BIN=find_profile profiles the localizer searching instead (its first
# four ring cycles of the main firmware's find-itself scenario).
# Usage: [BIN=ring_profile] [LINES=1] [PREDICT=1] bash scripts/m4-profile.sh [TOP]
set -euo pipefail
cd "$(dirname "$0")/.."
target=thumbv7em-none-eabihf
cargo build -q -p qemu-mps2-an386 --bin "${BIN:=ring_profile}" --target "$target" --release
elf="target/$target/release/$BIN"
log=$(mktemp)
trap 'rm -f "$log" "$log.sym"' EXIT
timeout 300 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
  -icount shift=0 -semihosting-config enable=on,target=native -kernel "$elf" \
  -d in_asm,exec,nochain -D "$log"
host=$(rustc -vV | sed -n 's/^host: //p')
nm="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-nm"
"$nm" -n -C --defined-only "$elf" | awk '$2 ~ /^[tTwW]$/' >"$log.sym"
a2l=$(command -v addr2line || echo addr2line)  # binutils' reads the ARM ELF's DWARF
python3 - "$log" "$log.sym" "${1:-30}" "${LINES:-0}" "$a2l" "$elf" "${PREDICT:-0}" <<'PY'
import sys, re, bisect, collections, subprocess
log, symf, top, lines, a2l, elf = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4] == "1", sys.argv[5], sys.argv[6]
by_step = sys.argv[7] == "1"
syms = []
for line in open(symf):
    parts = line.split(None, 2)
    if len(parts) == 3:
        syms.append((int(parts[0], 16) & ~1, parts[2].strip()))
syms.sort()
addrs = [a for a, _ in syms]
size = {}            # block start -> instructions
pcs = {}             # block start -> its instruction addresses
cur = None
runs = collections.Counter()
for line in open(log, errors="replace"):
    if line.startswith("IN:"):
        cur = None
        continue
    m = re.match(r"0x([0-9a-f]{8}):\s", line)
    if m and cur is not None:
        size[cur] = size.get(cur, 0) + 1
        pcs[cur].append(int(m.group(1), 16))
        continue
    if m and cur is None:
        cur = int(m.group(1), 16)
        size[cur] = 1
        pcs[cur] = [cur]
        continue
    m = re.search(r"Trace \d+: 0x[0-9a-f]+ \[[0-9a-f]+/([0-9a-f]+)/", line)
    if m:
        runs[int(m.group(1), 16)] += 1
by = collections.Counter()
total = 0
for pc, n in runs.items():
    k = size.get(pc, 1) * n
    total += k
    i = bisect.bisect_right(addrs, pc) - 1
    by[syms[i][1] if i >= 0 else "?"] += k
print(f"{total} instructions executed")
for name, k in by.most_common(top):
    print(f"{k:>10} {100.0 * k / total:5.1f}%  {name[:110]}")
# Executions of every instruction address, for the two attributions below.
per_pc = collections.Counter()
for pc, n in runs.items():
    for a in pcs.get(pc, [pc]):
        per_pc[a] += n
addrs_l = sorted(per_pc)
if lines:
    out = subprocess.run([a2l, "-e", elf], input="\n".join(hex(a) for a in addrs_l), capture_output=True, text=True).stdout.split("\n")
    by_line = collections.Counter()
    for a, loc in zip(addrs_l, out):
        loc = re.sub(r".*/(src|library|registry/src/[^/]+)/", "", loc.strip())
        by_line[loc] += per_pc[a]
    print("\ntop source lines:")
    for loc, k in by_line.most_common(top):
        print(f"{k:>10} {100.0 * k / total:5.1f}%  {loc[:110]}")
if by_step:
    out = subprocess.run([a2l, "-e", elf, "-a", "-i", "-f", "-C"], input="\n".join(hex(a) for a in addrs_l),
                         capture_output=True, text=True).stdout.split("\n")
    chains, a, buf, i = {}, None, [], 0
    while i < len(out):
        if re.match(r"^0x[0-9a-f]+$", out[i]):
            if a is not None:
                chains[a] = buf
            a, buf, i = int(out[i], 16), [], i + 1
            continue
        if i + 1 < len(out):
            buf.append((out[i], re.sub(r".*/(src|library|registry/src/[^/]+)/", "", out[i + 1].strip())))
        i += 2
    if a is not None:
        chains[a] = buf
    by_key = collections.Counter()
    for a in addrs_l:
        ch = chains.get(a, [])
        key = None
        for fn, loc in ch:  # innermost first: the last match is the frame in `predict` itself
            if fn.startswith("echoloc::predict::predict<") or fn == "echoloc::predict::predict":
                key = "predict @ " + loc
        by_key[key or (ch[-1][0][:100] if ch else "?")] += per_pc[a]
    print("\nby the predictor's steps (instructions inlined into predict, by its line; the rest by function):")
    for k, n in by_key.most_common(top):
        print(f"{n:>10} {100.0 * n / total:5.1f}%  {k}")
PY
