#!/usr/bin/env bash
# What the leash costs a navigation run: the simulated lab (the same
# follower, safety layer and simulated Khepera as `vl host`) on every
# shipped arena, `RUNS` runs each, by this checkout and by the last commit
# before the leash (its robot driven by speeds, which a stalled Host cannot
# stop), built side by side in target/bench-base. Per arena: mean time to
# the goal each way and their ratio (target: at most 1.05).
#   bench/leash_navigation.sh [RUNS] [BASE_REF]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-3}"
base="${2:-$(git log --format=%H -1 --grep='^A leash on every drive command')^}"
cargo build --release --quiet
if [ ! -d target/bench-base ]; then git worktree add --detach target/bench-base "$base" >/dev/null; fi
git -C target/bench-base checkout --quiet --detach "$base"
(cd target/bench-base && CARGO_TARGET_DIR=../bench-base-target cargo build --release --quiet)
now=$(mktemp) before=$(mktemp)
echo "leashed: this checkout; unleashed: $(git rev-parse --short "$base")" >&2
./target/release/vl experiment run navigation --arena all --runs "$runs" --json >"$now"
target/bench-base-target/release/vl experiment run navigation --arena all --runs "$runs" --json >"$before"
python3 - "$now" "$before" <<'PY'
import json, sys
def times(path):
    out = {}
    for r in json.load(open(path))["runs"]:
        out.setdefault(r["arena"], []).append((r["completion_s"], r["reached_goal"]))
    return out
now, before = times(sys.argv[1]), times(sys.argv[2])
rows = [["arena", "unleashed s", "leashed s", "ratio", "all reached"]]
ratios = []
for arena in sorted(now):
    a = sum(t for t, _ in before[arena]) / len(before[arena])
    b = sum(t for t, _ in now[arena]) / len(now[arena])
    ratios.append(b / a)
    reached = all(ok for _, ok in now[arena] + before[arena])
    rows.append([arena, f"{a:.2f}", f"{b:.2f}", f"{b / a:.3f}", "yes" if reached else "NO"])
rows.append(["all", "", "", f"{sum(ratios) / len(ratios):.3f}", ""])
widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
for r in rows:
    print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))))
PY
