"""vl's lens calibration against OpenCV's calibrateCamera on the same images.

    pip install opencv-python-headless
    cargo build --release
    python3 bench/calibrate_vs_opencv.py

Renders a dot target through five lenses of known distortion (`vl sim
render --target`, the noisy sensor, the lens centred on the image), then
calibrates each picture twice: `vl camera calibrate --image` (DLT, then map
and lens by Levenberg-Marquardt), and OpenCV (findCirclesGrid, then
calibrateCamera on the one view with the principal point at the centre,
the focal length at the image's width -- the unit vl measures radii in, so
k1 and k2 mean the same -- no tangential terms and k3 = 0). Prints both
reprojection errors and both lenses against the truth, side by side.
"""
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

VL = os.environ.get("VL", "target/release/vl")
LENSES = [(-0.12, 0.08), (-0.18, 0.12), (-0.25, 0.15), (-0.30, 0.20), (-0.22, 0.10)]
# DotTarget::spread_over(800, 600): 13 x 10 dots of 16 mm.
COLS, ROWS, RADIUS = 13, 10, 16.0
FIRST = (0.03 * 800 + RADIUS, 0.03 * 600 + RADIUS)
SPACING = ((800 - 2 * FIRST[0]) / (COLS - 1), (600 - 2 * FIRST[1]) / (ROWS - 1))
TARGET = {
    "cols": COLS,
    "rows": ROWS,
    "first_mm": {"x_mm": FIRST[0], "y_mm": FIRST[1]},
    "spacing_mm": list(SPACING),
    "radius_mm": RADIUS,
}


def vl(*args):
    out = subprocess.run([VL, *args], check=True, capture_output=True, text=True)
    return out.stdout


def floor_points():
    """The dots in vl's reading order: top row (largest y) first, left to right."""
    return np.array(
        [
            [FIRST[0] + i * SPACING[0], FIRST[1] + j * SPACING[1], 0.0]
            for j in reversed(range(ROWS))
            for i in range(COLS)
        ],
        dtype=np.float32,
    )


def opencv(path):
    grey = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    h, w = grey.shape
    found, centres = cv2.findCirclesGrid(grey, (COLS, ROWS), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    if not found:
        return None
    # The same reading order as vl's: rows from the top, each left to right.
    pts = sorted(centres.reshape(-1, 2).tolist(), key=lambda p: p[1])
    rows = [sorted(pts[k : k + COLS]) for k in range(0, len(pts), COLS)]
    image_points = np.array([p for row in rows for p in row], dtype=np.float32)
    camera = np.array([[w, 0, w / 2], [0, w, h / 2], [0, 0, 1]], dtype=np.float64)
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_PRINCIPAL_POINT
        | cv2.CALIB_FIX_FOCAL_LENGTH
        | cv2.CALIB_ZERO_TANGENT_DIST
        | cv2.CALIB_FIX_K3
    )
    rms, _, dist, _, _ = cv2.calibrateCamera(
        [floor_points()], [image_points], (w, h), camera, np.zeros(5), flags=flags
    )
    return rms, dist.ravel()[0], dist.ravel()[1]


def main():
    cv2.setNumThreads(1)
    with tempfile.TemporaryDirectory() as tmp:
        target = os.path.join(tmp, "target.json")
        with open(target, "w") as f:
            json.dump(TARGET, f)
        print(f"{'lens k1, k2':>16} | {'vl rms px':>9} {'vl k1':>8} {'vl k2':>8} | "
              f"{'OpenCV rms px':>13} {'cv k1':>8} {'cv k2':>8} | vl/OpenCV")
        ratios = []
        for n, (k1, k2) in enumerate(LENSES):
            image = os.path.join(tmp, f"lens{n}.png")
            vl("sim", "render", "--target", target, "--optics", "noisy", "--seed", str(n + 1),
               "--lens-offset=0,0", f"--lens={k1},{k2}", "--width", "640", "-o", image)
            ours = json.loads(vl("camera", "calibrate", "--image", image, "--target", target, "--json"))
            rms = ours["reprojection"]["rms_px"]
            lens = ours["camera"].get("distortion", {"k1": 0.0, "k2": 0.0})
            theirs = opencv(image)
            if theirs is None:
                print(f"{k1:+.2f}, {k2:+.2f} | OpenCV found no grid")
                continue
            ratio = rms / theirs[0]
            ratios.append(ratio)
            print(f"{k1:+7.2f}, {k2:+6.2f} | {rms:9.3f} {lens['k1']:+8.4f} {lens['k2']:+8.4f} | "
                  f"{theirs[0]:13.3f} {theirs[1]:+8.4f} {theirs[2]:+8.4f} | {ratio:.2f}")
        if ratios:
            print(f"worst vl/OpenCV reprojection ratio: {max(ratios):.2f}")
            sys.exit(0 if max(ratios) <= 1.2 else 1)


if __name__ == "__main__":
    main()
