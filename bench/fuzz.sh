#!/usr/bin/env bash
# The seeded socket fuzzer of tests/fuzz.rs, for as long as asked:
#   bench/fuzz.sh [MESSAGES] [SEEDS]
# runs MESSAGES messages (default 1,000,000) for each seed 1..SEEDS
# (default 1) and stops at the first seed that leaves the Host broken.
set -euo pipefail
cd "$(dirname "$0")/.."
messages=${1:-1000000}
seeds=${2:-1}
for seed in $(seq 1 "$seeds"); do
  echo "seed $seed, $messages messages"
  FUZZ_MESSAGES=$messages FUZZ_SEED=$seed \
    cargo test --release --test tests fuzz:: -- --nocapture 2>&1 | grep -E "fuzzed|test result|panicked"
done
