#!/usr/bin/env bash
# Whether a user's controller disturbs the lab's other clients: one
# simulated Host, an observer (Python's websockets, outside vl) timing the
# gaps between the feedback it gets during each run, and runs alternated
# ROUNDS times — a navigation run (no module) and a run of the C example
# controller (examples/controllers/go_to_goal.c, built by clang). Prints
# each run's p50/p99 gap and the ratio of the medians of the p99s
# (issue 58 asks at most 1.10).
#   bench/controller_observers.sh [ROUNDS]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-3}"
cargo build --release --quiet
work=$(mktemp -d)
clang --target=wasm32 -nostdlib -O2 -Wl,--no-entry -Wl,--export-dynamic \
  -o "$work/go_to_goal.wasm" examples/controllers/go_to_goal.c
port=$((20000 + RANDOM % 20000))
./target/release/vl host --listen "127.0.0.1:$port" --no-record >"$work/host.log" 2>&1 &
host=$!
trap 'kill $host 2>/dev/null; rm -rf "$work"' EXIT
sleep 3
url="ws://127.0.0.1:$port/"
for round in $(seq "$rounds"); do
  for kind in navigation controller; do
    python3 bench/observe_feedback.py "$url" 40 >"$work/$kind-$round.json" &
    observer=$!
    sleep 1
    case $kind in
      navigation) ./target/release/vl guest --connect "$url" --headless --json \
        --experiment navigation >/dev/null ;;
      controller) ./target/release/vl guest --connect "$url" --headless --json \
        --experiment your-controller --controller "$work/go_to_goal.wasm" >/dev/null ;;
    esac
    wait $observer
    echo "$kind $round $(cat "$work/$kind-$round.json")"
    sleep 6 # the drive back to the start
  done
done | tee "$work/all.txt"
python3 - "$work/all.txt" <<'PY'
import json, statistics, sys
p99 = {}
for line in open(sys.argv[1]):
    kind, _, report = line.split(" ", 2)
    p99.setdefault(kind, []).append(json.loads(report)["p99_ms"])
ratio = statistics.median(p99["controller"]) / statistics.median(p99["navigation"])
print(f"observer feedback gap p99, median: navigation {statistics.median(p99['navigation']):.2f} ms, "
      f"controller {statistics.median(p99['controller']):.2f} ms, ratio {ratio:.3f}")
PY
