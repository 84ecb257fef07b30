"""An outside client of the Foxglove WebSocket protocol, as Foxglove and
Lichtblick speak it: Python's websockets, nothing of vl's.

Connects offering SUBPROTOCOL, reads serverInfo and advertise, subscribes to
the camera, the robot's pose, the transforms and the scene, and decodes
what comes: each message data's opcode, subscription id and time, its JSON
payload, each camera image's JPEG. Prints what it saw as JSON.

usage: client.py URL SUBPROTOCOL SECONDS
"""
import asyncio
import base64
import json
import struct
import sys
import time

import websockets

url, subprotocol, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
WANTED = ["/camera", "/robot/pose", "/tf", "/scene", "/state"]


async def main():
    seen = {"subprotocol": None, "server": None, "channels": {}, "counts": {},
            "jpegs": 0, "bad": [], "times_rise": True, "pose": None}
    async with websockets.connect(url, subprotocols=[subprotocol], max_size=None) as ws:
        seen["subprotocol"] = ws.subprotocol
        info = json.loads(await asyncio.wait_for(ws.recv(), 10))
        assert info["op"] == "serverInfo", info
        seen["server"] = info["name"]
        advertise = json.loads(await asyncio.wait_for(ws.recv(), 10))
        assert advertise["op"] == "advertise", advertise
        by_topic = {c["topic"]: c for c in advertise["channels"]}
        for c in advertise["channels"]:
            json.loads(c["schema"])  # every schema is JSON Schema text
            seen["channels"][c["topic"]] = c["schemaName"]
        subscriptions = [{"id": 100 + i, "channelId": by_topic[t]["id"]}
                         for i, t in enumerate(WANTED)]
        topic_of = {s["id"]: t for s, t in zip(subscriptions, WANTED)}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        last = {}
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                message = await asyncio.wait_for(ws.recv(), max(end - time.monotonic(), 0.01))
            except asyncio.TimeoutError:
                break
            if isinstance(message, str):
                continue
            if message[0] != 1:  # time (2) and the rest are not message data
                continue
            opcode, sub, ns = struct.unpack_from("<BIQ", message)
            topic = topic_of.get(sub)
            if topic is None:
                seen["bad"].append(f"unknown subscription {sub}")
                continue
            payload = json.loads(message[13:])
            seen["counts"][topic] = seen["counts"].get(topic, 0) + 1
            if topic in ("/camera", "/robot/pose", "/tf") and ns < last.get(topic, 0):
                seen["times_rise"] = False
            last[topic] = ns
            if topic == "/camera":
                jpeg = base64.b64decode(payload["data"])
                if payload["format"] == "jpeg" and jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9":
                    seen["jpegs"] += 1
                else:
                    seen["bad"].append("a camera image that is no whole JPEG")
            elif topic == "/robot/pose":
                position = payload["pose"]["position"]
                seen["pose"] = [position["x"], position["y"]]
                assert payload["frame_id"] == "arena", payload
            elif topic == "/tf":
                assert payload["child_frame_id"] == "robot", payload
            elif topic == "/scene":
                assert any(e["id"] == "obstacles" for e in payload["entities"]), payload
    print(json.dumps(seen))


asyncio.run(main())
