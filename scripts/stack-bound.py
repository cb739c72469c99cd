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
                 [--reentry-guarded SYMBOL] [--expect-flipped] [--stack-sizes]
                 [--graph SYMBOL] [--path-to SYMBOL]

SYMBOL matches a function whose demangled name (without its `::h…` hash)
ends with it, e.g. `qemu_mps2_an386::ring_cycle`; it must match exactly one.
`--measured` gives a painted high-water mark for a root (bytes below the
caller's stack pointer): the bound must be at least that, or the analysis
missed something (exit 1). `--snapshot` compares each bound with the
committed one for `--board` (exit 1 if it grew); `--update` rewrites them.
`--stack-sizes` cross-checks the parsed frames against LLVM's own frame
sizes in the same image (built by nightly with `-Z emit-stack-sizes`, read
by `llvm-readobj --stack-sizes`): a parsed frame below LLVM's fails.
`--reentry-guarded SYMBOL`: see `bound`. `--expect-flipped`: fail unless the
initial stack pointer lies at or below `.data`/`.bss`/`.uninit` (flip-link).
`--graph SYMBOL` prints the call tree under a function with frames and
bounds; `--path-to SYMBOL` a shortest call chain from each root to it.
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
    """The demangled name without its legacy hash (`::h…`) or, in v0
    mangling, its trailing generic arguments (`::<…>`)."""
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    if name.endswith(">") and "::<" in name:
        depth = 0
        for i in range(len(name) - 1, -1, -1):
            depth += {">": 1, "<": -1}.get(name[i], 0)
            if depth == 0:
                if name[i - 2: i] == "::":
                    name = name[: i - 2]
                break
    return name


class Func:
    def __init__(self, addr, size, names):
        self.addr, self.size, self.names = addr, size, names
        self.frame = 0
        self.unknown_sp = []  # instructions that write sp in a way not understood
        self.calls = set()  # callee addresses
        self.indirect = []  # (insn address, text) unresolved
        self.resolved = []  # (insn address, target)
        self.pending = []  # indirect calls not resolved locally: (address, text, register)
        self.insns = []  # (address, mnemonic, operands, literal word or None)
        self.computed_jump = False

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
    funcs = {a: Func(a, sizes[a], sorted(set(n), key=lambda s: (not ("Handler" in s or "::" in s or s[:1].islower()), s.startswith("_"), len(s)))) for a, n in starts.items()}
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
    orphans = []  # instructions outside every function symbol: their calls would go unseen
    window = []  # recent instructions of the current function: (mnemonic, operands)
    for line in dis.splitlines():
        if re.search(r"\t\.(word|short|byte|long|zero)\b", line):
            continue  # data in the code (literal pools, tables)
        m = insn_re.match(line)
        if not m:
            continue
        addr, mn, ops = int(m.group(1), 16), m.group(2), m.group(3)
        ops = ops.split("@")[0].strip() if not mn.startswith("ldr") else ops.strip()
        if mn.startswith("."):
            continue  # data in the code (literal pools, tables)
        fa = owner(addr)
        if fa is None:
            orphans.append((addr, f"{mn} {m.group(3)}"))
            continue
        if fa != cur:
            cur, window = fa, []
        f = funcs[fa]
        window = (window + [(mn, ops)])[-48:]
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
            f.pending.append((addr, f"{mn} {ops}", ops))
        elif (base == "b" or re.match(r"b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)$", base) or base in ("cbz", "cbnz")) and target:
            t = int(target.group(1), 16)
            if not (fa <= t < ends[fa]):
                o = owner(t)
                if o is None:
                    f.indirect.append((addr, f"{mn} {ops} (outside every function)"))
                else:
                    f.calls.add(o)
        elif base == "mov" and ops.startswith("pc") and jump_table(window[:-1], ops.split(",")[-1].strip()):
            f.computed_jump = True  # a table of branches inside this function (`adr rN, table; add rN, rN, rI, lsl #2; mov pc, rN`)
        elif base in ("tbb", "tbh"):
            f.computed_jump = True  # a table of offsets inside this function
        elif base == "ldr" and re.fullmatch(r"pc, \[sp\], #(0x[0-9a-f]+|\d+)", ops):
            pass  # a return (pop of the saved lr into pc)
        elif (base in ("mov", "ldr") and ops.startswith("pc")) or (base in ("ldm", "ldmia") and "pc" in ops and not ops.startswith("sp!")):
            f.indirect.append((addr, f"{mn} {ops}"))
        lit = None
        if base == "ldr":
            m2 = re.search(r"\[pc, #[^\]]*\]\s*@\s*(0x[0-9a-f]+)", ops)
            if m2:
                lit = elf.word(int(m2.group(1), 16))
                window[-1] = ("=lit", f"{ops.split(',')[0].strip()}, {lit}")
        f.insns.append((addr, mn, ops, lit))
    for a, f in funcs.items():
        resolve_pending(f, funcs, owner)
    # Padding between functions: lld's Thumb fill 0xd4d4 decodes as
    # `bmi` back by 0x58; zeros as `movs r0, r0`.
    orphans = [(a, t) for a, t in orphans
               if t.strip() not in ("movs r0, r0", "nop") and not re.fullmatch(r"bmi\s+\S+ <[^>]*>\s*@ imm = #-0x58", t.strip())]
    if orphans:
        sys.exit(f"{elf_path}: {len(orphans)} instructions outside every function symbol (first: {orphans[0][1]} at "
                 f"{orphans[0][0]:#x}): the call graph would miss them")
    return funcs, elf


TOP = None  # an unknown value
MAX_VALUES = 8
BRANCH_COND = r"(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le)"


def join(a, b):
    if a is TOP or b is TOP:
        return TOP
    u = a | b
    return u if len(u) <= MAX_VALUES else TOP


def transfer(state, insn, conditional):
    """The register constants after one instruction (AAPCS: a call keeps r4-r11)."""
    addr, mn, ops, lit = insn
    base = mn.split(".")[0]
    parts = [p.strip() for p in ops.split(",")]
    out = dict(state)
    writes = {}
    if base in ("bl", "blx"):
        for r in ("r0", "r1", "r2", "r3", "r12", "lr"):
            writes[r] = TOP
    elif base == "pop" or base.startswith("ldm"):
        for r in re.findall(r"\b(r\d+|lr)\b", ops.split("{")[-1]):
            writes[r] = TOP
    elif parts and re.fullmatch(r"r\d+|lr", parts[0]) and not base.startswith(
        ("str", "stm", "vstr", "vstm", "cmp", "cmn", "tst", "teq", "push", "b", "cb", "it", "tb")
    ):
        r = parts[0]
        if lit is not None:
            writes[r] = {lit}
        elif re.fullmatch(r"(movw|movs?)", base) and len(parts) == 2 and parts[1].startswith("#"):
            writes[r] = {int(parts[1].lstrip("#"), 0) & 0xFFFFFFFF}
        elif base == "movt":
            v = state.get(r, TOP)
            hi = int(parts[1].lstrip("#"), 0)
            writes[r] = TOP if v is TOP else {(x & 0xFFFF) | (hi << 16) for x in v}
        elif re.fullmatch(r"movs?", base) and len(parts) == 2 and re.fullmatch(r"r\d+|lr", parts[1]):
            writes[r] = state.get(parts[1], TOP)
        elif re.fullmatch(r"mov" + BRANCH_COND, base) and len(parts) == 2:
            # a conditional move: the old value may stay
            conditional = True
            writes[r] = {int(parts[1].lstrip("#"), 0) & 0xFFFFFFFF} if parts[1].startswith("#") else state.get(parts[1], TOP)
        else:
            writes[r] = TOP
        # instructions with a second destination
        if base in ("ldrd", "ldrexd", "umull", "smull", "umlal", "smlal", "vmov") and len(parts) > 1:
            if re.fullmatch(r"r\d+|lr", parts[1]):
                writes[parts[1]] = TOP
    # base registers written back (`[rX, #n]!`, `[rX], #n`, `ldm rX!`, `stm rX!`)
    for r in re.findall(r"\[(r\d+|lr)[^\]]*\]!", ops) + re.findall(r"\[(r\d+|lr)\], ", ops) + re.findall(r"^(r\d+|lr)!", ops):
        writes[r] = TOP
    if base.startswith("strex") and parts:
        writes[parts[0]] = TOP
    for r, v in writes.items():
        out[r] = join(state.get(r, TOP), v) if conditional else v
    return out


def register_values(f):
    """For each instruction of `f`, the constants each register may hold
    before it: a forward data-flow over the function's own control flow
    (branches inside the function, fall-through, `it` blocks as maybe-taken
    writes). A table jump (`tbb`, `tbh`, a branch table) may land anywhere:
    its state flows into every instruction."""
    insns = f.insns
    index = {a: i for i, (a, _, _, _) in enumerate(insns)}
    succ = []
    cond_flags = []
    it_left = 0
    anywhere = set()
    for i, (addr, mn, ops, lit) in enumerate(insns):
        base = mn.split(".")[0]
        cond_flags.append(it_left > 0)
        if it_left:
            it_left -= 1
        if re.fullmatch(r"it[te]{0,3}", base):
            it_left = len(base) - 1
        nxt = [i + 1] if i + 1 < len(insns) else []
        tgt = re.match(r"(0x[0-9a-f]+)\b", ops.split(",")[-1].strip())
        t = int(tgt.group(1), 16) if tgt else None
        if base == "b" and t is not None and not cond_flags[-1]:
            s = [index[t]] if t in index else []
        elif (re.fullmatch(r"b" + BRANCH_COND, base) or base in ("cbz", "cbnz") or base == "b") and t is not None:
            s = nxt + ([index[t]] if t in index else [])
        elif (base == "bx" and ops == "lr") or (base == "pop" and "pc" in ops) or (base == "ldr" and ops.startswith("pc")):
            s = nxt if cond_flags[-1] else []
        elif base in ("tbb", "tbh") or (base == "mov" and ops.startswith("pc")):
            s = []
            anywhere.add(i)
        elif base == "bx":
            s = nxt if cond_flags[-1] else []
        else:
            s = nxt
        succ.append(s)
    before = [None] * len(insns)  # None: not reached
    if insns:
        before[0] = {}
    work = [0] if insns else []
    while work:
        i = work.pop()
        after = transfer(before[i], insns[i], cond_flags[i])
        after = {r: v for r, v in after.items() if v is not TOP}
        targets = succ[i] + (list(range(len(insns))) if i in anywhere else [])
        for j in targets:
            if before[j] is None:
                before[j] = dict(after)
                work.append(j)
            else:
                merged = {r: join(before[j].get(r, TOP), after.get(r, TOP)) for r in set(before[j]) | set(after)}
                merged = {r: v for r, v in merged.items() if v is not TOP}
                if merged != before[j]:
                    before[j] = merged
                    work.append(j)
    return index, before


def resolve_pending(f, funcs, owner):
    """Indirect calls (`blx rN`, `bx rN`) whose register can only hold
    constants at the call (by `register_values`) that are functions'
    addresses: calls to each of them. The rest stay unresolved."""
    if not f.pending:
        return
    index, before = register_values(f)
    for addr, text, reg in f.pending:
        st = before[index[addr]]
        vals = None if st is None else st.get(reg, TOP)
        if vals and all(owner(v & ~1) == (v & ~1) for v in vals):
            for v in vals:
                f.calls.add(v & ~1)
                f.resolved.append((addr, v & ~1))
        else:
            f.indirect.append((addr, text))


def jump_table(window, reg):
    """`reg` = `adr` of a table (pc-relative, so inside this function) plus a scaled index: a branch table."""
    for mn, ops in reversed(window):
        parts = [p.strip() for p in ops.split(",")]
        if not parts or parts[0] != reg:
            continue
        if mn.startswith("add") and len(parts) >= 3 and "lsl" in ops:
            reg = parts[1]  # table base + index << n: follow the base
            continue
        return mn.startswith("adr")
    return False


def const_in(window, reg):
    """The constant `reg` holds after `window` (a few instructions just before, oldest first), if it is one."""
    hi = None
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
            return ((hi or 0) << 16) | lo
        return None  # written by something else
    return None


def bound(funcs, root, guarded=frozenset()):
    """(bytes, reasons, path): the deepest path from `root`; reasons is empty when it is a bound.

    A function in `guarded` (`--reentry-guarded`) may be re-entered once
    while it runs (its code stops a second entry at once, e.g. a panic
    handler's flag): the cycle is followed a second time in full, an upper
    bound of that second entry, and cut at the third. Any other cycle is
    recursion, reported unbounded."""
    memo = {}
    stack = []

    def go(a):
        depth_g = tuple(stack.count(g) for g in sorted(guarded))
        if a in guarded and stack.count(a) >= 2:
            return (0, frozenset(), [])
        last_g = max([i for i, x in enumerate(stack) if x in guarded], default=-1)
        if a not in guarded and a in stack[last_g + 1:]:
            return (0, frozenset({f"recursion through {funcs[a].name}"}), [])
        key = (a, depth_g)
        if key in memo:
            return memo[key]
        stack.append(a)
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
        stack.pop()
        res = (f.frame + best, frozenset(reasons), [a] + path)
        memo[key] = res
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
    ap.add_argument("--stack-sizes", action="store_true",
                    help="cross-check the frames with LLVM's (the image built with nightly's -Z emit-stack-sizes)")
    ap.add_argument("--graph", help="print the calls and frames under this root symbol")
    ap.add_argument("--reentry-guarded", action="append", default=[],
                    help="SYMBOL: a function that stops a second entry while it runs (a cycle through it is followed twice)")
    ap.add_argument("--expect-flipped", action="store_true", help="fail unless the initial SP lies below .data/.bss/.uninit (flip-link)")
    ap.add_argument("--path-to", help="print a shortest call chain from each root to this symbol")
    args = ap.parse_args()

    funcs, elf = parse(args.elf)
    fail = []
    guarded = frozenset(find(funcs, g) for g in args.reentry_guarded)

    # The handlers that can preempt: every vector but the initial SP and Reset.
    vt = elf.vector_table()
    handlers = {}
    for v in vt[2:]:
        a = v & ~1
        if v and a in funcs:
            handlers[a] = funcs[a]
    worst_h, worst_h_name, h_reasons = 0, "-", set()
    for a, f in handlers.items():
        d, r, p = bound(funcs, a, guarded)
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

    resolved = [(f, a, t) for f in funcs.values() for a, t in f.resolved]
    if resolved:
        by = defaultdict(set)
        for f, a, t in resolved:
            by[(f.name, a)].add(funcs[t].name)
        print(f"indirect calls resolved by the register data-flow: {len(by)}")
        for (name, a), ts in sorted(by.items()):
            print(f"  {name} at {a:#x} -> {', '.join(sorted(ts))}")

    print(f"\nlargest frames:")
    for f in sorted(funcs.values(), key=lambda f: -f.frame)[: args.top]:
        print(f"  {f.frame:>7}  {f.name}")

    measured = dict(kv.split("=", 1) for kv in args.measured)
    results = {}
    print()
    for spec in args.root:
        label, symbol = spec.split("=", 1)
        a = find(funcs, symbol)
        d, reasons, path = bound(funcs, a, guarded)
        total = d + EXC_FRAME + worst_h
        results[label] = (d, reasons, total)
        state = "bound" if not reasons else "NOT BOUNDED (lower estimate)"
        on_top = f"{total}" if not (reasons or h_reasons) else f"not bounded ({total} without the unbounded paths)"
        print(f"root {label} ({funcs[a].name}): {d} bytes [{state}]; with the deepest handler on top: {on_top}")
        print("  deepest path: " + " -> ".join(f"{funcs[x].name} [{funcs[x].frame}]" for x in path))
        for r in sorted(reasons):
            print("  why not bounded:", r)
        if label in measured:
            m = int(measured[label])
            ok = d >= m
            if reasons:
                print(f"  measured high-water mark (painted): {m} bytes; the lower estimate is {'at least' if ok else 'below'} it"
                      " (no check: not bounded)")
            else:
                print(f"  measured high-water mark (painted): {m} bytes; bound {'>=' if ok else '<'} measured"
                      + (f" (margin {d - m} bytes)" if ok else ": the analysis missed something"))
            if not ok and not reasons:
                fail.append(f"{label}: bound {d} < measured {m}")

    if args.expect_flipped:
        # flip-link: the initial stack pointer (the vector table's first word)
        # at or below the lowest RAM section, so the stack grows away from them.
        ram = {n: (addr, len(blob) if typ != 8 else None) for n, (typ, flags, addr, blob) in elf.sections.items()
               if flags & 2 and addr >= 0x2000_0000 and n in (".data", ".bss", ".uninit")}
        low = min(a for a, _ in ram.values())
        sp0 = vt[0]
        ok = sp0 <= low
        print(f"\nflip-link: initial SP {sp0:#010x}, lowest static in RAM at {low:#010x} ("
              + ", ".join(f"{n} {a:#010x}" for n, (a, _) in sorted(ram.items(), key=lambda x: x[1][0])) + "): "
              + ("the stack lies below the statics" if ok else "NOT flipped: the stack lies above the statics"))
        if not ok:
            fail.append("the stack is not below .data/.bss (not linked with flip-link?)")

    if args.path_to:
        target = find(funcs, args.path_to)
        for spec in args.root:
            label, symbol = spec.split("=", 1)
            a = find(funcs, symbol)
            prev, todo = {a: None}, [a]
            while todo and target not in prev:
                nxt = []
                for x in todo:
                    for c in sorted(funcs[x].calls):
                        if c not in prev:
                            prev[c] = x
                            nxt.append(c)
                todo = nxt
            chain, x = [], target if target in prev else None
            while x is not None:
                chain.append(funcs[x].name)
                x = prev[x]
            print(f"\n{label} reaches {funcs[target].name}: " + (" -> ".join(reversed(chain)) if chain else "no"))

    if args.graph:
        a = find(funcs, args.graph)
        seen = set()

        def show(x, depth):
            f = funcs[x]
            d, r, _ = bound(funcs, x, guarded)
            print(f"{'  ' * depth}{f.name} frame {f.frame} bound {d}{' (unbounded)' if r else ''}")
            if x in seen:
                return
            seen.add(x)
            for c in sorted(f.calls, key=lambda c: -bound(funcs, c, guarded)[0]):
                show(c, depth + 1)

        print()
        show(a, 0)

    if args.stack_sizes:
        # LLVM's own frame size per function (`-Z emit-stack-sizes`), from this
        # same image: an oracle for the frames parsed from the instructions.
        ref = stack_sizes(args.elf)
        addr_of = {}
        for f in funcs.values():
            for n in f.names:
                addr_of[n] = f.addr
        mangled = subprocess.check_output([tool("llvm-nm"), "--defined-only", args.elf], text=True)
        demangled = subprocess.check_output([tool("llvm-nm"), "-C", "--defined-only", args.elf], text=True)
        dm = {a.split(" ", 2)[-1]: b.split(" ", 2)[-1] for a, b in zip(mangled.splitlines(), demangled.splitlines())}
        agree, diffs, missing = 0, [], 0
        for n, size in sorted(ref.items()):
            a = addr_of.get(dm.get(n, n))
            if a is None:
                missing += 1
                continue
            if funcs[a].frame == size:
                agree += 1
            else:
                diffs.append((funcs[a].name, size, funcs[a].frame))
        print(f"\ncross-check with LLVM's stack sizes: {len(ref)} functions have one, {agree} agree with the parse, "
              f"{len(diffs)} differ, {missing} not found by name")
        for n, llvm, parsed in diffs:
            print(f"  {n}: LLVM {llvm}, parsed {parsed} ({'above: conservative' if parsed > llvm else 'BELOW LLVM'})")
        under = [d for d in diffs if d[2] < d[1]]
        if under:
            fail.append(f"{len(under)} parsed frames below LLVM's own size")
        if not ref:
            fail.append("no .stack_sizes in the image (built without -Z emit-stack-sizes?)")

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
