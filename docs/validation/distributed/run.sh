#!/usr/bin/env bash
# Every shipped case (full length; the long fatigue plate only on its coarse lattice) run on one
# process and under mpirun on 2, 3 and 4, each folder compared with the one-process folder by
# tests/compare_runs.py. usage (from the source folder, after the release build):
#   bash docs/validation/distributed/run.sh [OUT_DIR]
set -uo pipefail
LDEM=${LDEM:-build/release/ldem}
OUT=${1:-results/distributed}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$OUT"
fails=0
for c in cases/tutorial/notched_plate.toml cases/fgm_plate/homogeneous.toml \
         cases/fgm_plate/graded_toughness.toml cases/fgm_plate/graded_modulus_toughness.toml \
         cases/subcritical_fatigue_coarse.toml; do
  n=$(basename "$c" .toml)
  rm -rf "$OUT/$n"
  start=$(date +%s.%N)
  "$LDEM" run "$c" --out "$OUT/$n/1" --no-plot --threads 1 >/dev/null 2>&1
  echo "$n: 1 process, $(printf '%.0f' "$(echo "$(date +%s.%N) - $start" | bc)") s"
  for np in 2 3 4; do
    mpirun -np "$np" --oversubscribe "$LDEM" run "$c" --out "$OUT/$n/$np" --no-plot --threads 1 \
      >/dev/null 2>&1
    /usr/bin/python3 tests/compare_runs.py "$OUT/$n/1" "$OUT/$n/$np" || fails=$((fails + 1))
  done
done
exit $fails
