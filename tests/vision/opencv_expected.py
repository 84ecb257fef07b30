"""Expected vision results for the frames in this directory, from OpenCV.

Run from the repository root after changing a frame:
    pip install opencv-python-headless
    python3 tests/vision/opencv_expected.py
It writes NAME.expected.json and NAME.labels.png (8-connected labels) beside
each NAME.png. tests/vision.rs compares vl's pipeline against them; the
tests themselves need neither Python nor OpenCV.
"""
import json
import pathlib

import cv2
import numpy as np

HERE = pathlib.Path(__file__).parent

for frame in sorted(HERE.glob("*.png")):
    if frame.name.endswith(".labels.png"):
        continue
    bgr = cv2.imread(str(frame), cv2.IMREAD_COLOR)
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    otsu, mask = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    n4, _ = cv2.connectedComponents(mask, connectivity=4)
    fixed, _ = cv2.connectedComponents(
        cv2.threshold(grey, 128, 255, cv2.THRESH_BINARY)[1], connectivity=8
    )
    components = []
    for i in range(1, n):
        hu = cv2.HuMoments(cv2.moments((labels == i).astype(np.uint8), binaryImage=True))
        x, y, w, h, area = (int(v) for v in stats[i])
        components.append(
            {
                "area": area,
                "centroid": [float(centroids[i][0]), float(centroids[i][1])],
                "bbox": [x, y, w, h],
                "hu": [float(v) for v in hu.flatten()],
            }
        )
    assert n < 256, "labels are stored as 8-bit"
    cv2.imwrite(str(frame.with_suffix(".labels.png")), labels.astype(np.uint8))
    expected = {
        "opencv": cv2.__version__,
        "grey_sum": int(grey.astype(np.int64).sum()),
        "otsu_threshold": float(otsu),
        "components_8": components,
        "count_4": n4 - 1,
        "count_fixed_128_bright_8": fixed - 1,
    }
    frame.with_suffix(".expected.json").write_text(json.dumps(expected, indent=1) + "\n")
    print(frame.name, "threshold", otsu, "components", n - 1)
