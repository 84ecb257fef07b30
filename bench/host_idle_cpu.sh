#!/usr/bin/env bash
# The share of a core a simulated Host uses at idle (no client) with the
# noisy 640x480 camera at 15 fps, as /proc counts its CPU time over a
# window. Give other vl binaries to compare in the same run, e.g. one built
# from an earlier commit:
#   bench/host_idle_cpu.sh target/release/vl /tmp/prev-target/release/vl
# OPTICS (default noisy) and SECONDS (default 20) change the set-up.
set -euo pipefail
cd "$(dirname "$0")/.."
OPTICS=${OPTICS:-noisy}
SECONDS_MEASURED=${SECONDS:-20}
[ $# -gt 0 ] || set -- target/release/vl
[ -x target/release/vl ] || cargo build --release --quiet
ticks=$(getconf CLK_TCK)
printf '%-40s %8s %s\n' "binary" "core %" "optics"
for vl in "$@"; do
  "$vl" host --listen 127.0.0.1:0 --optics "$OPTICS" > /tmp/vl-idle-host.log 2>&1 &
  pid=$!
  sleep 5 # calibration and the first look
  cpu() { awk '{print $14 + $15}' "/proc/$pid/stat"; }
  before=$(cpu)
  sleep "$SECONDS_MEASURED"
  after=$(cpu)
  kill "$pid"; wait "$pid" 2>/dev/null || true
  share=$(awk -v a="$before" -v b="$after" -v t="$ticks" -v s="$SECONDS_MEASURED" \
    'BEGIN { printf "%.1f", 100 * (b - a) / t / s }')
  printf '%-40s %8s %s\n' "$vl" "$share" "$OPTICS"
done
