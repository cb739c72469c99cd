#!/usr/bin/env python3
"""Writes a ROS 2 bag (rosbag2, MCAP storage) of a lidar robot's run, with
PyPI's `rosbags` (its own message definitions and CDR serializer,
independent of echoloc), and beside it the oracle `lab/tests/lidar_bag.rs`
checks `echoloc_lab::lidar::bag` against.

The world: a square room, walls x = 0, x = 6, y = 0 and y = 6 (metres, the
map frame). The robot drives a circle of radius 1.5 m about (3, 3) at
0.25 rad/s for 30 s, heading along it (the heading crosses ±π). Its laser
sits on it through a chain on /tf_static, base_link -> laser_base ->
laser, offset and turned. Each scan's ranges are computed here exactly (the
ray from the laser's true pose at the scan's stamp to the nearest wall),
then stored as float32 as a driver would.

Topics (--pose stamped, the default):
  /scan        sensor_msgs/msg/LaserScan at 7 Hz, frame laser, 271 beams
               over 270° (-135° to +135°), range_min 0.08 m, range_max 5.2 m;
               a beam whose wall is beyond range_max keeps its true range (the
               reader must drop it); every 10th scan has beams 5..8 as NaN,
               +Inf, -Inf and 0.03 m (below range_min): no return, REP 117.
               The first scan is before the first pose, the last two after the
               last: left out.
  /slam_pose   geometry_msgs/msg/PoseStamped at 10 Hz in map: the true pose at
               its stamp (stamps between the scans').
  /odom        nav_msgs/msg/Odometry at 20 Hz (stamps offset 13 ms), in an odom
               frame whose origin is (0.7, -1.2, 0.4 rad) in the map.
  /chatter     std_msgs/msg/String, 5 messages (to be counted and skipped).
  /tf_static   base_link -> laser_base (0.15, 0.05, 0.1 rad),
               laser_base -> laser (0.08, -0.02, 0.25 rad).
--pose cov: /amcl_pose (geometry_msgs/msg/PoseWithCovarianceStamped) instead of /slam_pose.
--pose tf:  no pose topic and no /odom: /tf map -> odom at 2 Hz (a correction
            drifting in time) and odom -> base_link at 20 Hz.

--expected OUT.csv writes, per /scan message, what ROS's semantics make of
it, computed here: whether a pose covers its stamp, the robot's pose in the
map interpolated between the pose messages around the stamp (linear in x, y,
the heading the short way; for tf, map -> odom and odom -> base_link each
interpolated, then composed), the laser's pose (the robot's composed with
the mount chain), the odometry interpolated likewise, whether the two pose
messages around it straddle ±π, and the number of beams with a return.

--break KIND writes a malformed bag: negative (message 7, beam 30 is
-0.5 m), two-scans (a second LaserScan topic /scan_rear), no-mount (the
laser_base -> laser link missing from /tf_static), bad-limits (message 5 has
range_min 6 > range_max 0.1).

Usage: python3 scripts/fixture-lidar-bag.py OUT_DIR [--pose stamped|cov|tf] [--expected OUT.csv] [--break KIND]
"""
import argparse
import math
import os
import shutil
import sys

try:
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # the test command installs it (scripts/setup.sh)
    sys.exit(f"fixture-lidar-bag.py needs PyPI's rosbags ({e}): pip install rosbags")

ROOM = 6.0
CENTRE, RADIUS, OMEGA, PHASE0 = (3.0, 3.0), 1.5, 0.25, 2.0
T0_NS = 1_700_000_000 * 1_000_000_000
DURATION_NS = 30 * 1_000_000_000
MOUNT_CHAIN = [("base_link", "laser_base", (0.15, 0.05, 0.1)), ("laser_base", "laser", (0.08, -0.02, 0.25))]
ANGLE_MIN, BEAMS = -0.75 * math.pi, 271
ANGLE_INC = 1.5 * math.pi / (BEAMS - 1)
RANGE_MIN, RANGE_MAX = 0.08, 5.2
ODOM_ORIGIN = (0.7, -1.2, 0.4)  # the odom frame in the map


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2])


def truth(t_ns):
    """The robot's true pose in the map at t."""
    phi = PHASE0 + OMEGA * (t_ns - T0_NS) / 1e9
    return (CENTRE[0] + RADIUS * math.cos(phi), CENTRE[1] + RADIUS * math.sin(phi), wrap(phi + math.pi / 2))


def map_to_odom(t_ns):
    """--pose tf: map -> odom, a correction drifting 1 cm and 2 mrad a second."""
    dt = (t_ns - T0_NS) / 1e9
    return (ODOM_ORIGIN[0] + 0.01 * dt, ODOM_ORIGIN[1], wrap(ODOM_ORIGIN[2] + 0.002 * dt))


def wall_distance(x, y, a):
    """The distance from (x, y) along heading a to the room's nearest wall."""
    c, s = math.cos(a), math.sin(a)
    d = math.inf
    if c > 1e-12:
        d = min(d, (ROOM - x) / c)
    if c < -1e-12:
        d = min(d, -x / c)
    if s > 1e-12:
        d = min(d, (ROOM - y) / s)
    if s < -1e-12:
        d = min(d, -y / s)
    return d


def interp(stamps, poses, t):
    """The pose at t: a message's own at its stamp, else linear between the two
    around t, the heading the short way; None outside. Also whether the two
    straddle ±π."""
    if not stamps or t < stamps[0] or t > stamps[-1]:
        return None, False
    lo, hi = 0, len(stamps) - 1
    while hi - lo > 1:  # the last stamp <= t
        mid = (lo + hi) // 2
        if stamps[mid] <= t:
            lo = mid
        else:
            hi = mid
    if stamps[lo] == t:
        return poses[lo], False
    if stamps[hi] == t:
        return poses[hi], False
    a, b = poses[lo], poses[hi]
    f = (t - stamps[lo]) / (stamps[hi] - stamps[lo])
    d = wrap(b[2] - a[2])
    straddles = abs(b[2] - a[2]) > math.pi
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), wrap(a[2] + f * d)), straddles


class Msgs:
    def __init__(self):
        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.T = self.ts.types

    def header(self, t_ns, frame):
        T = self.T
        stamp = T["builtin_interfaces/msg/Time"](sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def pose(self, p):
        T = self.T
        q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(p[2] / 2), w=math.cos(p[2] / 2))
        return T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=0.0),
                                           orientation=q)

    def pose_cov(self, p):
        return self.T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(p),
                                                              covariance=np.zeros(36, dtype=np.float64))

    def odometry(self, t_ns, p):
        T = self.T
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36, dtype=np.float64))
        return T["nav_msgs/msg/Odometry"](header=self.header(t_ns, "odom"), child_frame_id="base_link",
                                          pose=self.pose_cov(p), twist=twist)

    def transform(self, t_ns, parent, child, p):
        T = self.T
        q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(p[2] / 2), w=math.cos(p[2] / 2))
        return T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t_ns, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=0.2), rotation=q))

    def tf(self, transforms):
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def scan(self, t_ns, frame, ranges, range_min=RANGE_MIN, range_max=RANGE_MAX):
        return self.T["sensor_msgs/msg/LaserScan"](
            header=self.header(t_ns, frame), angle_min=ANGLE_MIN, angle_max=ANGLE_MIN + (BEAMS - 1) * ANGLE_INC,
            angle_increment=ANGLE_INC, time_increment=0.0, scan_time=1 / 7, range_min=range_min,
            range_max=range_max, ranges=np.array(ranges, dtype=np.float32),
            intensities=np.zeros(len(ranges), dtype=np.float32))

    def cdr(self, msg):
        return self.ts.serialize_cdr(msg, msg.__msgtype__)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--pose", choices=["stamped", "cov", "tf"], default="stamped")
    ap.add_argument("--expected")
    ap.add_argument("--break", dest="brk", choices=["negative", "two-scans", "no-mount", "bad-limits"])
    a = ap.parse_args()
    m = Msgs()
    if os.path.exists(a.out):
        shutil.rmtree(a.out)

    mount = (0.0, 0.0, 0.0)
    for _, _, p in MOUNT_CHAIN:
        mount = compose(mount, p)

    # Every message: (receive time, topic, message); written in receive order.
    out = []

    def put(topic, msg, t_ns):
        out.append((t_ns + 1_000_000, topic, msg))  # received 1 ms after its stamp

    links = [m.transform(T0_NS, parent, child, p) for parent, child, p in MOUNT_CHAIN
             if not (a.brk == "no-mount" and child == "laser")]
    put("/tf_static", m.tf(links), T0_NS - 500_000_000)

    # The pose, at 10 Hz over [T0, T0 + 30 s].
    pose_stamps, pose_values = [], []
    for k in range(DURATION_NS // 100_000_000 + 1):
        t = T0_NS + k * 100_000_000
        p = truth(t)
        pose_stamps.append(t)
        pose_values.append(p)
        if a.pose == "stamped":
            put("/slam_pose", m.T["geometry_msgs/msg/PoseStamped"](header=m.header(t, "map"), pose=m.pose(p)), t)
        elif a.pose == "cov":
            put("/amcl_pose", m.T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=m.header(t, "map"),
                                                                                pose=m.pose_cov(p)), t)
    # Odometry (or, for tf, odom -> base_link) at 20 Hz, 13 ms after the pose's stamps.
    odom_stamps, odom_values = [], []
    for k in range(DURATION_NS // 50_000_000 + 1):
        t = T0_NS + 13_000_000 + k * 50_000_000
        if a.pose == "tf":
            p = compose(inverse(map_to_odom(t)), truth(t))
            put("/tf", m.tf([m.transform(t, "odom", "base_link", p)]), t)
        else:
            p = compose(inverse(ODOM_ORIGIN), truth(t))
            put("/odom", m.odometry(t, p), t)
        odom_stamps.append(t)
        odom_values.append(p)
    # For tf, map -> odom at 2 Hz.
    corr_stamps, corr_values = [], []
    if a.pose == "tf":
        for k in range(DURATION_NS // 500_000_000 + 1):
            t = T0_NS + k * 500_000_000
            p = map_to_odom(t)
            put("/tf", m.tf([m.transform(t, "map", "odom", p)]), t)
            corr_stamps.append(t)
            corr_values.append(p)
    for k in range(5):
        put("/chatter", m.T["std_msgs/msg/String"](data=f"hello {k}"), T0_NS + k * 1_000_000_000)

    # The scans, at 7 Hz from 0.1 s before the first pose to past the last.
    expected = []
    straddles = 0
    k = 0
    while True:
        t = T0_NS - 100_000_000 + (k * 1_000_000_000) // 7
        if t > T0_NS + DURATION_NS + 300_000_000:
            break
        laser = compose(truth(t), mount)
        ranges = []
        for i in range(BEAMS):
            ranges.append(wall_distance(laser[0], laser[1], laser[2] + ANGLE_MIN + i * ANGLE_INC))
        lo, hi = RANGE_MIN, RANGE_MAX
        if k % 10 == 0:
            ranges[5:9] = [math.nan, math.inf, -math.inf, 0.03]
        if a.brk == "negative" and k == 7:
            ranges[30] = -0.5
        if a.brk == "bad-limits" and k == 5:
            lo, hi = 6.0, 0.1
        put("/scan", m.scan(t, "laser", ranges, lo, hi), t)
        if a.brk == "two-scans" and k < 3:
            put("/scan_rear", m.scan(t, "laser", ranges), t)

        # The oracle.
        f32 = np.array(ranges, dtype=np.float32)
        returns = int(sum(1 for r in f32 if math.isfinite(r) and np.float32(lo) <= r <= np.float32(hi) and r > 0))
        if a.pose == "tf":
            c, _ = interp(corr_stamps, corr_values, t)
            o, s = interp(odom_stamps, odom_values, t)
            robot = compose(c, o) if c is not None and o is not None else None
            odom = None
        else:
            robot, s = interp(pose_stamps, pose_values, t)
            odom, _ = interp(odom_stamps, odom_values, t)
        straddles += bool(s and robot is not None)
        row = {"index": k, "stamp_ns": t, "in_pose": int(robot is not None), "straddles": int(bool(s)),
               "returns": returns}
        for name, p in (("robot", robot), ("laser", compose(robot, mount) if robot else None), ("odom", odom)):
            for j, axis in enumerate(("x", "y", "th")):
                row[f"{name}_{axis}"] = "" if p is None else repr(wrap(p[2]) if j == 2 else p[j])
        expected.append(row)
        k += 1
    assert straddles > 0 or a.pose == "tf", "no scan between two poses that straddle ±π: change PHASE0"

    out.sort(key=lambda x: x[0])  # stable: one receive time keeps the order above
    with Writer(a.out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for t, topic, msg in out:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=m.ts)
            w.write(conns[topic], t, m.cdr(msg))

    if a.expected:
        keys = list(expected[0].keys())
        with open(a.expected, "w") as f:
            f.write(",".join(keys) + "\n")
            for r in expected:
                f.write(",".join(str(r[k]) for k in keys) + "\n")


if __name__ == "__main__":
    main()
