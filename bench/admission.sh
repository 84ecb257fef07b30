#!/usr/bin/env bash
# Admission under bare connects and the relay's memory with observers that
# never read, for as long as asked (default three minutes):
#   bench/admission.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
ADMISSION_SOAK_S=${1:-180} cargo test --release --test tests admission:: -- --nocapture 2>&1 |
  grep -E "bare connections|the relay|test result|panicked"
