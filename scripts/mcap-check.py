#!/usr/bin/env python3
"""Reads an echoloc Foxglove recording (MCAP) with PyPI's `mcap` package,
independently of echoloc, and checks it against the run's JSON report
(`echoloc-lab simulate|replay --json --mcap OUT.mcap`):

- every channel has a well-known Foxglove schema name, protobuf encoded
  (decoded by PyPI's mcap-protobuf-support from the schema the file carries),
  and log times that never decrease and equal the messages' own timestamps;
- the message counts match the run: one pose, transform, sensor window and
  covariance ellipse per reading, truth poses per reading with a reference,
  one map, a mode log line at the start and at each change of the localizer's mode;
- with --trace TRACE.csv (the run's `--trace`): one `/particles` cloud per
  cycle that ended searching or lost, no two within 0.25 s, each with as
  many points as the cycle's `particles`, and `/hypotheses` only while searching;
- the first and last EKF poses equal the JSON's `ekf.first_pose` and
  `ekf.final_pose` (6 decimals).

Prints a JSON summary; exits 1 with the reasons on any failure.
--picture OUT.png draws what the recording shows (needs matplotlib).

With --link, REPORT is what `echoloc-lab link --mcap` printed (one JSON line
per controller message): the counts and the first and last poses are the
controller's Reading messages'.

--clouds OUT.png draws the particle cloud at the start, at convergence (the
last cloud before the first hand-off) and after the first kidnap.

Usage: python3 scripts/mcap-check.py RUN.mcap RUN.json [--trace TRACE.csv] [--picture OUT.png] [--clouds OUT.png]
       python3 scripts/mcap-check.py LINK.mcap LINK.jsonl --link
"""
import argparse
import json
import math
import sys

try:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
except ImportError as e:
    sys.exit(f"mcap-check.py needs PyPI's mcap and mcap-protobuf-support ({e}): pip install mcap mcap-protobuf-support")

CLOUD_INTERVAL_S = 0.25

FOXGLOVE = {
    "foxglove.SceneUpdate", "foxglove.FrameTransforms", "foxglove.FrameTransform", "foxglove.PoseInFrame",
    "foxglove.PosesInFrame", "foxglove.Log", "foxglove.PointCloud", "foxglove.LaserScan", "foxglove.Grid",
}


def to_dict(msg):
    """A decoded protobuf message as plain data, every field present (zeros
    included); timestamps as {sec, nsec}; bytes as bytes."""
    if msg.DESCRIPTOR.full_name == "google.protobuf.Timestamp":
        return {"sec": msg.seconds, "nsec": msg.nanos}
    out = {}
    for f in msg.DESCRIPTOR.fields:
        v = getattr(msg, f.name)
        repeated = f.is_repeated if isinstance(getattr(f, "is_repeated", None), bool) else f.label == 3
        if f.message_type is not None:
            out[f.name] = [to_dict(x) for x in v] if repeated else to_dict(v)
        else:
            out[f.name] = list(v) if repeated else v
    return out


def pose2(p):
    return (p["position"]["x"], p["position"]["y"], yaw(p["orientation"]))


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def yaw(q):
    return math.atan2(2 * (q["w"] * q["z"] + q["x"] * q["y"]), 1 - 2 * (q["y"] ** 2 + q["z"] ** 2))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mcap")
    ap.add_argument("report")
    ap.add_argument("--picture")
    ap.add_argument("--clouds")
    ap.add_argument("--points", help="writes every particle of every cloud as CSV: time_s,x_m,y_m,weight")
    ap.add_argument("--trace", help="the run's --trace CSV: checks /particles and /hypotheses per cycle")
    ap.add_argument("--link", action="store_true", help="REPORT is the JSON lines `echoloc-lab link` printed")
    a = ap.parse_args()
    if a.link:
        report = [json.loads(line) for line in open(a.report) if line.strip()]
    else:
        report = json.load(open(a.report))
    problems = []
    channels, messages = {}, {}
    last_time = -1
    with open(a.mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            topic = channel.topic
            if topic not in channels:
                channels[topic] = {"schema": schema.name, "schema_encoding": schema.encoding,
                                   "message_encoding": channel.message_encoding, "count": 0}
                if schema.name not in FOXGLOVE:
                    problems.append(f"{topic}: schema {schema.name!r} is not a well-known Foxglove schema")
                if schema.encoding != "protobuf" or channel.message_encoding != "protobuf":
                    problems.append(f"{topic}: encodings {schema.encoding}/{channel.message_encoding}")
            channels[topic]["count"] += 1
            if message.log_time < last_time:
                problems.append(f"{topic}: log time {message.log_time} before {last_time}")
            last_time = message.log_time
            m = to_dict(decoded)
            stamps = []
            if "timestamp" in m:
                stamps.append(m["timestamp"])
            for e in m.get("entities", []):
                stamps.append(e["timestamp"])
            for t in m.get("transforms", []):
                stamps.append(t["timestamp"])
            for s in stamps:
                if s["sec"] * 1_000_000_000 + s["nsec"] != message.log_time:
                    problems.append(f"{topic}: a timestamp {s} is not the log time {message.log_time}")
                    break
            messages.setdefault(topic, []).append(m)
    if a.link:
        # The controller's own messages, as `link` printed them.
        readings = [r["Reading"] for r in report if isinstance(r, dict) and "Reading" in r]
        n = len(readings)
        changes = sum(1 for x, y in zip(readings, readings[1:]) if x["mode"] != y["mode"])
        expect = {"/tf": n, "/pose/controller": n, "/ekf/covariance": n, "/sonar": n,
                  "/localization/mode": (1 + changes) if n else 0}
        pose_topic = "/pose/controller"
        want = {"first_pose": readings[0]["pose"], "final_pose": readings[-1]["pose"]} if n else {}
    else:
        n = report["readings"]
        with_truth = report.get("log", {}).get("reference_rows", n)
        expect = {
            "/map": 1, "/tf": n, "/pose/ekf": n, "/pose/dead_reckoning": n, "/pose/threshold": n,
            "/ekf/covariance": n, "/sonar": n, "/localization/mode": 1 + report["localization"]["mode_changes"],
        }
        if a.trace:
            problems += check_clouds(messages, a.trace, expect)
        if with_truth:
            expect["/pose/truth"] = with_truth
        pose_topic = "/pose/ekf"
        want = {"first_pose": report["ekf"]["first_pose"], "final_pose": report["ekf"]["final_pose"]}
    for topic, count in expect.items():
        got = channels.get(topic, {}).get("count", 0)
        if got != count:
            problems.append(f"{topic}: {got} messages, the run has {count}")
    for topic in channels:
        if topic not in expect:
            problems.append(f"{topic}: a channel the run does not explain")
    poses = messages.get(pose_topic, [])
    ends = {}
    for key, m in (("first_pose", poses[0] if poses else None), ("final_pose", poses[-1] if poses else None)):
        if m is None or key not in want:
            continue
        p = m["pose"]
        got = [round(p["position"]["x"], 6), round(p["position"]["y"], 6), round(yaw(p["orientation"]), 6)]
        ends[key] = got
        if any(abs(x - y) > 1.5e-6 for x, y in zip(got, want[key])):
            problems.append(f"EKF {key}: the recording has {got}, the run {want[key]}")
    print(json.dumps({"channels": channels, "ekf": ends, "problems": problems}, indent=1))
    if a.picture:
        picture(messages, a.picture)
    if a.clouds:
        kidnaps = [] if a.link else [k["time_s"] for k in report.get("localization", {}).get("kidnaps", [])]
        clouds_picture(messages, a.clouds, kidnaps)
    if a.points:
        with open(a.points, "w") as out:
            out.write("time_s,x_m,y_m,weight\n")
            for m in messages.get("/particles", []):
                t = m["timestamp"]["sec"] + m["timestamp"]["nsec"] * 1e-9
                for x, y, w in cloud_points(m):
                    out.write(f"{t:.6f},{x:.6f},{y:.6f},{w:.9g}\n")
    if problems:
        sys.exit("mcap-check: " + "; ".join(problems))


def check_clouds(messages, trace_path, expect):
    """/particles against the trace's cycles: the cloud drawn at the start (a
    search from no pose, before the first cycle's end), then the cycles that
    ended searching or lost with particles, thinned to one per 0.25 s, each
    cloud as big as the cycle's particles; /hypotheses only at searching
    cycles' ends, the best of the place test's places leading by the
    cycle's lead."""
    import csv
    problems = []
    rows = list(csv.DictReader(open(trace_path)))
    stamp = lambda m: m["timestamp"]["sec"] + m["timestamp"]["nsec"] * 1e-9
    clouds = messages.get("/particles", [])
    first_row = float(rows[0]["time_s"]) if rows else 0.0
    start = [m for m in clouds[:1] if stamp(m) < first_row - 2e-6]
    due, last = [], stamp(start[0]) if start else None
    for r in rows:
        t, n = float(r["time_s"]), int(r["particles"])
        if r["mode"] != "tracking" and n > 0 and (last is None or t - last >= CLOUD_INTERVAL_S):
            due.append((t, n))
            last = t
    expect["/particles"] = len(due) + len(start)
    for (t, n), m in zip(due, clouds[len(start):]):
        got_t = stamp(m)
        points = len(m["data"]) // m["point_stride"] if m["point_stride"] else 0
        if abs(got_t - t) > 2e-6 or points != n:
            problems.append(f"/particles: a cloud of {points} at {got_t:.6f} s, the trace has {n} at {t:.6f} s")
            break
        names = [f["name"] for f in m["fields"]]
        if names[:2] != ["x", "y"] or "weight" not in names or m["frame_id"] != "map":
            problems.append(f"/particles: fields {names} in {m['frame_id']!r}")
            break
    searching = {round(float(r["time_s"]), 6) for r in rows if r["mode"] != "tracking"}
    hyp = messages.get("/hypotheses", [])
    if hyp:
        expect["/hypotheses"] = len(hyp)
    lead = {round(float(r["time_s"]), 6): float(r["lead_nats"]) for r in rows if r["lead_nats"]}
    for m in hyp:
        for e in m["entities"]:
            t = round(e["timestamp"]["sec"] + e["timestamp"]["nsec"] * 1e-9, 6)
            if t not in searching:
                problems.append(f"/hypotheses: {e['id']} at {t} s, a cycle that did not end searching")
                return problems
        # The place test's living places: the best one's smallest lead is
        # the cycle's lead in the trace (each drawn to 0.1 nats).
        places = [e for e in m["entities"] if e["id"].startswith("hypothesis/place/")]
        if places:
            t = round(places[0]["timestamp"]["sec"] + places[0]["timestamp"]["nsec"] * 1e-9, 6)
            best = max(float({kv["key"]: kv["value"] for kv in e["metadata"]}["smallest_lead_nats"]) for e in places)
            if t not in lead or abs(best - lead[t]) > 0.06:
                problems.append(f"/hypotheses: the best place leads by {best} at {t} s, the trace says {lead.get(t)}")
                return problems
    return problems


def cloud_points(m):
    import struct
    names = {f["name"]: f["offset"] for f in m["fields"]}
    stride, data = m["point_stride"], m["data"]
    out = []
    for k in range(0, len(data) - stride + 1, stride):
        x, = struct.unpack_from("<f", data, k + names["x"])
        y, = struct.unpack_from("<f", data, k + names["y"])
        w, = struct.unpack_from("<f", data, k + names["weight"])
        out.append((x, y, w))
    return out


def clouds_picture(messages, out, kidnaps):
    """The particle cloud at the start, at convergence (the last cloud before
    the first hand-off) and after the first kidnap (the run's JSON says
    when), as the recording has them."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    clouds = messages.get("/particles", [])
    if not clouds:
        sys.exit("mcap-check: --clouds: the recording has no /particles")
    t = lambda m: m["timestamp"]["sec"] + m["timestamp"]["nsec"] * 1e-9
    modes = [(t(m), m["message"]) for m in messages.get("/localization/mode", [])]
    handoffs = [tm for tm, msg in modes if msg.startswith("tracking")]
    picks = [("start", clouds[0])]
    if handoffs:
        before = [c for c in clouds if t(c) <= handoffs[0]]
        if before:
            picks.append(("at convergence (before the hand-off)", before[-1]))
    if kidnaps:
        after = [c for c in clouds if t(c) > kidnaps[0]]
        if after:
            picks.append((f"after the kidnap at {kidnaps[0]:.0f} s (the particles woke)", after[0]))
    truth = messages.get("/pose/truth", [])
    fig, axes = plt.subplots(1, len(picks), figsize=(6 * len(picks), 5.2), dpi=100, squeeze=False)
    for ax, (name, m) in zip(axes[0], picks):
        for e in messages["/map"][0]["entities"]:
            if e["id"] != "map/outlines":
                continue
            for line in e["lines"]:
                xs = [p["x"] for p in line["points"]]
                ys = [p["y"] for p in line["points"]]
                for k in range(0, len(xs) - 1, 2):
                    ax.plot(xs[k:k + 2], ys[k:k + 2], color=(0.0, 0.35, 0.86), lw=1)
        pts = cloud_points(m)
        w = [p[2] for p in pts]
        sc = ax.scatter([p[0] for p in pts], [p[1] for p in pts], c=w, s=3, cmap="viridis", zorder=3)
        tm = t(m)
        near = [q for q in truth if abs(t(q) - tm) < 1.0]
        if near:
            q = min(near, key=lambda q: abs(t(q) - tm))["pose"]["position"]
            ax.plot([q["x"]], [q["y"]], marker="o", mfc="none", color="red", ms=16, mew=1.5, label="truth", zorder=2)
            ax.legend(loc="lower right")
        ax.set_title(f"{name}: {tm:.1f} s, {len(pts)} particles", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        fig.colorbar(sc, ax=ax, shrink=0.7, label="weight")
    axes[0][0].set_ylabel("y (m)")
    fig.suptitle("/particles of a Foxglove recording, read back by PyPI's mcap")
    fig.tight_layout()
    fig.savefig(out)


def picture(messages, out):
    """What the recording shows at its last reading: the map, the paths, the
    EKF's covariance ellipses along the way, the last sensor window of every
    transducer coloured by verdict."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def rgba(c):
        return (c["r"], c["g"], c["b"], c["a"])

    fig, ax = plt.subplots(figsize=(12, 7), dpi=100)
    for e in messages["/map"][0]["entities"]:
        for line in e["lines"]:
            xs = [p["x"] for p in line["points"]]
            ys = [p["y"] for p in line["points"]]
            if line["type"] == 2:  # LINE_LIST
                for k in range(0, len(xs) - 1, 2):
                    ax.plot(xs[k:k + 2], ys[k:k + 2], color=rgba(line["color"]), lw=1)
            else:
                if line["type"] == 1:
                    xs, ys = xs + xs[:1], ys + ys[:1]
                ax.plot(xs, ys, color=rgba(line["color"]), lw=0.5 if e["id"] == "map/buffers" else 1)
    names = {"truth": "black", "dead_reckoning": "tab:red", "threshold": "tab:purple", "ekf": "tab:green"}
    for name, colour in names.items():
        ps = messages.get(f"/pose/{name}", [])
        ax.plot([m["pose"]["position"]["x"] for m in ps], [m["pose"]["position"]["y"] for m in ps],
                color=colour, lw=1, label=name.replace("_", " "))
    cov = messages.get("/ekf/covariance", [])
    for m in cov[:: max(1, len(cov) // 25)]:
        for sphere in m["entities"][0]["spheres"]:
            # A flat sphere: its size is the ellipse's axes, its yaw the major axis'.
            x0, y0, th = pose2(sphere["pose"])
            a, b = sphere["size"]["x"] / 2, sphere["size"]["y"] / 2
            us = [2 * math.pi * k / 48 for k in range(49)]
            ax.plot([x0 + a * math.cos(u) * math.cos(th) - b * math.sin(u) * math.sin(th) for u in us],
                    [y0 + a * math.cos(u) * math.sin(th) + b * math.sin(u) * math.cos(th) for u in us],
                    color="tab:green", lw=0.6)
    # Each frame's pose at each time, from /tf: the sensor windows are drawn in the estimate's frame.
    frames = {}
    for m in messages.get("/tf", []):
        for tr in m["transforms"]:
            t = tr["timestamp"]["sec"] * 10**9 + tr["timestamp"]["nsec"]
            q = tr["rotation"]
            frames[(tr["child_frame_id"], t)] = (tr["translation"]["x"], tr["translation"]["y"], yaw(q))
    last = {}
    for m in messages.get("/sonar", []):
        e = m["entities"][0]
        last[e["id"]] = e
    for e in last.values():
        t = e["timestamp"]["sec"] * 10**9 + e["timestamp"]["nsec"]
        f = frames.get((e["frame_id"], t), (0.0, 0.0, 0.0)) if e["frame_id"] != "map" else (0.0, 0.0, 0.0)
        for k, line in enumerate(e["lines"]):
            p = compose(f, pose2(line["pose"]))
            pts = [compose(p, (q["x"], q["y"], 0.0)) for q in line["points"]]
            xs, ys = [q[0] for q in pts], [q[1] for q in pts]
            if line["type"] == 1:
                xs, ys = xs + xs[:1], ys + ys[:1]
            ax.plot(xs, ys, color=rgba(line["color"]), lw=line["thickness"] * 0.6,
                    alpha=0.5 if k == 0 else 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Foxglove recording, read back by PyPI's mcap: map, paths, 2σ ellipses, last sensor windows", fontsize=10)
    from matplotlib.lines import Line2D
    handles, _ = ax.get_legend_handles_labels()
    # The verdict colours as the recording has them (read from its sensor windows).
    seen = {}
    for e in last.values():
        meta = {kv["key"]: kv["value"] for kv in e["metadata"]}
        if meta["observed_mm"] != "no echo" and len(e["lines"]) > 1:
            seen.setdefault(meta["verdict"], rgba(e["lines"][-1]["color"]))
    handles += [Line2D([], [], color=c, lw=3, label=f"observed: {v}") for v, c in sorted(seen.items())]
    handles.append(Line2D([], [], color=(0.2, 0.2, 0.9), lw=2, label="predicted range (chord)"))
    handles.append(Line2D([], [], color=(0.4, 0.4, 0.4), lw=1, label="sensor window"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main()
