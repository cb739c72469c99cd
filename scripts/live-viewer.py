#!/usr/bin/env python3
"""An independent viewer of echoloc's live view (`echoloc-lab link --live`,
`replay --live`): speaks Foxglove's WebSocket protocol as the Foxglove app
does, with PyPI's `websockets` (not echoloc's code, not Foxglove's SDK).

It connects (subprotocol `foxglove.sdk.v1`), reads the server's `serverInfo`
and `advertise`, subscribes to the topics asked for, decodes each binary
message-data frame's protobuf payload with the schema the channel
advertised (google.protobuf), and prints a JSON summary: per topic the
message count, the first and last log times, and for PoseInFrame topics the
first and last poses (x, y, yaw).

  --late S         connect only after S seconds
  --leave-after N  disconnect after N messages (a viewer that goes mid-run)
  --idle-s S       stop when no message came for S seconds (after the first)
  --timeout-s S    give up connecting / waiting after S seconds

Usage: python3 scripts/live-viewer.py ws://127.0.0.1:8765 --topics /pose/controller /sonar /localization/mode
"""
import argparse
import asyncio
import base64
import json
import math
import struct
import sys
import time

try:
    import websockets
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
except ImportError as e:
    sys.exit(f"live-viewer.py needs PyPI's websockets and protobuf ({e}): pip install websockets protobuf")


def message_class(schema_name, schema_b64):
    """The protobuf class of `schema_name` from a base64 FileDescriptorSet."""
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def yaw(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2))


async def view(a):
    if a.late:
        await asyncio.sleep(a.late)
    deadline = time.monotonic() + a.timeout_s
    while True:
        try:
            ws = await websockets.connect(a.url, subprotocols=["foxglove.sdk.v1"], max_size=None)
            break
        except OSError:
            if time.monotonic() > deadline:
                sys.exit(f"live-viewer: cannot connect to {a.url}")
            await asyncio.sleep(0.1)
    summary = {"server": None, "subprotocol": ws.subprotocol, "topics": {}, "left_early": False}
    channels, subs, classes = {}, {}, {}
    wanted = set(a.topics)
    total = 0
    last_message = None
    async with ws:
        while True:
            idle = a.idle_s if last_message is not None else max(0.1, deadline - time.monotonic())
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=idle)
            except asyncio.TimeoutError:
                if last_message is None:
                    sys.exit("live-viewer: no message came")
                break
            except websockets.ConnectionClosed:
                break
            if isinstance(frame, str):
                m = json.loads(frame)
                if m["op"] == "serverInfo":
                    summary["server"] = m.get("name")
                elif m["op"] == "advertise":
                    new = []
                    for c in m["channels"]:
                        channels[c["id"]] = c
                        if c["topic"] in wanted and c["id"] not in subs.values():
                            sid = len(subs) + 1
                            subs[sid] = c["id"]
                            new.append({"id": sid, "channelId": c["id"]})
                            if c.get("encoding") != "protobuf" or c.get("schemaEncoding") != "protobuf":
                                sys.exit(f"live-viewer: {c['topic']} is {c.get('encoding')}/{c.get('schemaEncoding')}")
                            classes[c["id"]] = message_class(c["schemaName"], c["schema"])
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                continue
            # Binary: opcode 1 is message data (subscription id, log time, payload).
            if frame[0] != 1:
                continue
            sid, log_time = struct.unpack_from("<IQ", frame, 1)
            cid = subs.get(sid)
            if cid is None:
                continue
            c = channels[cid]
            msg = classes[cid].FromString(frame[13:])
            t = summary["topics"].setdefault(c["topic"], {"schema": c["schemaName"], "count": 0})
            t["count"] += 1
            t.setdefault("first_time", log_time)
            t["last_time"] = log_time
            if c["schemaName"] == "foxglove.PoseInFrame":
                p = msg.pose
                pose = [round(p.position.x, 6), round(p.position.y, 6), round(yaw(p.orientation), 6)]
                t.setdefault("first_pose", pose)
                t["last_pose"] = pose
            if c["schemaName"] == "foxglove.Log":
                t.setdefault("messages", []).append(msg.message)
            total += 1
            last_message = time.monotonic()
            if a.leave_after and total >= a.leave_after:
                summary["left_early"] = True
                break
    summary["messages"] = total
    print(json.dumps(summary, indent=1))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("url")
    ap.add_argument("--topics", nargs="+", required=True)
    ap.add_argument("--late", type=float, default=0.0)
    ap.add_argument("--leave-after", type=int, default=0)
    ap.add_argument("--idle-s", type=float, default=3.0)
    ap.add_argument("--timeout-s", type=float, default=60.0)
    asyncio.run(view(ap.parse_args()))


if __name__ == "__main__":
    main()
