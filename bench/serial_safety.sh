#!/usr/bin/env bash
# The safety layer on a real robot's serial timing, the whole sweep: every
# baud a Khepera offers (9600–115200) × every scene (walls, a box, a
# 256-vertex virtual polygon) × every way of asking for full speed (paced,
# a burst at the rate limit, a flood above it), each ending in an emergency
# stop. CI runs a cross-section of it (tests/serial_safety.rs).
#   bench/serial_safety.sh
set -euo pipefail
cd "$(dirname "$0")/.."
SERIAL_SWEEP=all cargo test --release --test tests serial_safety:: -- --nocapture 2>&1 |
  grep -E "baud|test result|panicked|failures"
