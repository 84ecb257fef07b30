#!/usr/bin/env bash
# vl petri analyze against TAPAAL's verifypn, side by side on one machine:
# whole processes, taken in turn, RUNS runs each (default 3), medians of
# wall time and peak resident memory (GNU time's %e and %M).
#
#   VERIFYPN=/path/to/verifypn-linux64 bench/petri_vs_verifypn.sh [MODEL ...]
#
# MODEL is a large model of tests/petri-corpus (default: all six). verifypn
# is not part of vl: build 3.1.1 outside the repository (see its README) and
# put it on PATH or in $VERIFYPN. `verifypn -e` explores the state space only;
# `vl petri analyze` also keeps the reachability graph and reads liveness,
# reversibility and deadlocks off it.
set -euo pipefail

here=$(cd "$(dirname "$0")/.." && pwd)
corpus="$here/tests/petri-corpus"
runs=${RUNS:-3}
verifypn=${VERIFYPN:-$(command -v verifypn-linux64 || command -v verifypn || true)}
if [[ -z "$verifypn" || ! -x "$verifypn" ]]; then
  echo "verifypn not found: put it on PATH or set VERIFYPN" >&2
  exit 2
fi
if [[ ! -x /usr/bin/time ]]; then
  echo "GNU time (/usr/bin/time) is needed for peak memory: apt-get install time" >&2
  exit 2
fi
vl="$here/target/release/vl"
(cd "$here" && cargo build --release --quiet)

if [[ $# -eq 0 ]]; then
  set -- $(awk -F, '$3 == "large" { print $1 }' "$corpus/manifest.csv")
fi

# Prints "seconds peak_kb" of one whole run of the command given.
measure() {
  local out
  out=$(mktemp)
  /usr/bin/time -f "%e %M" -o "$out" "$@" >/dev/null 2>&1
  tail -n 1 "$out"
  rm -f "$out"
}

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

printf "%-24s %12s %12s %8s %12s %12s %8s\n" model "verifypn s" "vl s" "time ×" "verifypn MB" "vl MB" "memory ×"
for model in "$@"; do
  pnml=$(awk -F, -v m="$model" '$1 == m { print $4 }' "$corpus/manifest.csv")
  if [[ -z "$pnml" ]]; then
    echo "no model $model in the corpus manifest" >&2
    exit 2
  fi
  file="$corpus/$pnml"
  v_s=() v_kb=() l_s=() l_kb=()
  for ((i = 0; i < runs; i++)); do
    read -r s kb < <(measure "$verifypn" -e "$file")
    v_s+=("$s") v_kb+=("$kb")
    read -r s kb < <(measure "$vl" petri analyze "$file" --json)
    l_s+=("$s") l_kb+=("$kb")
  done
  vs=$(printf "%s\n" "${v_s[@]}" | median)
  vkb=$(printf "%s\n" "${v_kb[@]}" | median)
  ls_=$(printf "%s\n" "${l_s[@]}" | median)
  lkb=$(printf "%s\n" "${l_kb[@]}" | median)
  awk -v m="$model" -v vs="$vs" -v ls="$ls_" -v vkb="$vkb" -v lkb="$lkb" 'BEGIN {
    printf "%-24s %12.2f %12.2f %7.2f× %12.0f %12.0f %7.2f×\n", m, vs, ls, vs / ls, vkb / 1024, lkb / 1024, lkb / vkb
  }'
done
echo "medians of $runs runs each, taken in turn; time ×: verifypn's time over vl's (above 1: vl is faster);"
echo "memory ×: vl's peak resident memory over verifypn's (below 1: vl holds less)"
