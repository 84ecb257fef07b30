"""An outside ROS 2 client of a lab served with `vl host --ros2`: PyPI's
zenoh-ros2-sdk (rmw_zenoh's wire format, nothing of vl's), given the
vendored .msg folder as its registry so it never downloads. Prints one
JSON object with what it saw; tests/ros2.rs asserts on it.

    python3 lab.py MSG_DIR ROUTER_PORT STEP [SECONDS [SPEED | MODE | TOPIC...]]

STEP is one of:
  discover  the topics, their types, hashes and QoS, and the hashes the
            SDK computes itself from the .msg files
  watch     every topic for SECONDS: counts, rates, a decoded image's
            size, the camera info, the last odometry, /tf's frames
  list      the topics and their types, once TOPIC... (after SECONDS) are
            all listed, or SECONDS have passed
  map       /map as a subscriber joining late (transient local)
  drive     Twists on /cmd_vel at 20 Hz: SECONDS forward at SPEED m/s, then
            the odometry after a second of silence
  turn      as drive, turning on the spot at SPEED rad/s
  forge_odom  for SECONDS at 400 Hz, /odom saying the robot stands where
            it stood, as a publisher of its own or (MODE copy) as the robot
  hostile   for SECONDS, as fast as it can, on /cmd_vel's key: random bytes,
            cut Twists, Twists of NaN, of ±1e300 and of a turn at 1e9 rad/s;
            the fastest the robot went meanwhile
"""

import json
import struct
import sys
import threading
import time

MSG_DIR, PORT, STEP = sys.argv[1], int(sys.argv[2]), sys.argv[3]
SECONDS = float(sys.argv[4]) if len(sys.argv) > 4 else 3.0
SPEED = float(sys.argv[5]) if len(sys.argv) > 5 and STEP in ("drive", "turn") else 0.05

from zenoh_ros2_sdk import get_registry  # noqa: E402

# The first call fixes the registry's folder: the vendored one, offline.
REGISTRY = get_registry(MSG_DIR)

from zenoh_ros2_sdk import (  # noqa: E402
    ROS2Publisher,
    ROS2Subscriber,
    get_topic_info,
    get_topic_names_and_types,
)
from zenoh_ros2_sdk.qos import QosDurability, QosProfile  # noqa: E402
from zenoh_ros2_sdk.utils import get_type_hash, load_dependencies_recursive  # noqa: E402

TOPICS = {
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/camera/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
}


def sdk_hash(msg_type):
    """The type hash the SDK computes from the .msg files alone."""
    definition = open(REGISTRY.get_msg_file_path(msg_type)).read()
    deps = load_dependencies_recursive(msg_type, definition, REGISTRY)
    return get_type_hash(msg_type, msg_definition=definition, dependencies=deps)


def discover():
    # The node may still be coming up: ask until every topic is there.
    deadline = time.monotonic() + 20
    while True:
        listed = dict(get_topic_names_and_types(router_port=PORT, timeout=1.0))
        if set(TOPICS) | {"/cmd_vel"} <= set(listed) or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    topics = {}
    for topic in list(TOPICS) + ["/cmd_vel"]:
        info = get_topic_info(topic, router_port=PORT, timeout=1.0, verbose=True)
        if info is None:
            continue
        ends = info.publishers + info.subscribers
        topics[topic] = {
            "types": info.topic_types,
            "publishers": info.publisher_count,
            "subscribers": info.subscriber_count,
            "hashes": sorted({e.type_hash for e in ends}),
            "qos": sorted({e.qos for e in ends}),
            "nodes": sorted({e.node_name for e in ends}),
            "sdk_hash": sdk_hash(info.topic_types[0]),
        }
    return {"listed": listed, "topics": topics}


def listing():
    expected = set(sys.argv[5:])
    deadline = time.monotonic() + SECONDS
    while True:
        listed = dict(get_topic_names_and_types(router_port=PORT, timeout=1.0))
        if expected <= set(listed) or time.monotonic() > deadline:
            return {"listed": listed}
        time.sleep(0.5)


def jpeg_size(data):
    """(width, height) from a JPEG's start-of-frame, or None."""
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker, length = data[i + 1], struct.unpack(">H", data[i + 2 : i + 4])[0]
        if marker in (0xC0, 0xC1, 0xC2):
            height, width = struct.unpack(">HH", data[i + 5 : i + 9])
            return [width, height]
        i += 2 + length
    return None


def watch():
    seen = {topic: [] for topic in TOPICS if topic != "/map"}
    last = {}
    lock = threading.Lock()

    def keep(topic):
        def on(msg):
            with lock:
                seen[topic].append(time.monotonic())
                last[topic] = msg

        return on

    subs = [ROS2Subscriber(topic=t, msg_type=TOPICS[t], callback=keep(t), router_port=PORT) for t in seen]
    time.sleep(1.0)
    with lock:
        for times in seen.values():
            times.clear()
    time.sleep(SECONDS)
    with lock:
        counts = {t: len(v) for t, v in seen.items()}
        rates = {t: len(v) / SECONDS for t, v in seen.items()}
        image = last.get("/camera/image_raw/compressed")
        info = last.get("/camera/camera_info")
        odom = last.get("/odom")
        tf = last.get("/tf")
        scan = last.get("/scan")
    for s in subs:
        s.close()
    out = {"counts": counts, "rates": rates}
    if image is not None:
        import io

        from PIL import Image

        data = bytes(image.data)
        decoded = Image.open(io.BytesIO(data))
        decoded.load()  # every pixel decoded, or an exception
        out["image"] = {
            "format": image.format,
            "decoded": decoded.format,
            "size": list(decoded.size),
            "sof_size": jpeg_size(data),
            "frame": image.header.frame_id,
        }
    if info is not None:
        out["camera_info"] = {
            "size": [info.width, info.height],
            "k": list(info.k),
            "model": info.distortion_model,
            "frame": info.header.frame_id,
        }
    if odom is not None:
        out["odom"] = odom_of(odom)
    if tf is not None:
        out["tf"] = [
            {
                "parent": t.header.frame_id,
                "child": t.child_frame_id,
                "xyz": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                "stamp": t.header.stamp.sec + t.header.stamp.nanosec * 1e-9,
            }
            for t in tf.transforms
        ]
    if scan is not None:
        finite = [r for r in scan.ranges if r == r and r != float("inf")]
        out["scan"] = {"bins": len(scan.ranges), "seen": len(finite), "frame": scan.header.frame_id}
    out["now"] = time.time()
    return out


def odom_of(odom):
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    return {
        "x": p.x,
        "y": p.y,
        "qz": q.z,
        "qw": q.w,
        "v": odom.twist.twist.linear.x,
        "w": odom.twist.twist.angular.z,
        "frame": odom.header.frame_id,
        "child": odom.child_frame_id,
        "stamp": odom.header.stamp.sec + odom.header.stamp.nanosec * 1e-9,
    }


def late_map():
    got = []
    done = threading.Event()

    def on(msg):
        got.append(msg)
        done.set()

    latched = QosProfile(durability=QosDurability.TRANSIENT_LOCAL, history_depth=1)
    sub = ROS2Subscriber(topic="/map", msg_type=TOPICS["/map"], callback=on, router_port=PORT, qos=latched)
    done.wait(SECONDS)
    sub.close()
    if not got:
        return {"maps": 0}
    m = got[0]
    return {
        "maps": len(got),
        "size": [m.info.width, m.info.height],
        "resolution": m.info.resolution,
        "cells": len(m.data),
        "taken": sum(1 for c in m.data if c == 100),
        "edge_free": sum(
            1
            for i, c in enumerate(m.data)
            if c != 100
            and (i % m.info.width in (0, m.info.width - 1) or i // m.info.width in (0, m.info.height - 1))
        ),
        "frame": m.header.frame_id,
    }


def drive(turn=False):
    odoms = []
    sub = ROS2Subscriber(
        topic="/odom", msg_type=TOPICS["/odom"], callback=lambda m: odoms.append(odom_of(m)), router_port=PORT
    )
    pub = ROS2Publisher(topic="/cmd_vel", msg_type="geometry_msgs/msg/Twist", router_port=PORT)
    time.sleep(1.0)
    start = odoms[-1] if odoms else None
    Vector3 = REGISTRY.get_message_class("geometry_msgs/msg/Vector3")
    began = time.monotonic()
    sent = 0
    while time.monotonic() - began < SECONDS:
        v, w = (0.0, SPEED) if turn else (SPEED, 0.0)
        pub.publish(linear=Vector3(x=v, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=w))
        sent += 1
        time.sleep(0.05)
    driven = odoms[-1] if odoms else None
    fastest = max((o["v"] for o in odoms), default=0.0)
    # Silence: the lab's watchdog stops the robot.
    time.sleep(1.0)
    after = odoms[-1] if odoms else None
    time.sleep(0.5)
    later = odoms[-1] if odoms else None
    pub.close()
    sub.close()
    return {
        "sent": sent,
        "start": start,
        "driven": driven,
        "fastest_v": fastest,
        "after_silence": after,
        "later": later,
    }


def hostile():
    import random

    import zenoh

    from zenoh_ros2_sdk import ZenohSession
    from zenoh_ros2_sdk.utils import ros2_to_dds_type

    msg_type = "geometry_msgs/msg/Twist"
    key = f"0/cmd_vel/{ros2_to_dds_type(msg_type)}/{sdk_hash(msg_type)}"
    odoms = []
    sub = ROS2Subscriber(
        topic="/odom", msg_type=TOPICS["/odom"], callback=lambda m: odoms.append(odom_of(m)), router_port=PORT
    )
    session = ZenohSession.get_instance("127.0.0.1", PORT).session
    pub = session.declare_publisher(key)
    header = b"\x00\x01\x00\x00"

    def twist(vx, wz):
        return header + struct.pack("<6d", vx, 0.0, 0.0, 0.0, 0.0, wz)

    rng = random.Random(7)
    kinds = [
        lambda: bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 200))),
        lambda: twist(0.1, 0.0)[: rng.randrange(0, 52)],
        lambda: twist(float("nan"), 0.0),
        lambda: twist(float("inf"), float("-inf")),
        lambda: twist(rng.choice([1e300, -1e300]), 0.0),
        lambda: twist(0.0, 1e9),
        lambda: header + b"\xff" * 48 + b"extra bytes after the message",
    ]
    sent = 0
    began = time.monotonic()
    while time.monotonic() - began < SECONDS:
        pub.put(rng.choice(kinds)())
        sent += 1
    time.sleep(1.0)
    sub.close()
    return {
        "sent": sent,
        "odoms": len(odoms),
        "fastest_v": max((abs(o["v"]) for o in odoms), default=0.0),
        "fastest_w": max((abs(o["w"]) for o in odoms), default=0.0),
        "last": odoms[-1] if odoms else None,
    }


def forge_odom():
    """A stranger on /odom for SECONDS at 400 Hz, saying the robot stands
    where it stood when this began (the robot's own sample, sent again):
    as a publisher of its own (MODE "own"), or writing as the robot, its
    GID and numbers ahead of its own (MODE "copy")."""
    import os

    import zenoh

    from zenoh_ros2_sdk.utils import ros2_to_dds_type

    mode = sys.argv[5] if len(sys.argv) > 5 else "own"
    msg_type = TOPICS["/odom"]
    key = f"0/odom/{ros2_to_dds_type(msg_type)}/{sdk_hash(msg_type)}"
    # A plain Zenoh session: a stranger needs nothing of ROS's.
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{PORT}"]))
    session = zenoh.open(conf)
    robot = {}

    def heard(sample):
        if sample.attachment is not None and "payload" not in robot:
            robot["payload"] = bytes(sample.payload.to_bytes())
            robot["attachment"] = bytes(sample.attachment.to_bytes())

    sub = session.declare_subscriber(key, heard)
    deadline = time.monotonic() + 5
    while "payload" not in robot and time.monotonic() < deadline:
        time.sleep(0.01)
    if "payload" not in robot:
        session.close()
        return {"sent": 0, "why": "no /odom heard"}
    sequence, _ = struct.unpack("<qq", robot["attachment"][:16])
    gid = robot["attachment"][17:] if mode == "copy" else os.urandom(16)
    number = sequence + 100_000 if mode == "copy" else 1
    sent = 0
    began = time.monotonic()
    while time.monotonic() - began < SECONDS:
        attachment = struct.pack("<qqB", number, time.time_ns(), len(gid)) + gid
        session.put(key, robot["payload"], attachment=attachment)
        number += 1
        sent += 1
        time.sleep(0.0025)
    sub.undeclare()
    session.close()
    return {"sent": sent, "mode": mode}


STEPS = {"forge_odom": forge_odom, "discover": discover, "list": listing, "watch": watch, "map": late_map, "drive": drive, "turn": lambda: drive(turn=True), "hostile": hostile}
print(json.dumps(STEPS[STEP]()), flush=True)
