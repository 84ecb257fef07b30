#!/usr/bin/env bash
# vl petri states and analyze against TAPAAL's verifypn, side by side on one machine:
# whole processes, taken in turn, RUNS runs each (default 3), medians of
# wall time and peak resident memory (GNU time's %e and %M).
#
#   VERIFYPN=/path/to/verifypn-linux64 bench/petri_vs_verifypn.sh [MODEL ...]
#
# MODEL is a large model of assets/petri-corpus (default: all six). verifypn
# is not part of vl: build 3.1.1 outside the repository (see its README) and
# put it on PATH or in $VERIFYPN. `verifypn -e` explores the state space only;
# `vl petri states` does the same (and checks its count against verifypn's);
# `vl petri analyze` also reads liveness, reversibility and deadlocks, by
# Tarjan's algorithm inside a depth-first search, keeping no edge.
set -euo pipefail

here=$(cd "$(dirname "$0")/.." && pwd)
corpus="$here/assets/petri-corpus"
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

# Runs the command given once; prints "seconds peak_kb" and leaves its
# standard output in $last_out.
last_out=$(mktemp)
trap 'rm -f "$last_out"' EXIT
measure() {
  local times
  times=$(mktemp)
  /usr/bin/time -f "%e %M" -o "$times" "$@" >"$last_out" 2>/dev/null
  tail -n 1 "$times"
  rm -f "$times"
}

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

printf "%-22s %10s %10s %11s %9s %6s %10s %6s %11s %9s %10s\n" model "states" "same?" "verifypn s" "states s" "×" "analyze s" "×" "verifypn MB" "states MB" "analyze MB"
for model in "$@"; do
  pnml=$(awk -F, -v m="$model" '$1 == m { print $4 }' "$corpus/manifest.csv")
  if [[ -z "$pnml" ]]; then
    echo "no model $model in the corpus manifest" >&2
    exit 2
  fi
  file="$corpus/$pnml"
  v_s=() v_kb=() s_s=() s_kb=() a_s=() a_kb=()
  for ((i = 0; i < runs; i++)); do
    read -r s kb < <(measure "$verifypn" -e "$file")
    v_s+=("$s") v_kb+=("$kb")
    v_states=$(awk '/^STATE_SPACE STATES/ { print $3 }' "$last_out")
    read -r s kb < <(measure "$vl" petri states "$file" --json)
    s_s+=("$s") s_kb+=("$kb")
    l_states=$(sed -n 's/^  "states": \([0-9]*\),$/\1/p' "$last_out")
    read -r s kb < <(measure "$vl" petri analyze "$file" --json)
    a_s+=("$s") a_kb+=("$kb")
  done
  same=$([[ "$v_states" == "$l_states" ]] && echo yes || echo "NO: $l_states")
  m() { printf "%s\n" "$@" | median; }
  awk -v m="$model" -v n="$v_states" -v same="$same" \
    -v vs="$(m "${v_s[@]}")" -v ss="$(m "${s_s[@]}")" -v as="$(m "${a_s[@]}")" \
    -v vkb="$(m "${v_kb[@]}")" -v skb="$(m "${s_kb[@]}")" -v akb="$(m "${a_kb[@]}")" 'BEGIN {
    printf "%-22s %10d %10s %11.2f %9.2f %5.2f× %10.2f %5.2f× %11.0f %9.0f %10.0f\n", m, n, same, vs, ss, vs / ss, as, vs / as, vkb / 1024, skb / 1024, akb / 1024
  }'
done
echo "medians of $runs runs each, taken in turn; same?: vl petri states counts what verifypn -e does;"
echo "×: verifypn's time over vl's (above 1: vl is faster); MB: peak resident memory"
