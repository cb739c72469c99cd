#!/usr/bin/env python3
"""Reads a ROS 2 bag that echoloc wrote (`echoloc-lab simulate --bag`,
`log --to-bag`, `echoloc_lab::bag::write`) with PyPI's `rosbags`, an
independent reader, and prints what it found as one JSON object, for
lab/tests/bag_write.rs to check against the rows the bag was written from.

Checks on the way (each failure exits non-zero with the reason):
  * rosbags' rosbag2 Reader opens the directory: metadata.yaml parses, the
    MCAP has the ros2 profile, the file list and the counts agree;
  * AnyReader builds the types from the bag's own ros2msg schemas and checks
    each topic's RIHS01 type_description_hash against them;
  * each schema is the one rosbags generates for ROS 2 Jazzy's type;
  * every message decodes with the bag's types, and decodes with rosbags'
    own Jazzy types to a message whose CDR, re-serialized by rosbags, is the
    very bytes stored.

Printed: the metadata's version, distro and counts; per topic its type,
message count and offered durability; the first and last Range message
(in time order) with its topic, frame, stamp and range; every Range's
limits seen; the /tf_static transforms (parent, child, x, y, yaw in
degrees); the first and last pose of each Odometry topic.

Usage: python3 scripts/bag-check.py BAG_DIR
"""
import json
import math
import sys
from pathlib import Path

try:
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    from ruamel.yaml import YAML  # rosbags' own YAML parser
except ImportError as e:  # scripts/setup.sh installs it
    sys.exit(f"bag-check.py needs PyPI's rosbags ({e}): pip install rosbags")


def fail(msg):
    sys.exit(f"bag-check.py: {msg}")


def stamp_ns(h):
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


def yaw(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    path = Path(sys.argv[1])
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    out = {"topics": {}, "ranges": {}, "tf_static": [], "odometry": {}}

    with Reader(path) as r:
        meta = YAML(typ="safe").load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        out["metadata"] = {
            "version": meta["version"],
            "ros_distro": r.ros_distro,
            "message_count": r.message_count,
            "duration_ns": r.duration,
            "files": meta["relative_file_paths"],
            "custom_data": meta.get("custom_data"),
        }
        for c in r.connections:
            qos = c.ext.offered_qos_profiles
            out["topics"][c.topic] = {
                "type": c.msgtype,
                "count": c.msgcount,
                "durability": qos[0].durability.name.lower() if qos else None,
                "schema_encoding": c.msgdef.format.name,
                "hash": c.digest,
            }
            want, _ = jazzy.generate_msgdef(c.msgtype, ros_version=2)
            if c.msgdef.data != want:
                fail(f"{c.topic}: the schema is not rosbags' Jazzy {c.msgtype}:\n{c.msgdef.data}\n---\n{want}")
            if c.digest != jazzy.hash_rihs01(c.msgtype):
                fail(f"{c.topic}: type hash {c.digest!r}, Jazzy's is {jazzy.hash_rihs01(c.msgtype)!r}")

    ranges = []
    with AnyReader([path]) as r:  # types from the bag's own schemas, hashes checked
        for c, t, raw in r.messages():
            msg = r.deserialize(raw, c.msgtype)
            again = jazzy.serialize_cdr(jazzy.deserialize_cdr(raw, c.msgtype), c.msgtype)
            if bytes(again) != bytes(raw):
                fail(f"{c.topic}: a message re-serialized by rosbags is not the bytes stored")
            if c.msgtype == "sensor_msgs/msg/Range":
                if t != stamp_ns(msg.header):
                    fail(f"{c.topic}: log time {t} is not the stamp {stamp_ns(msg.header)}")
                ranges.append((t, c.topic, msg))
            elif c.topic == "/tf_static":
                for tr in msg.transforms:
                    v, q = tr.transform.translation, tr.transform.rotation
                    out["tf_static"].append({
                        "parent": tr.header.frame_id, "child": tr.child_frame_id,
                        "x": v.x, "y": v.y, "z": v.z, "yaw_deg": math.degrees(yaw(q)),
                    })
            elif c.msgtype == "nav_msgs/msg/Odometry":
                p = msg.pose.pose
                pose = {"stamp_ns": stamp_ns(msg.header), "frame": msg.header.frame_id,
                        "child": msg.child_frame_id, "x": p.position.x, "y": p.position.y,
                        "yaw": yaw(p.orientation)}
                o = out["odometry"].setdefault(c.topic, {"count": 0, "first": pose})
                o["count"] += 1
                o["last"] = pose

    if ranges:
        ranges.sort(key=lambda x: x[0])  # stable: a tie keeps the file's order

        def rng(x):
            t, topic, m = x
            return {"topic": topic, "frame": m.header.frame_id, "stamp_ns": stamp_ns(m.header),
                    # JSON has no infinity: REP 117's +Inf (no echo) as "inf".
                    "range": m.range if math.isfinite(m.range) else str(m.range),
                    "radiation_type": m.radiation_type}

        out["ranges"] = {
            "count": len(ranges),
            "first": rng(ranges[0]),
            "last": rng(ranges[-1]),
            "infinite": sum(1 for x in ranges if math.isinf(x[2].range) and x[2].range > 0),
            "limits": sorted({(x[2].min_range, x[2].max_range, x[2].field_of_view) for x in ranges}),
        }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
