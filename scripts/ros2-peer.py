#!/usr/bin/env python3
"""An independent ROS 2 node for `link --ros2` tests (issue #50): Cyclone DDS's
Python binding (PyPI `cyclonedds`), no ROS installed, on the loopback only.

It subscribes to what echoloc publishes as amcl would (/amcl_pose, /tf,
/tf_static, /sonar_<k>, /diagnostics, /particlecloud) with the ROS 2 type names on the wire
(`geometry_msgs::msg::dds_::PoseWithCovarianceStamped_` on `rt/amcl_pose`),
and can act as rviz and a nav2 client would: publish an /initialpose (a pose
offset from the last /amcl_pose, with a wide covariance), a malformed one, or
call /reinitialize_global_localization (std_srvs/Empty, rmw_cyclonedds'
service mapping). As a robot's odometry node would, it can publish /odom
(nav_msgs/Odometry, reliable) from a JSON-lines file of the controller's
clock ({"time_us", "x", "y", "theta"}), stamped on the host's clock through
the anchor the link says on /diagnostics at the controller's Hello. It prints
one JSON summary and exits when nothing has come for --idle-s seconds (after
something came), or at --timeout-s.

    python3 scripts/ros2-peer.py [--initial-after N --offset-m 2 --sigma-m 2.5]
        [--bad-initial-after N] [--global-after N] [--leave-after N] [--late S]
        [--mark N FILE] [--join-when FILE] [--odom FILE [--odom-bad]]
"""
import argparse
import json
import math
import os
import sys
import time

os.environ.setdefault(
    "CYCLONEDDS_URI",
    "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>"
    "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>",
)

from dataclasses import dataclass  # noqa: E402

from cyclonedds.core import Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import array, float32, float64, int32, int64, sequence, uint8, uint32, uint64  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class PoseWithCovarianceStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"):
    header: Header
    pose: PoseWithCovariance


@dataclass
class PoseArray(IdlStruct, typename="geometry_msgs::msg::dds_::PoseArray_"):
    header: Header
    poses: sequence[Pose]


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped]


@dataclass
class RangeJazzy(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    header: Header
    radiation_type: uint8
    field_of_view: float32
    min_range: float32
    max_range: float32
    range: float32
    variance: float32


@dataclass
class RangeHumble(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    header: Header
    radiation_type: uint8
    field_of_view: float32
    min_range: float32
    max_range: float32
    range: float32


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str
    value: str


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: uint8
    name: str
    message: str
    hardware_id: str
    values: sequence[KeyValue]


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header
    status: sequence[DiagnosticStatus]


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3
    angular: Vector3


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


# rmw_cyclonedds' service mapping: the client's id and a sequence number before the request.
@dataclass
class EmptyRequest(IdlStruct, typename="std_srvs::srv::dds_::Empty_Request_"):
    client_guid: uint64
    sequence_number: int64
    structure_needs_at_least_one_member: uint8


@dataclass
class EmptyResponse(IdlStruct, typename="std_srvs::srv::dds_::Empty_Response_"):
    client_guid: uint64
    sequence_number: int64
    structure_needs_at_least_one_member: uint8


def valid(samples):
    """The samples that carry data (a writer that leaves sends an invalid one)."""
    return [s for s in samples if isinstance(s, IdlStruct)]


def yaw(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--transducers", type=int, default=16)
    ap.add_argument("--distro", choices=["humble", "jazzy"], default="jazzy")
    ap.add_argument("--initial-after", type=int, help="publish /initialpose after this many /amcl_pose")
    ap.add_argument("--offset-m", type=float, default=2.0)
    ap.add_argument("--sigma-m", type=float, default=2.5)
    ap.add_argument("--bad-initial-after", type=int, help="publish malformed /initialpose (NaN; frame odom) after N")
    ap.add_argument("--global-after", type=int, help="call /reinitialize_global_localization after N /amcl_pose")
    ap.add_argument("--leave-after", type=int, help="leave after this many /amcl_pose")
    ap.add_argument("--late", type=float, default=0.0, help="join this many seconds late")
    ap.add_argument("--join-when", help="join only once this file exists (another peer's --mark)")
    ap.add_argument("--mark", nargs=2, metavar=("N", "FILE"), help="create FILE after N /amcl_pose")
    ap.add_argument("--odom", help="publish /odom from this JSON-lines file once the link's Hello is said")
    ap.add_argument("--odom-bad", action="store_true",
                    help="and three it must refuse: one stamped before the Hello, one in frame map, one NaN")
    ap.add_argument("--idle-s", type=float, default=4.0)
    ap.add_argument("--timeout-s", type=float, default=400.0)
    a = ap.parse_args()
    time.sleep(a.late)
    while a.join_when and not os.path.exists(a.join_when):
        time.sleep(0.005)
    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    rel = Policy.Reliability.Reliable(max_blocking_time=1_000_000_000)
    latched = Qos(rel, Policy.Durability.TransientLocal, Policy.History.KeepLast(1))
    keep_all = Qos(rel, Policy.Durability.Volatile, Policy.History.KeepAll)
    pose_reader = DataReader(dp, Topic(dp, "rt/amcl_pose", PoseWithCovarianceStamped), qos=Qos(rel, Policy.Durability.TransientLocal, Policy.History.KeepAll))
    tf_reader = DataReader(dp, Topic(dp, "rt/tf", TFMessage), qos=keep_all)
    static_reader = DataReader(dp, Topic(dp, "rt/tf_static", TFMessage), qos=latched)
    range_type = RangeJazzy if a.distro == "jazzy" else RangeHumble
    range_readers = [DataReader(dp, Topic(dp, f"rt/sonar_{k}", range_type), qos=keep_all) for k in range(a.transducers)]
    diag_reader = DataReader(dp, Topic(dp, "rt/diagnostics", DiagnosticArray), qos=keep_all)
    cloud_reader = DataReader(dp, Topic(dp, "rt/particlecloud", PoseArray), qos=keep_all)
    initial_writer = DataWriter(dp, Topic(dp, "rt/initialpose", PoseWithCovarianceStamped), qos=Qos(rel, Policy.Durability.Volatile, Policy.History.KeepLast(10)))
    rq = DataWriter(dp, Topic(dp, "rq/reinitialize_global_localizationRequest", EmptyRequest), qos=Qos(rel, Policy.Durability.Volatile, Policy.History.KeepLast(10)))
    rr = DataReader(dp, Topic(dp, "rr/reinitialize_global_localizationReply", EmptyResponse), qos=keep_all)
    odom_writer = DataWriter(dp, Topic(dp, "rt/odom", Odometry), qos=Qos(rel, Policy.Durability.Volatile, Policy.History.KeepAll))
    odom = []
    if a.odom:
        with open(a.odom) as f:
            odom = [json.loads(line) for line in f if line.strip()]
    odom_next, odom_bad_sent, hello = 0, 0, None

    poses, tfs, statics, ranges, diags, replies, clouds = [], [], [], [0] * a.transducers, [], 0, []
    sent = {}
    start = last = time.monotonic()
    got_any = False
    left_early = False

    def wide_cov(s):
        c = [0.0] * 36
        c[0] = c[7] = s * s
        c[35] = 0.5 ** 2
        return c

    while True:
        now = time.monotonic()
        if now - start > a.timeout_s or (got_any and now - last > a.idle_s):
            break
        n = 0
        for s in valid(pose_reader.take(N=100)):
            p = s.pose.pose
            poses.append({"stamp_ns": s.header.stamp.sec * 1_000_000_000 + s.header.stamp.nanosec,
                          "frame": s.header.frame_id,
                          "pose": [p.position.x, p.position.y, yaw(p.orientation)],
                          "cov": [s.pose.covariance[i] for i in (0, 1, 5, 7, 11, 35)]})
            n += 1
        for s in valid(tf_reader.take(N=100)):
            for t in s.transforms:
                tr = t.transform
                tfs.append({"stamp_ns": t.header.stamp.sec * 1_000_000_000 + t.header.stamp.nanosec,
                            "parent": t.header.frame_id, "child": t.child_frame_id,
                            "pose": [tr.translation.x, tr.translation.y, yaw(tr.rotation)]})
            n += 1
        for s in valid(static_reader.take(N=10)):
            statics.extend({"parent": t.header.frame_id, "child": t.child_frame_id} for t in s.transforms)
            n += 1
        for k, r in enumerate(range_readers):
            got = valid(r.take(N=100))
            ranges[k] += len(got)
            n += len(got)
        for s in valid(diag_reader.take(N=100)):
            for st in s.status:
                values = {kv.key: kv.value for kv in st.values}
                diags.append({"level": int(st.level), "name": st.name, "message": st.message,
                              "stamp_ns": s.header.stamp.sec * 1_000_000_000 + s.header.stamp.nanosec})
                if st.name == "echoloc: link":
                    hello = (diags[-1]["stamp_ns"], int(values["controller time us"]))
            n += 1
        for s in valid(cloud_reader.take(N=100)):
            clouds.append({"stamp_ns": s.header.stamp.sec * 1_000_000_000 + s.header.stamp.nanosec,
                           "frame": s.header.frame_id, "particles": len(s.poses)})
            n += 1
        replies += len(valid(rr.take(N=10)))
        if n:
            got_any, last = True, time.monotonic()
        if a.initial_after is not None and "initial" not in sent and len(poses) >= a.initial_after:
            x, y, th = poses[-1]["pose"]
            msg = PoseWithCovarianceStamped(
                Header(Time(0, 0), "map"),
                PoseWithCovariance(Pose(Point(x + a.offset_m, y, 0.0), Quaternion(0.0, 0.0, math.sin(th / 2), math.cos(th / 2))), wide_cov(a.sigma_m)))
            initial_writer.write(msg)
            sent["initial"] = {"at_pose": len(poses), "pose": [x + a.offset_m, y, th], "sigma_m": a.sigma_m}
        if a.bad_initial_after is not None and "bad" not in sent and len(poses) >= a.bad_initial_after:
            q = Quaternion(0.0, 0.0, 0.0, 1.0)
            initial_writer.write(PoseWithCovarianceStamped(Header(Time(0, 0), "map"), PoseWithCovariance(Pose(Point(float("nan"), 0.0, 0.0), q), wide_cov(0.5))))
            initial_writer.write(PoseWithCovarianceStamped(Header(Time(0, 0), "odom"), PoseWithCovariance(Pose(Point(1.0, 1.0, 0.0), q), wide_cov(0.5))))
            sent["bad"] = {"at_pose": len(poses), "count": 2}
        if a.global_after is not None and "global" not in sent and len(poses) >= a.global_after:
            rq.write(EmptyRequest(0x0102030405060708, 1, 0))
            sent["global"] = {"at_pose": len(poses)}
        if a.mark and "mark" not in sent and len(poses) >= int(a.mark[0]):
            open(a.mark[1], "w").close()
            sent["mark"] = {"at_pose": len(poses)}
        if hello and odom_next < len(odom) and odom_writer.get_matched_subscriptions():
            h, c = hello

            def odometry(ns, frame, x, y, th):
                q = Quaternion(0.0, 0.0, math.sin(th / 2), math.cos(th / 2))
                zero = Vector3(0.0, 0.0, 0.0)
                return Odometry(Header(Time(ns // 1_000_000_000, ns % 1_000_000_000), frame), "base_link",
                                PoseWithCovariance(Pose(Point(x, y, 0.0), q), [0.0] * 36),
                                TwistWithCovariance(Twist(zero, zero), [0.0] * 36))
            if a.odom_bad and odom_bad_sent == 0 and odom_next >= 10:
                s0 = odom[0]
                odom_writer.write(odometry(h - 1_000_000_000, "odom", s0["x"], s0["y"], s0["theta"]))
                odom_writer.write(odometry(h + 5, "map", 1.0, 2.0, 0.0))
                odom_writer.write(odometry(h + 6, "odom", float("nan"), 0.0, 0.0))
                odom_bad_sent = 3
            # A burst at most per round: the link polls its reader every few ms.
            for s in odom[odom_next:odom_next + 8]:
                odom_writer.write(odometry(h + (s["time_us"] - c) * 1000, "odom", s["x"], s["y"], s["theta"]))
                odom_next += 1
            n += 1
        if a.leave_after is not None and len(poses) >= a.leave_after:
            left_early = True
            break
        time.sleep(0.002)
    print(json.dumps({"poses": poses, "tf": tfs, "tf_static": statics, "ranges": ranges, "diagnostics": diags,
                      "service_replies": replies, "particle_clouds": clouds, "sent": sent, "left_early": left_early,
                      "odom_sent": odom_next, "odom_bad_sent": odom_bad_sent, "hello": hello}))


if __name__ == "__main__":
    sys.exit(main())
