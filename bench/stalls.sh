#!/usr/bin/env bash
# How far the robot goes once the lab machine stalls, at each baud: the
# Khepera emulator driven flat out at a wall, a box and a virtual polygon,
# the Host and its serial guard SIGSTOPped at random moments of the
# approach (quiet, then with 2 × cores busy programs at the Host's
# priority). Per baud: runs, contacts, how far the robot went after the
# Host's last word against the leash it had (what the safety layer
# budgeted: the hold and the braking at the profile's acceleration), and
# the speed it had. CI runs 4 per baud and scene (tests/stalls.rs).
#   bench/stalls.sh [RUNS_PER_BAUD_AND_SCENE]   (default 10: 180 stalls)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-10}"
log=$(mktemp)
STALL_RUNS="$runs" cargo test --release --test alone stalls:: -- --nocapture --test-threads 1 2>&1 |
  tee "$log" | grep -E "^stall|test result|panicked" >&2 || true
python3 - "$log" <<'PY'
import re, sys
rows = {}
for line in open(sys.argv[1]):
    if not line.startswith("stall baud="):
        continue
    f = dict(kv.split("=", 1) for kv in line.split()[1:])
    key = (int(f["baud"]), "starved" if f["busy"] != "0" else "quiet")
    r = rows.setdefault(key, {"runs": 0, "contacts": 0, "into": 0.0, "over": 0.0,
                              "after": 0.0, "leash": 0.0, "speed": 0.0, "stops": 0})
    r["runs"] += 1
    r["contacts"] += int(f["contacts"])
    r["into"] = max(r["into"], float(f["into_polygon_mm"]))
    after, leash, speed = float(f["after_mm"]), float(f["leash_mm"]), float(f["speed_mm_s"])
    r["over"] = max(r["over"], after - leash)
    if after > r["after"]:
        r["after"], r["leash"], r["speed"] = after, leash, speed
header = ["baud", "machine", "runs", "contacts", "into polygon mm", "longest stop mm",
          "its leash mm", "at mm/s", "most past leash mm"]
table = [header]
for (baud, machine), r in sorted(rows.items()):
    table.append([str(baud), machine, str(r["runs"]), str(r["contacts"]), f"{r['into']:.1f}",
                  f"{r['after']:.1f}", f"{r['leash']:.1f}", f"{r['speed']:.0f}", f"{r['over']:.1f}"])
widths = [max(len(row[i]) for row in table) for i in range(len(header))]
for row in table:
    print("  ".join(cell.rjust(w) if i >= 2 else cell.ljust(w) for i, (cell, w) in enumerate(zip(row, widths))))
PY
