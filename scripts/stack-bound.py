#!/usr/bin/env python3
"""A static worst-case stack bound from a Cortex-M (Thumb-2) firmware ELF (issue #30 item 2).

Reads the ELF that runs (the stable `--release` build), disassembled by the
toolchain's own `llvm-objdump`, and bounds the stack of named roots:

* **Frames** from each function's instructions: every instruction that moves
  `sp` down counts, wherever it sits (`push`/`push.w`/`stmdb sp!`: 4 bytes a
  register; `vpush`/`vstmdb sp!`: 8 a d-register, 4 an s-register; `sub sp,
  #N`, `sub.w`/`subw sp, sp, #N`; `str`/`strd` with `[sp, #-N]!`; `sub sp, rX`
  when `rX` is a `movw`/`movt` constant set just before). Summing them all is
  an upper bound: code that moves `sp` down twice on two exclusive paths is
  counted twice. Any other write to `sp` (`mov sp, rX`, `sub sp, rX` of an
  unknown `rX`, a load into `sp`) makes the frame *unknown*, and so every
  path through it unbounded.
* **Calls** from `bl`/`blx` to an address, and tail calls: any branch
  (`b`, `b.w`, `b<cond>.w`, `cbz`, `cbnz`) whose target lies outside the
  function. A tail call is counted on top of the caller's whole frame (an
  upper bound: the caller has usually popped it).
* **Indirect calls** (`blx rN`, `bx rN` other than `lr`, a load or move into
  `pc` that is not a return): resolved when `rN` is loaded a few instructions
  before from a constant (a literal-pool word or a `movw`/`movt` pair) that is
  a function's address; otherwise *unresolved*: every path through the
  function is reported unbounded, with the call sites.
* **Recursion**: a cycle in the call graph makes the paths through it unbounded.

The bound of a root is its frame plus the deepest bound among its callees.
Exceptions: an exception taken while the root runs stacks its frame (with the
FPU in use, the extended frame: 26 words = 104 bytes, plus 4 bytes of
alignment padding) and then runs its handler; the deepest handler in the
vector table (every entry but the reset vector) is added on top: one level
of preemption, as on these boards (no interrupt is enabled, so only faults
can preempt; a fault inside a fault handler locks the core up).

Usage:
  stack-bound.py ELF --root LABEL=SYMBOL [...] [--measured LABEL=BYTES ...]
                 [--snapshot FILE --board NAME [--update]] [--top N]
                 [--stack-sizes ELF_WITH_STACK_SIZES]

SYMBOL matches a function whose demangled name (without its `::h…` hash)
ends with it, e.g. `qemu_mps2_an386::ring_cycle`; it must match exactly one.
`--measured` gives a painted high-water mark for a root (bytes below the
caller's stack pointer): the bound must be at least that, or the analysis
missed something (exit 1). `--snapshot` compares each bound with the
committed one for `--board` (exit 1 if it grew); `--update` rewrites them.
`--stack-sizes` cross-checks the prologue parse against LLVM's own frame
sizes (`-Z emit-stack-sizes` on nightly, read by `llvm-readobj --stack-sizes`)
for the functions both builds have by name.
"""

import argparse
import os
import re
import struct
import subprocess
import sys
from collections import defaultdict

EXC_FRAME = 104 + 4  # extended (FPU) exception frame + alignment padding


def tool(name):
    sysroot = subprocess.check_output(["rustc", "--print", "sysroot"], text=True).strip()
    host = re.search(r"^host: (\S+)", subprocess.check_output(["rustc", "-vV"], text=True), re.M).group(1)
    path = os.path.join(sysroot, "lib", "rustlib", host, "bin", name)
    if not os.path.exists(path):
        sys.exit(f"{path} missing: rustup component add llvm-tools")
    return path


class Elf:
    """The few ELF32 (little-endian) facts needed: loadable sections' bytes and the vector table."""

    def __init__(self, path):
        data = open(path, "rb").read()
        if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
            sys.exit(f"{path}: not a little-endian ELF32 file")
        shoff, = struct.unpack_from("<I", data, 0x20)
        shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
        secs = []
        for i in range(shnum):
            name, typ, flags, addr, off, size = struct.unpack_from("<IIIIII", data, shoff + i * shentsize)
            secs.append([name, typ, flags, addr, off, size])
        stroff = secs[shstrndx][4]
        self.sections = {}
        for name, typ, flags, addr, off, size in secs:
            n = data[stroff + name: data.index(b"\0", stroff + name)].decode()
            self.sections[n] = (typ, flags, addr, data[off: off + size] if typ != 8 else b"")

    def word(self, addr):
        for typ, flags, base, blob in self.sections.values():
            if flags & 2 and typ == 1 and base <= addr and addr + 4 <= base + len(blob):
                return struct.unpack_from("<I", blob, addr - base)[0]
        return None

    def vector_table(self):
        typ, flags, base, blob = self.sections[".vector_table"]
        return [struct.unpack_from("<I", blob, i)[0] for i in range(0, len(blob), 4)]


def strip_hash(name):
    return re.sub(r"::h[0-9a-f]{16}$", "", name)


class Func:
    def __init__(self, addr, size, names):
        self.addr, self.size, self.names = addr, size, names
        self.frame = 0
        self.unknown_sp = []  # instructions that write sp in a way not understood
        self.calls = set()  # callee addresses
        self.indirect = []  # (insn address, text) unresolved
        self.resolved = []  # (insn address, target)

    @property
    def name(self):
        return strip_hash(self.names[0])


REG_LIST = re.compile(r"\{([^}]*)\}")


def count_regs(text):
    m = REG_LIST.search(text)
    n4 = n8 = 0
    for r in m.group(1).split(","):
        r = r.strip()
        rng = re.fullmatch(r"([rsd])(\d+)-[rsd](\d+)", r)
        k = int(rng.group(3)) - int(rng.group(2)) + 1 if rng else 1
        if r.startswith("d"):
            n8 += k
        else:
            n4 += k
    return 4 * n4 + 8 * n8


def parse(elf_path):
    nm = subprocess.check_output([tool("llvm-nm"), "-n", "-S", "-C", "--defined-only", elf_path], text=True)
    starts = defaultdict(list)
    sizes = {}
    for line in nm.splitlines():
        parts = line.split(" ", 3)
        if len(parts) == 4 and parts[2] in "tTwW":
            addr, size = int(parts[0], 16) & ~1, int(parts[1], 16)
            starts[addr].append(parts[3])
            sizes[addr] = max(sizes.get(addr, 0), size)
    funcs = {a: Func(a, sizes[a], sorted(set(n), key=lambda s: (s.startswith("_"), len(s)))) for a, n in starts.items()}
    order = sorted(funcs)
    # Function extents: the symbol's size, or up to the next symbol when it has none.
    ends = {}
    for i, a in enumerate(order):
        nxt = order[i + 1] if i + 1 < len(order) else 1 << 32
        ends[a] = a + funcs[a].size if funcs[a].size else nxt

    def owner(addr):
        import bisect
        i = bisect.bisect_right(order, addr) - 1
        if i >= 0 and addr < ends[order[i]]:
            return order[i]
        return None

    dis = subprocess.check_output([tool("llvm-objdump"), "-d", "--no-show-raw-insn", elf_path], text=True)
    elf = Elf(elf_path)
    insn_re = re.compile(r"^\s*([0-9a-f]+):\s+([a-z][\w.]*)\s*(.*)$")
    cur = None
    window = []  # recent instructions of the current function: (mnemonic, operands)
    for line in dis.splitlines():
        m = insn_re.match(line)
        if not m:
            continue
        addr, mn, ops = int(m.group(1), 16), m.group(2), m.group(3)
        ops = ops.split("@")[0].strip() if not mn.startswith("ldr") else ops.strip()
        fa = owner(addr)
        if fa is None or mn.startswith("."):
            continue
        if fa != cur:
            cur, window = fa, []
        f = funcs[fa]
        window = (window + [(mn, ops)])[-12:]
        base = mn.split(".")[0]
        # --- stack pointer adjustments
        dest_sp = re.match(r"sp\b", ops) is not None
        neg = re.search(r"\[sp, #-(0x[0-9a-f]+|\d+)\]!", ops)
        if base in ("push", "vpush") or (base in ("stmdb", "vstmdb") and ops.startswith("sp!")):
            f.frame += count_regs(ops)
        elif re.match(r"(str|vstr)[bhd]?$", base) and neg:
            f.frame += int(neg.group(1), 0)
        elif dest_sp and base in ("sub", "subs", "subw"):
            imm = re.search(r"#(0x[0-9a-f]+|\d+)$", ops)
            if imm:
                f.frame += int(imm.group(1), 0)
            else:
                val = const_in(window[:-1], ops.split(",")[-1].strip())
                if val is None:
                    f.unknown_sp.append((addr, f"{mn} {ops}"))
                else:
                    f.frame += val
        elif dest_sp and base in ("add", "adds", "addw"):
            imm = re.search(r"#(-?)(0x[0-9a-f]+|\d+)$", ops)
            if imm is None:
                f.unknown_sp.append((addr, f"{mn} {ops}"))
            elif imm.group(1):
                f.frame += int(imm.group(2), 0)
        elif base in ("pop", "vpop") or (base in ("ldm", "ldmia", "vldmia", "vldm") and ops.startswith("sp!")):
            pass  # sp goes up
        elif dest_sp and not base.startswith(("str", "stm", "vstr", "vstm", "cmp", "cmn", "tst", "teq")):
            f.unknown_sp.append((addr, f"{mn} {ops}"))
        # --- calls
        target = re.match(r"(0x[0-9a-f]+)\b", ops.split(",")[-1].strip())
        if base in ("bl", "blx") and target:
            t = int(target.group(1), 16)
            o = owner(t)
            if o is None:
                f.indirect.append((addr, f"{mn} {ops} (outside every function)"))
            else:
                f.calls.add(o)
        elif base in ("blx", "bx") and re.fullmatch(r"r\d+|r1[0-2]|ip|sb|sl|fp", ops):
            val = const_in(window[:-1], ops)
            if val is not None and owner(val & ~1) == (val & ~1):
                f.calls.add(val & ~1)
                f.resolved.append((addr, val & ~1))
            else:
                f.indirect.append((addr, f"{mn} {ops}"))
        elif (base == "b" or re.match(r"b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)$", base) or base in ("cbz", "cbnz")) and target:
            t = int(target.group(1), 16)
            if not (fa <= t < ends[fa]):
                o = owner(t)
                if o is None:
                    f.indirect.append((addr, f"{mn} {ops} (outside every function)"))
                else:
                    f.calls.add(o)
        elif (base in ("mov", "ldr") and ops.startswith("pc")) or (base in ("ldm", "ldmia") and "pc" in ops and not ops.startswith("sp!")):
            f.indirect.append((addr, f"{mn} {ops}"))
        # literal-pool loads: remember the constant for const_in
        if base == "ldr":
            lit = re.search(r"\[pc, #[^\]]*\]\s*@\s*(0x[0-9a-f]+)", ops)
            if lit:
                w = elf.word(int(lit.group(1), 16))
                reg = ops.split(",")[0].strip()
                window[-1] = ("=lit", f"{reg}, {w}")
    return funcs, elf


def const_in(window, reg):
    """The constant `reg` holds after `window` (a few instructions, oldest first), if it is one."""
    lo = hi = None
    for mn, ops in reversed(window):
        parts = [p.strip() for p in ops.split(",")]
        if not parts or parts[0] != reg:
            continue
        if mn == "=lit":
            return int(parts[1]) if parts[1] != "None" else None
        if mn.startswith("movt") and hi is None:
            hi = int(parts[1].lstrip("#"), 0)
            continue
        if mn.startswith(("movw", "mov")) and parts[1].startswith("#"):
            lo = int(parts[1].lstrip("#"), 0)
            return ((hi or 0) << 16) | lo if hi is not None else lo
        return None  # written by something else
    return None


def bound(funcs, root):
    """(bytes, reasons, path): the deepest path from `root`; reasons is empty when it is a bound."""
    memo = {}
    onstack = set()

    def go(a):
        if a in memo:
            return memo[a]
        if a in onstack:
            return (0, {f"recursion through {funcs[a].name}"}, [])
        onstack.add(a)
        f = funcs[a]
        reasons = set()
        if f.unknown_sp:
            reasons.add(f"{f.name}: sp written in a way not understood ({f.unknown_sp[0][1]} at {f.unknown_sp[0][0]:#x})")
        for addr, text in f.indirect:
            reasons.add(f"{f.name}: unresolved indirect call `{text}` at {addr:#x}")
        best, path = 0, []
        for c in sorted(f.calls):
            d, r, p = go(c)
            reasons |= r
            if d > best:
                best, path = d, p
        onstack.discard(a)
        res = (f.frame + best, frozenset(reasons), [a] + path)
        memo[a] = res
        return res

    return go(root)


def find(funcs, symbol):
    hits = [a for a, f in funcs.items() if any(strip_hash(n) == symbol or strip_hash(n).endswith("::" + symbol) for n in f.names)]
    if len(hits) != 1:
        sys.exit(f"root {symbol!r} matches {len(hits)} functions: " + ", ".join(funcs[a].name for a in hits[:8]))
    return hits[0]


def stack_sizes(path):
    out = subprocess.check_output([tool("llvm-readobj"), "--stack-sizes", path], text=True, stderr=subprocess.STDOUT)
    sizes = {}
    for fm, sz in re.findall(r"Functions: \[([^\]]*)\]\s*Size: (0x[0-9A-Fa-f]+|\d+)", out):
        for name in fm.split(","):
            sizes[name.strip()] = int(sz, 0)
    return sizes


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("elf")
    ap.add_argument("--root", action="append", default=[], help="LABEL=SYMBOL")
    ap.add_argument("--measured", action="append", default=[], help="LABEL=BYTES")
    ap.add_argument("--snapshot")
    ap.add_argument("--board")
    ap.add_argument("--update", action="store_true")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--stack-sizes", help="an ELF built with -Z emit-stack-sizes, to cross-check the frames")
    ap.add_argument("--graph", help="print the calls and frames under this root symbol")
    args = ap.parse_args()

    funcs, elf = parse(args.elf)
    fail = []

    # The handlers that can preempt: every vector but the initial SP and Reset.
    vt = elf.vector_table()
    handlers = {}
    for v in vt[2:]:
        a = v & ~1
        if v and a in funcs:
            handlers[a] = funcs[a]
    worst_h, worst_h_name, h_reasons = 0, "-", set()
    for a, f in handlers.items():
        d, r, p = bound(funcs, a)
        if r:
            h_reasons |= {f"handler {f.name}: {x}" for x in r}
        if d > worst_h:
            worst_h, worst_h_name = d, " -> ".join(funcs[x].name for x in p)
    print(f"{args.elf}: {len(funcs)} functions, {len(handlers)} distinct exception handlers in the vector table")
    print(f"deepest handler: {worst_h} bytes ({worst_h_name}), +{EXC_FRAME} bytes of exception frame")
    if h_reasons:
        print("  the handlers are not all bounded:")
        for r in sorted(h_reasons):
            print("   ", r)

    print(f"\nlargest frames:")
    for f in sorted(funcs.values(), key=lambda f: -f.frame)[: args.top]:
        print(f"  {f.frame:>7}  {f.name}")

    measured = dict(kv.split("=", 1) for kv in args.measured)
    results = {}
    print()
    for spec in args.root:
        label, symbol = spec.split("=", 1)
        a = find(funcs, symbol)
        d, reasons, path = bound(funcs, a)
        total = d + EXC_FRAME + worst_h
        results[label] = (d, reasons, total)
        state = "bound" if not reasons else "NOT BOUNDED (lower estimate)"
        print(f"root {label} ({funcs[a].name}): {d} bytes [{state}]; with the deepest handler on top: {total}")
        print("  deepest path: " + " -> ".join(f"{funcs[x].name} [{funcs[x].frame}]" for x in path))
        for r in sorted(reasons):
            print("  why not bounded:", r)
        if label in measured:
            m = int(measured[label])
            ok = d >= m
            print(f"  measured high-water mark (painted): {m} bytes; bound {'>=' if ok else '<'} measured"
                  + ("" if ok else ": the analysis missed something"))
            if not ok and not reasons:
                fail.append(f"{label}: bound {d} < measured {m}")

    if args.graph:
        a = find(funcs, args.graph)
        seen = set()

        def show(x, depth):
            f = funcs[x]
            d, r, _ = bound(funcs, x)
            print(f"{'  ' * depth}{f.name} frame {f.frame} bound {d}{' (unbounded)' if r else ''}")
            if x in seen:
                return
            seen.add(x)
            for c in sorted(f.calls, key=lambda c: -bound(funcs, c)[0]):
                show(c, depth + 1)

        print()
        show(a, 0)

    if args.stack_sizes:
        ref = stack_sizes(args.stack_sizes)
        # Compare by name without the hash (the two builds hash differently).
        by_name = defaultdict(set)
        for f in funcs.values():
            for n in f.names:
                by_name[strip_hash(n)].add(f.frame)
        ref_by = defaultdict(set)
        demangled = subprocess.run(["rustfilt"], input="\n".join(ref), capture_output=True, text=True) if False else None
        cf = subprocess.check_output([tool("llvm-nm"), "-C", "--defined-only", args.stack_sizes], text=True)
        mangled = subprocess.check_output([tool("llvm-nm"), "--defined-only", args.stack_sizes], text=True)
        dm = {}
        for l1, l2 in zip(mangled.splitlines(), cf.splitlines()):
            dm[l1.split(" ", 2)[-1]] = l2.split(" ", 2)[-1]
        for n, s in ref.items():
            ref_by[strip_hash(dm.get(n, n))].add(s)
        agree = differ = 0
        diffs = []
        for n, s in ref_by.items():
            if n in by_name and len(s) == 1 and len(by_name[n]) == 1:
                if s == by_name[n]:
                    agree += 1
                else:
                    differ += 1
                    diffs.append((n, min(s), min(by_name[n])))
        print(f"\ncross-check with LLVM's stack sizes ({args.stack_sizes}): {agree} functions agree, {differ} differ")
        for n, s, p in diffs[:20]:
            print(f"  {n}: LLVM {s}, prologue parse {p}")
        if differ:
            under = [d for d in diffs if d[2] < d[1]]
            if under:
                fail.append(f"{len(under)} frames below LLVM's own size")

    if args.snapshot and args.board:
        snap = {}
        lines = open(args.snapshot).read().splitlines() if os.path.exists(args.snapshot) else []
        for line in lines:
            if line.strip() and not line.startswith("#"):
                b, label, v = line.split()[:3]
                snap[(b, label)] = v
        if args.update:
            for label, (d, reasons, total) in results.items():
                snap[(args.board, label)] = str(d) if not reasons else "unbounded"
                snap[(args.board, label + "+handler")] = str(total) if not (reasons or h_reasons) else "unbounded"
            with open(args.snapshot, "w") as fh:
                fh.write("# Static worst-case stack bounds, bytes (scripts/stack-bound.sh; --update rewrites).\n")
                fh.write("# board root bound; `+handler`: with the deepest exception handler and its frame on top.\n")
                for (b, label), v in sorted(snap.items()):
                    fh.write(f"{b} {label} {v}\n")
            print(f"\nsnapshot updated: {args.snapshot} ({args.board})")
        else:
            print()
            for label, (d, reasons, total) in results.items():
                for lab, v, unb in ((label, d, bool(reasons)), (label + "+handler", total, bool(reasons or h_reasons))):
                    s = snap.get((args.board, lab))
                    now = "unbounded" if unb else str(v)
                    if s is None:
                        fail.append(f"{args.board} {lab}: not in the snapshot {args.snapshot}")
                    elif s == "unbounded" or now == "unbounded":
                        if s != now:
                            fail.append(f"{args.board} {lab}: {now}, snapshot {s}")
                        print(f"{args.board} {lab}: {now} (snapshot {s})")
                    else:
                        grew = int(now) > int(s)
                        print(f"{args.board} {lab}: {now} bytes (snapshot {s}){' GREW' if grew else ''}")
                        if grew:
                            fail.append(f"{args.board} {lab}: {now} bytes grew past the snapshot's {s}")
    if fail:
        print("\nFAIL:", "; ".join(fail))
        sys.exit(1)


if __name__ == "__main__":
    main()
