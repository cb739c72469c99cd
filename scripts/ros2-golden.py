#!/usr/bin/env python3
"""Golden bytes for `link --ros2` (issue #50): each line of stdin is a JSON
object {"type": "pkg/msg/Name", "distro": "humble"|"jazzy"|"kilted", "msg":
{...fields...}, "cdr": "hex"}: a message as echoloc's node encodes it. Each is
built again from its fields as the distribution's own message (PyPI
`rosbags`' type store for that distribution) and serialized by rosbags' CDR
serializer; the bytes must be identical. Prints {"checked": N, "mismatches":
[...]} and exits 1 on any mismatch.
"""
import json
import math
import sys

import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import Nodetype

STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY, "kilted": Stores.ROS2_KILTED}
NUMPY = {"float64": np.float64, "float32": np.float32, "uint8": np.uint8, "byte": np.uint8, "int32": np.int32,
         "uint32": np.uint32}


def number(v):
    # JSON has no infinity: serde_json writes it as null (a Range's no echo).
    return math.inf if v is None else v


def build(ts, desc, v):
    kind, arg = desc
    if kind.name == "NAME":
        cls = ts.types[arg]
        fields = ts.fielddefs[arg][1]
        missing = [n for n, _ in fields if n not in v]
        if missing:
            raise KeyError(f"{arg}: echoloc's message has no {missing}")
        extra = set(v) - {n for n, _ in fields}
        if extra:
            raise KeyError(f"{arg}: echoloc's message has fields {extra} the distribution's has not")
        return cls(**{n: build(ts, d, v[n]) for n, d in fields})
    if kind.name == "BASE":
        t = arg[0]
        if t == "string":
            return v
        return type(0.0)(number(v)) if t.startswith("float") else int(v)
    if kind.name in ("ARRAY", "SEQUENCE"):
        sub, _ = arg
        if sub[0].name == "BASE" and sub[1][0] in NUMPY:
            return np.array([number(x) for x in v], dtype=NUMPY[sub[1][0]])
        return [build(ts, sub, x) for x in v]
    raise ValueError(desc)


def main():
    checked, mismatches = 0, []
    for line in sys.stdin:
        if not line.strip():
            continue
        c = json.loads(line)
        ts = get_typestore(STORES[c["distro"]])
        msg = build(ts, (Nodetype.NAME, c["type"]), c["msg"])
        ours = bytes.fromhex(c["cdr"])
        theirs = bytes(ts.serialize_cdr(msg, c["type"]))
        checked += 1
        if ours != theirs:
            mismatches.append({"type": c["type"], "distro": c["distro"], "echoloc": ours.hex(), "rosbags": theirs.hex()})
    print(json.dumps({"checked": checked, "mismatches": mismatches}))
    return 1 if mismatches else 0


if __name__ == "__main__":
    sys.exit(main())
