"""A simulated ROS 2 differential-drive robot, written with PyPI's
zenoh-ros2-sdk (nothing of vl's): it takes Twists on /cmd_vel, stops by
itself 0.5 s after the last (as ROS 2's diff_drive_controller's command
timeout does), moves as a Khepera-sized differential drive whose wheels
reach their speeds at 4 m/s² (a Khepera's controller), and publishes
/odom at 50 Hz. Given an overhead picture of its arena (`vl sim render`,
which shows the robot at its start), it is also an overhead camera: 15
times a second it paints the floor over the robot's start and draws the
robot where it is (a red body, a white marker ahead of its centre, as the
lab's vision knows a Khepera from above), and publishes the JPEG on
/camera/image_raw/compressed. Prints one JSON line a second: its pose and
the Twists it has taken. Given STUCK_AFTER_M, its body sticks once its
wheels have rolled that far: the wheels spin on and /odom counts them, but
the camera shows the robot where it stuck.

    python3 robot.py MSG_DIR ROUTER_PORT X_M Y_M THETA_RAD [BACKDROP.png ARENA_WIDTH_MM [STUCK_AFTER_M]]
"""

import json
import math
import sys
import threading
import time

MSG_DIR, PORT = sys.argv[1], int(sys.argv[2])
x, y, theta = (float(v) for v in sys.argv[3:6])

from zenoh_ros2_sdk import get_registry  # noqa: E402

REGISTRY = get_registry(MSG_DIR)

from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber  # noqa: E402

TIMEOUT = 0.5
PERIOD = 0.02
ACCEL = 4.0  # m/s², each wheel
BASE = 0.053  # m between the wheels
TOP_V, TOP_W = 0.5, 10.0

lock = threading.Lock()
asked = {"v": 0.0, "w": 0.0, "at": 0.0}
twists = 0


def on_twist(msg):
    global twists
    with lock:
        asked["v"] = max(-TOP_V, min(TOP_V, msg.linear.x))
        asked["w"] = max(-TOP_W, min(TOP_W, msg.angular.z))
        asked["at"] = time.monotonic()
        twists += 1


sub = ROS2Subscriber(topic="/cmd_vel", msg_type="geometry_msgs/msg/Twist", callback=on_twist, router_port=PORT)
odom = ROS2Publisher(topic="/odom", msg_type="nav_msgs/msg/Odometry", router_port=PORT, node_name="sim_robot")

Header = REGISTRY.get_message_class("std_msgs/msg/Header")
Time = REGISTRY.get_message_class("builtin_interfaces/msg/Time")
Point = REGISTRY.get_message_class("geometry_msgs/msg/Point")
Quaternion = REGISTRY.get_message_class("geometry_msgs/msg/Quaternion")
Pose = REGISTRY.get_message_class("geometry_msgs/msg/Pose")
PoseWithCovariance = REGISTRY.get_message_class("geometry_msgs/msg/PoseWithCovariance")
Vector3 = REGISTRY.get_message_class("geometry_msgs/msg/Vector3")
Twist = REGISTRY.get_message_class("geometry_msgs/msg/Twist")
TwistWithCovariance = REGISTRY.get_message_class("geometry_msgs/msg/TwistWithCovariance")

import numpy as np  # noqa: E402  (rosbags' messages take arrays)

RADIUS = 0.035  # m, a Khepera II's
FLOOR, BODY, MARKER = (226, 224, 216), (170, 36, 32), (250, 250, 250)


def camera(backdrop_path, width_mm):
    """Publishes what an overhead camera sees, 15 frames a second."""
    import io

    from PIL import Image, ImageDraw

    backdrop = Image.open(backdrop_path).convert("RGB")
    px_per_m = backdrop.width / (width_mm / 1000)

    def at(mx, my):
        return mx * px_per_m, backdrop.height - my * px_per_m

    def disc(draw, mx, my, r_m, colour):
        cx, cy = at(mx, my)
        r = r_m * px_per_m
        draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=colour)

    disc(ImageDraw.Draw(backdrop), x, y, RADIUS + 3 / px_per_m, FLOOR)
    images = ROS2Publisher(
        topic="/camera/image_raw/compressed",
        msg_type="sensor_msgs/msg/CompressedImage",
        router_port=PORT,
        node_name="sim_camera",
    )
    while True:
        with lock:
            px, py, heading = pose
        frame = backdrop.copy()
        draw = ImageDraw.Draw(frame)
        disc(draw, px, py, RADIUS, BODY)
        ahead = 0.45 * RADIUS
        disc(draw, px + ahead * math.cos(heading), py + ahead * math.sin(heading), 0.35 * RADIUS, MARKER)
        jpeg = io.BytesIO()
        frame.save(jpeg, format="JPEG", quality=90)
        now = time.time()
        images.publish(
            header=Header(stamp=Time(sec=int(now), nanosec=int((now % 1) * 1e9)), frame_id="camera"),
            format="jpeg",
            data=np.frombuffer(jpeg.getvalue(), dtype=np.uint8),
        )
        time.sleep(1 / 15)


pose = (x, y, theta)
if len(sys.argv) > 7:
    threading.Thread(target=camera, args=(sys.argv[6], float(sys.argv[7])), daemon=True).start()


def toward(now, target, dt):
    step = ACCEL * dt
    return now + max(-step, min(step, target - now))


STUCK_AFTER = float(sys.argv[8]) if len(sys.argv) > 8 else math.inf
rolled = 0.0
left = right = 0.0
last_said = time.monotonic()
while True:
    with lock:
        fresh = time.monotonic() - asked["at"] <= TIMEOUT
        target_v, target_w = (asked["v"], asked["w"]) if fresh else (0.0, 0.0)
    left = toward(left, target_v - target_w * BASE / 2, PERIOD)
    right = toward(right, target_v + target_w * BASE / 2, PERIOD)
    v, w = (left + right) / 2, (right - left) / BASE
    x += v * math.cos(theta) * PERIOD
    y += v * math.sin(theta) * PERIOD
    theta = math.atan2(math.sin(theta + w * PERIOD), math.cos(theta + w * PERIOD))
    rolled += abs(v) * PERIOD
    if rolled < STUCK_AFTER:
        with lock:
            pose = (x, y, theta)
    now = time.time()
    stamp = Time(sec=int(now), nanosec=int((now % 1) * 1e9))
    odom.publish(
        header=Header(stamp=stamp, frame_id="odom"),
        child_frame_id="base_link",
        pose=PoseWithCovariance(
            pose=Pose(
                position=Point(x=x, y=y, z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2)),
            ),
            covariance=np.zeros(36),
        ),
        twist=TwistWithCovariance(
            twist=Twist(linear=Vector3(x=v, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=w)),
            covariance=np.zeros(36),
        ),
    )
    if time.monotonic() - last_said >= 1.0:
        last_said = time.monotonic()
        with lock:
            seen_x, seen_y, _ = pose
            print(json.dumps({"x": x, "y": y, "theta": theta, "twists": twists, "seen": [seen_x, seen_y]}), flush=True)
    time.sleep(PERIOD)
