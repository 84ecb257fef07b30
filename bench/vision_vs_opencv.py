"""vl's vision pipeline against OpenCV's equivalent on the same frame, in one run.

    pip install opencv-python-headless
    cargo build --release
    python3 bench/vision_vs_opencv.py [FRAME.png]

OpenCV: grey, Otsu threshold, connectedComponentsWithStats (8-connected),
also timed alone,
and moments + Hu of each component (on its bounding-box ROI). vl: the same
steps plus hole finding and the robot's pose (`vl vision bench`), and
the Host's in-loop `look` (the same steps, locating the robot). Prints the
times and vl/OpenCV (below 1 means vl is faster).
"""
import json
import subprocess
import sys
import time

import cv2
import numpy as np

frame = sys.argv[1] if len(sys.argv) > 1 else "tests/vision/maze-640.png"
runs = 200
cv2.setNumThreads(1)
bgr = cv2.imread(frame, cv2.IMREAD_COLOR)


def opencv_labelling():
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    _, mask = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    return cv2.connectedComponentsWithStats(mask, connectivity=8)


def opencv_pipeline():
    n, labels, stats, _ = opencv_labelling()
    for i in range(1, n):
        x, y, w, h, _ = stats[i]
        roi = (labels[y : y + h, x : x + w] == i).astype(np.uint8)
        cv2.HuMoments(cv2.moments(roi, binaryImage=True))


def per_frame_ms(pipeline):
    pipeline()
    start = time.perf_counter()
    for _ in range(runs):
        pipeline()
    return (time.perf_counter() - start) * 1e3 / runs


opencv_ms = per_frame_ms(opencv_pipeline)
labelling_ms = per_frame_ms(opencv_labelling)

out = subprocess.run(
    ["target/release/vl", "vision", "bench", frame, "--runs", str(runs), "--json"],
    check=True,
    capture_output=True,
    text=True,
)
bench = json.loads(out.stdout)
vl_ms = bench["ms_per_frame"]
look_ms = bench["look_ms_per_frame"]
print(f"{'frame':<10} {frame}")
print(f"{'OpenCV':<10} {opencv_ms:8.3f} ms/frame  (cv2 {cv2.__version__}, one thread)")
print(f"{'  no Hu':<10} {labelling_ms:8.3f} ms/frame  (grey, Otsu, components with stats only)")
print(f"{'vl':<10} {vl_ms:8.3f} ms/frame")
print(f"{'vl/OpenCV':<10} {vl_ms / opencv_ms:8.2f}")
print(f"{'vl look':<10} {look_ms:8.3f} ms/frame  (the Host's in-loop step: locate the robot, label the floor)")
print(f"{'look/OpenCV':<10} {look_ms / opencv_ms:8.2f}")
