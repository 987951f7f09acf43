#!/usr/bin/env bash
# Median of several `ldem bench` runs: run_bench.sh [REPS] [ldem bench options...]
# Prints every run's last line, then min/median/max of bar_updates_per_s.
set -euo pipefail
REPS=${1:-5}
shift || true
LDEM=${LDEM:-$(dirname "$0")/../build/release/ldem}
vals=()
for _ in $(seq "$REPS"); do
  line=$("$LDEM" bench "$@" | tail -1)
  echo "$line"
  vals+=("$(echo "$line" | sed -n 's/.*bar_updates_per_s=\([^ ]*\).*/\1/p')")
done
printf '%s\n' "${vals[@]}" | sort -g | awk '{v[NR]=$1} END {
  printf "runs=%d min=%.4g median=%.4g max=%.4g bar_updates_per_s\n", NR, v[1], (NR % 2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2), v[NR] }'
