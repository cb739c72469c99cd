#!/usr/bin/env python3
"""Writes ROS 2 bags (rosbag2, MCAP or sqlite3 storage) of a robot run, with PyPI's
`rosbags` (its own message definitions and CDR serializer, independent of
echoloc), and beside each the plain log (docs/log.md) that ROS's documented
semantics make of it: the oracle `echoloc-lab replay --bag` is checked against.

Input: a plain log with a reference pose on every row (what
`echoloc-lab simulate --log` writes: each reading's time, transducer, range,
cumulative odometry and true pose). The ring is the Pioneer 16, written out
here from DESIGN §5.

Forms (--form):
  range      one sensor_msgs/msg/Range topic per transducer (/sonar/N, frame
             sonar_N), the mounts on /tf_static as base_link -> sonar_ring ->
             sonar_N, /odom (nav_msgs/msg/Odometry) and /ground_truth
             (Odometry) at every reading; ROS 2 Humble's types.
  frame      one Range topic /sonar_ranges whose header.frame_id names the
             transducer (ROS 2 Jazzy's Range, with `variance`), odometry as /tf
             odom -> base_link, the reference as /amcl_pose
             (geometry_msgs/msg/PoseWithCovarianceStamped).
  cloud      RosAria: sensor_msgs/msg/PointCloud on /sonar, the whole ring per
             cycle at the cycle's first firing time (--cloud-stamp end: at the
             next cycle's first firing, the ring's end), one point per
             transducer in base_link (mount + range along the axis; no echo as
             the point at 5 m), /odom and /ground_truth. Its --expected log
             has every point of a cycle at its first firing (the bag read
             with --ring-stamp one-instant).

REP 117 in the oracle: Range.range is float32 metres; a range above
max_range (5 m here) or below min_range (0.45 m) is no echo, as is +Inf (the
writer's "no return").

--storage mcap|sqlite3 chooses rosbag2's storage plugin: MCAP (Iron's
default, `<name>.mcap`) or sqlite3 (Humble's, `<name>.db3`); the messages,
their order and their bytes are the same in both.

--break KIND writes a malformed bag (no oracle log), each a row of
docs/bags.md's table: no-range, no-transform, negative, nan, mm, backwards,
no-odom, bad-limits, truncated-message, cloud-count (either storage), chunk,
truncated-file, chunk-crc (MCAP; chunk-crc with --chunks: a byte flipped in a
compressed chunk), no-topics-table, no-messages-table, truncated-blob
(sqlite3: a table dropped, or the third message's data cut to 10 bytes, with
python's own sqlite3 module after rosbags has written the bag).

--chunks zstd|lz4 rewrites the bag's MCAP with PyPI's mcap writer, its chunks
compressed as rosbag2's storage presets do (every message as it was).

Usage: python3 scripts/fixture-bag.py LOG.csv OUT_DIR --form range [--storage sqlite3] [--expected OUT.csv] [--break KIND] [--chunks zstd]
"""
import argparse
import csv
import math
import os
import shutil
import sqlite3
import struct
import sys

try:
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # the test command installs it (scripts/setup.sh)
    sys.exit(f"fixture-bag.py needs PyPI's rosbags ({e}): pip install rosbags")

# The Pioneer 16 ring (DESIGN §5): x m, y m, heading degrees.
PIONEER16 = [(0.075, 0.130, 90), (0.115, 0.115, 50), (0.150, 0.080, 30), (0.170, 0.025, 10),
             (0.170, -0.025, -10), (0.150, -0.080, -30), (0.115, -0.115, -50), (0.075, -0.130, -90),
             (-0.155, -0.130, -90), (-0.195, -0.115, -130), (-0.230, -0.080, -150), (-0.250, -0.025, -170),
             (-0.250, 0.025, 170), (-0.230, 0.080, 150), (-0.195, 0.115, 130), (-0.155, 0.130, 90)]
# The sonar ring's own frame sits 2 cm ahead of base_link: the mounts are
# published relative to it, so a reader must follow the chain.
RING_OFFSET_X = 0.02
MIN_RANGE, MAX_RANGE = 0.45, 5.0
CLOUD_MAX = 5.0  # RosAria: no echo is a point at the 5 m maximum


def read_log(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(line for line in f if not line.startswith("#")):
            rows.append({
                "t": float(r["time_s"]), "i": int(r["transducer"]),
                "range_mm": int(r["range_mm"]) if r["range_mm"] else None,
                "odom": tuple(float(r[k]) for k in ("odom_x_m", "odom_y_m", "odom_theta_rad")),
                "ref": tuple(float(r[k]) for k in ("ref_x_m", "ref_y_m", "ref_theta_rad")),
            })
    return rows


def ns(t):
    return int(round(t * 1e9))


class Msgs:
    def __init__(self, store):
        self.ts = get_typestore(store)
        self.T = self.ts.types

    def time(self, t_ns):
        return self.T["builtin_interfaces/msg/Time"](sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)

    def header(self, t_ns, frame):
        return self.T["std_msgs/msg/Header"](stamp=self.time(t_ns), frame_id=frame)

    def quat(self, yaw):
        return self.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def pose(self, p):
        T = self.T
        return T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=0.0),
                                             orientation=self.quat(p[2])),
            covariance=np.zeros(36, dtype=np.float64))

    def odometry(self, t_ns, frame, child, p):
        T = self.T
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36, dtype=np.float64))
        return T["nav_msgs/msg/Odometry"](header=self.header(t_ns, frame), child_frame_id=child, pose=self.pose(p),
                                          twist=twist)

    def transform(self, t_ns, parent, child, x, y, yaw):
        T = self.T
        return T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t_ns, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.3),
                                                       rotation=self.quat(yaw)))

    def range(self, t_ns, frame, value, min_range=MIN_RANGE, max_range=MAX_RANGE):
        kw = dict(header=self.header(t_ns, frame), radiation_type=0, field_of_view=math.radians(30),
                  min_range=min_range, max_range=max_range, range=value)
        if "variance" in self.T["sensor_msgs/msg/Range"].__dataclass_fields__:
            kw["variance"] = 0.0
        return self.T["sensor_msgs/msg/Range"](**kw)

    def cdr(self, msg):
        return self.ts.serialize_cdr(msg, msg.__msgtype__)


def f32(v):
    return float(np.float32(v))


def oracle_range(mm):
    """What REP 117 makes of a Range carrying this reading: None is no echo."""
    if mm is None:
        return None
    r = f32(mm / 1000.0)
    if r > f32(MAX_RANGE) or r < f32(MIN_RANGE):
        return None
    back = round(r * 1000.0)
    assert back == mm, (mm, r)
    return back


def write_expected(path, rows):
    with open(path, "w") as f:
        f.write("time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad,ref_x_m,ref_y_m,ref_theta_rad\n")
        for r in rows:
            rng = "" if r["range_mm"] is None else str(r["range_mm"])
            f.write(",".join([repr(r["t"]), str(r["i"]), rng] + [repr(v) for v in r["odom"] + r["ref"]]) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("log")
    ap.add_argument("out")
    ap.add_argument("--form", choices=["range", "frame", "cloud"], default="range")
    ap.add_argument("--expected")
    ap.add_argument("--break", dest="brk")
    ap.add_argument("--chunks", choices=["none", "zstd", "lz4"], default="none",
                    help="rewrite the MCAP with compressed chunks (PyPI's mcap writer)")
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap",
                    help="rosbag2's storage plugin: mcap (Iron's default) or sqlite3 (Humble's, .db3)")
    ap.add_argument("--cloud-stamp", choices=["start", "end"], default="start",
                    help="the cloud form's stamp: the cycle's first firing, or its end (the next "
                         "cycle's first firing, as RosAria stamps when it publishes)")
    a = ap.parse_args()
    mcap_only = a.chunks != "none" or a.brk in ("chunk", "truncated-file", "chunk-crc")
    sqlite_only = a.brk in ("no-topics-table", "no-messages-table", "truncated-blob")
    if (a.storage == "sqlite3" and mcap_only) or (a.storage == "mcap" and sqlite_only):
        ap.error(f"--break {a.brk} / --chunks {a.chunks} does not apply to --storage {a.storage}")
    rows = read_log(a.log)
    brk = a.brk
    m = Msgs(Stores.ROS2_JAZZY if a.form == "frame" else Stores.ROS2_HUMBLE)
    if os.path.exists(a.out):
        shutil.rmtree(a.out)
    storage = StoragePlugin.SQLITE3 if a.storage == "sqlite3" else StoragePlugin.MCAP
    expected = []
    with Writer(a.out, version=8, storage_plugin=storage) as w:
        conns = {}

        def conn(topic, msgtype):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=m.ts)
            return conns[topic]

        def put(topic, msg, t_ns, data=None):
            # Received 1 ms after the stamp, as a recorder would.
            w.write(conn(topic, msg.__msgtype__), t_ns + 1_000_000, data if data is not None else m.cdr(msg))

        t0 = ns(rows[0]["t"])
        # The ring's mounts, once, on /tf_static.
        if a.form != "cloud":
            tfs = [m.transform(t0, "base_link", "sonar_ring", RING_OFFSET_X, 0.0, 0.0)]
            for i, (x, y, deg) in enumerate(PIONEER16):
                if brk == "no-transform" and i == 5:
                    continue
                tfs.append(m.transform(t0, "sonar_ring", f"sonar_{i}", x - RING_OFFSET_X, y, math.radians(deg)))
            put("/tf_static", m.T["tf2_msgs/msg/TFMessage"](transforms=tfs), t0)
        # Odometry and reference at every distinct reading time.
        last_t = None
        odom_k = 0
        for r in rows:
            t = ns(r["t"])
            if t == last_t:
                continue
            last_t = t
            if brk != "no-odom":
                if a.form == "frame":
                    tf = m.transform(t, "odom", "base_link", r["odom"][0], r["odom"][1], r["odom"][2])
                    put("/tf", m.T["tf2_msgs/msg/TFMessage"](transforms=[tf]), t)
                else:
                    msg = m.odometry(t, "odom", "base_link", r["odom"])
                    data = None
                    if brk == "truncated-message" and odom_k == 3:
                        data = m.cdr(msg)[:40]
                    put("/odom", msg, t, data)
                odom_k += 1
            if a.form == "frame":
                amcl = m.T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=m.header(t, "map"),
                                                                          pose=m.pose(r["ref"]))
                put("/amcl_pose", amcl, t)
            else:
                put("/ground_truth", m.odometry(t, "map", "base_link", r["ref"]), t)
        # The ranges.
        if a.form in ("range", "frame") and brk != "no-range":
            count = {}
            for k, r in enumerate(rows):
                t = ns(r["t"])
                i = r["i"]
                n = count.get(i, 0)
                count[i] = n + 1
                value = float("inf") if r["range_mm"] is None else f32(r["range_mm"] / 1000.0)
                lo, hi = MIN_RANGE, MAX_RANGE
                if brk == "negative" and i == 3 and n == 7:
                    value = -0.3
                if brk == "nan" and i == 3 and n == 7:
                    value = float("nan")
                if brk == "mm":
                    value, lo, hi = value * 1000.0, lo * 1000.0, hi * 1000.0
                if brk == "bad-limits" and i == 3 and n == 7:
                    lo, hi = 5.0, 0.45
                if brk == "backwards" and i == 3 and n == 20:
                    t -= 1_000_000_000  # more than a ring cycle: before the previous message
                topic = f"/sonar/{i}" if a.form == "range" else "/sonar_ranges"
                put(topic, m.range(t, f"sonar_{i}", value, lo, hi), t)
                expected.append(dict(r, range_mm=oracle_range(r["range_mm"])))
        if a.form == "cloud":
            # Cycles as the log has them: a cycle ends before a transducer fires again.
            cycles, cur = [], []
            for r in rows:
                if any(c["i"] == r["i"] for c in cur):
                    cycles.append(cur)
                    cur = []
                cur.append(r)
            if cur:
                cycles.append(cur)
            P32 = m.T["geometry_msgs/msg/Point32"]
            starts = [c[0]["t"] for c in cycles]
            gaps = sorted(b - a_ for a_, b in zip(starts, starts[1:]))
            median_period = gaps[len(gaps) // 2] if gaps else 0.0
            for ci, cyc in enumerate(cycles):
                if len(cyc) != 16:
                    continue
                first = cyc[0]
                t = ns(first["t"])
                if a.cloud_stamp == "end":
                    t = ns(starts[ci + 1]) if ci + 1 < len(starts) else ns(first["t"] + median_period)
                by_i = {c["i"]: c["range_mm"] for c in cyc}
                pts = []
                for i, (x, y, deg) in enumerate(PIONEER16):
                    mm = by_i[i]
                    r = CLOUD_MAX if mm is None or mm >= CLOUD_MAX * 1000 else mm / 1000.0
                    h = math.radians(deg)
                    pts.append(P32(x=f32(x + r * math.cos(h)), y=f32(y + r * math.sin(h)), z=f32(0.3)))
                    expected.append(dict(first, i=i, range_mm=None if r >= CLOUD_MAX else mm))
                if brk == "cloud-count":
                    pts = pts[:8]
                cloud = m.T["sensor_msgs/msg/PointCloud"](header=m.header(t, "base_link"), points=pts, channels=[])
                put("/sonar", cloud, t)
    if sqlite_only:
        db3 = next(os.path.join(a.out, f) for f in os.listdir(a.out) if f.endswith(".db3"))
        con = sqlite3.connect(db3)
        if brk == "truncated-blob":
            # The third message written (the range form's first /ground_truth)
            # keeps its first 10 bytes: the CDR header and 6 bytes of stamp.
            con.execute("UPDATE messages SET data = substr(data, 1, 10) WHERE id = 3")
        else:
            con.execute("DROP TABLE " + {"no-topics-table": "topics", "no-messages-table": "messages"}[brk])
        con.commit()
        con.close()
    if brk in ("chunk", "truncated-file"):
        mcap = next(os.path.join(a.out, f) for f in os.listdir(a.out) if f.endswith(".mcap"))
        data = bytearray(open(mcap, "rb").read())
        if brk == "chunk":
            # The second chunk's first record claims to run far past the
            # chunk's end (rosbags writes uncompressed chunks without a CRC,
            # so damage inside one shows only in its structure). MCAP: magic,
            # then records of opcode u8, length u64, body; a chunk's body is
            # start, end, uncompressed size (u64 each), CRC u32, the
            # compression string (u32 length + bytes), the records' length u64.
            p, chunks = 8, 0
            while p < len(data):
                op, ln = data[p], struct.unpack_from("<Q", data, p + 1)[0]
                if op == 0x06:
                    chunks += 1
                    if chunks == 2:
                        body = p + 9
                        clen = struct.unpack_from("<I", data, body + 28)[0]
                        records = body + 32 + clen + 8
                        struct.pack_into("<Q", data, records + 1, 1 << 40)
                        break
                p += 9 + ln
            assert chunks == 2, "the bag has fewer than two chunks"
        else:
            data = data[: len(data) * 6 // 10]
        open(mcap, "wb").write(bytes(data))
    if a.chunks in ("zstd", "lz4"):
        mcap_path = next(os.path.join(a.out, f) for f in os.listdir(a.out) if f.endswith(".mcap"))
        rechunk(mcap_path, a.chunks)
        if brk == "chunk-crc":
            # One byte flipped in the middle of the first chunk's compressed records.
            data = bytearray(open(mcap_path, "rb").read())
            p = 8
            while data[p] != 0x06:
                p += 9 + struct.unpack_from("<Q", data, p + 1)[0]
            body = p + 9
            clen = struct.unpack_from("<I", data, body + 28)[0]
            records = body + 32 + clen + 8
            rlen = struct.unpack_from("<Q", data, records - 8)[0]
            data[records + rlen // 2] ^= 0x01
            open(mcap_path, "wb").write(bytes(data))
    if a.expected and brk is None:
        write_expected(a.expected, expected)


def rechunk(path, compression):
    """Rewrites the MCAP file with PyPI's mcap writer, its chunks compressed
    (zstd: rosbag2's `zstd_fast`/`zstd_small` storage presets; lz4), every
    schema, channel and message as it was, with chunk CRCs."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer as McapWriter

    kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}[compression]
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        items = list(reader.iter_messages(log_time_order=False))
    out = path + ".tmp"
    with open(out, "wb") as f:
        w = McapWriter(f, compression=kind, chunk_size=256 * 1024, enable_crcs=True)
        w.start(profile=header.profile, library="fixture-bag.py (mcap " + compression + ")")
        schemas, channels = {}, {}
        for schema, channel, message in items:
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                          schemas[schema.id], channel.metadata)
            w.add_message(channels[channel.id], message.log_time, message.data, message.publish_time,
                          message.sequence)
        w.finish()
    os.replace(out, path)


if __name__ == "__main__":
    main()
