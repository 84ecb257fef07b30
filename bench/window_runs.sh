#!/usr/bin/env bash
# Window runs in a row on a Host with noisy optics, an observer's window
# beside (issue 25: none may end with the camera losing the robot):
#   bench/window_runs.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
WINDOW_RUNS=${1:-20} cargo test --release --test tests guest_window::window_runs -- --nocapture 2>&1 |
  grep -E "window run|test result|panicked"
