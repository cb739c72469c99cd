#!/usr/bin/env python3
"""Reads an echoloc Foxglove recording (MCAP) with PyPI's `mcap` package,
independently of echoloc, and checks it against the run's JSON report
(`echoloc-lab simulate|replay --json --mcap OUT.mcap`):

- every channel has a well-known Foxglove schema name, JSON Schema encoded,
  JSON messages that parse, and log times that never decrease and equal the
  messages' own timestamps;
- the message counts match the run: one pose, transform, sensor window and
  covariance ellipse per reading, truth poses per reading with a reference,
  one map, a state log line at the start and at each change of the localizer's mode;
- the first and last EKF poses equal the JSON's `ekf.first_pose` and
  `ekf.final_pose` (6 decimals).

Prints a JSON summary; exits 1 with the reasons on any failure.
--picture OUT.png draws what the recording shows (needs matplotlib).

With --link, REPORT is what `echoloc-lab link --mcap` printed (one JSON line
per controller message): the counts and the first and last poses are the
controller's Reading messages'.

Usage: python3 scripts/mcap-check.py RUN.mcap RUN.json [--picture OUT.png]
       python3 scripts/mcap-check.py LINK.mcap LINK.jsonl --link
"""
import argparse
import json
import math
import sys

try:
    from mcap.reader import make_reader
except ImportError as e:
    sys.exit(f"mcap-check.py needs PyPI's mcap ({e}): pip install mcap")

FOXGLOVE = {
    "foxglove.SceneUpdate", "foxglove.FrameTransforms", "foxglove.FrameTransform", "foxglove.PoseInFrame",
    "foxglove.PosesInFrame", "foxglove.Log", "foxglove.PointCloud", "foxglove.LaserScan", "foxglove.Grid",
}


def yaw(q):
    return math.atan2(2 * (q["w"] * q["z"] + q["x"] * q["y"]), 1 - 2 * (q["y"] ** 2 + q["z"] ** 2))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mcap")
    ap.add_argument("report")
    ap.add_argument("--picture")
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
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            topic = channel.topic
            if topic not in channels:
                channels[topic] = {"schema": schema.name, "schema_encoding": schema.encoding,
                                   "message_encoding": channel.message_encoding, "count": 0}
                if schema.name not in FOXGLOVE:
                    problems.append(f"{topic}: schema {schema.name!r} is not a well-known Foxglove schema")
                if schema.encoding != "jsonschema" or channel.message_encoding != "json":
                    problems.append(f"{topic}: encodings {schema.encoding}/{channel.message_encoding}")
                json.loads(schema.data)
            channels[topic]["count"] += 1
            if message.log_time < last_time:
                problems.append(f"{topic}: log time {message.log_time} before {last_time}")
            last_time = message.log_time
            m = json.loads(message.data)
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
        expect = {"/tf": n, "/pose/controller": n, "/ekf/covariance": n, "/sonar": n, "/state": (1 + changes) if n else 0}
        pose_topic = "/pose/controller"
        want = {"first_pose": readings[0]["pose"], "final_pose": readings[-1]["pose"]} if n else {}
    else:
        n = report["readings"]
        with_truth = report.get("log", {}).get("reference_rows", n)
        expect = {
            "/map": 1, "/tf": n, "/pose/ekf": n, "/pose/dead_reckoning": n, "/pose/threshold": n,
            "/ekf/covariance": n, "/sonar": n, "/state": 1 + report["localization"]["mode_changes"],
        }
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
    if problems:
        sys.exit("mcap-check: " + "; ".join(problems))


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
        for line in m["entities"][0]["lines"]:
            xs = [p["x"] for p in line["points"]]
            ys = [p["y"] for p in line["points"]]
            ax.plot(xs + xs[:1], ys + ys[:1], color="tab:green", lw=0.6)
    last = {}
    for m in messages.get("/sonar", []):
        e = m["entities"][0]
        last[e["id"]] = e
    for e in last.values():
        meta = {kv["key"]: kv["value"] for kv in e["metadata"]}
        for k, line in enumerate(e["lines"]):
            xs = [p["x"] for p in line["points"]]
            ys = [p["y"] for p in line["points"]]
            if line["type"] == 1:
                xs, ys = xs + xs[:1], ys + ys[:1]
            ax.plot(xs, ys, color=rgba(line["color"]), lw=line["thickness"] * 0.6,
                    alpha=0.5 if k == 0 else 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Foxglove recording, read back by PyPI's mcap: map, paths, 2σ ellipses, last sensor windows")
    from matplotlib.lines import Line2D
    handles, _ = ax.get_legend_handles_labels()
    # The verdict colours as the recording has them (read from its sensor windows).
    seen = {}
    for e in last.values():
        meta = {kv["key"]: kv["value"] for kv in e["metadata"]}
        if meta["observed_mm"] != "no echo" and len(e["lines"]) > 1:
            seen.setdefault(meta["verdict"], rgba(e["lines"][-1]["color"]))
    handles += [Line2D([], [], color=c, lw=3, label=f"observed: {v}") for v, c in sorted(seen.items())]
    handles.append(Line2D([], [], color=(0.2, 0.2, 0.9), lw=2, label="predicted range"))
    handles.append(Line2D([], [], color=(0.4, 0.4, 0.4), lw=1, label="sensor window"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main()
