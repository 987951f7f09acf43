#!/usr/bin/env bash
# Every shipped case (full length; the long fatigue plate only on its coarse lattice) run on one
# process and under mpirun on 2, 3 and 4, each folder compared with the one-process folder by
# tests/compare_runs.py; then two of them made 4 modules thick (with random fields on the
# tutorial plate) on boxes over y and z: 2 x 1, 4 x 1, 3 x 1 and 2 x 2 processes; and the
# memory of each process on an 80^3 cube.
# usage (from the source folder, after the release build):
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
# Thick plates: the notch or the pre-crack through the thickness; the tutorial plate with a
# random modulus per bar and a correlated random density.
sed -e 's/^modules = .*/modules = [40, 4, 20]/; s/^edge2 = .*/edge2 = [0.0, 0.022, 0.0]/' \
  -e 's/^E = .*/E = { type = "weibull", mean = 35.0e9, cv = 0.1, seed = 3 }/' \
  -e 's/^rho = .*/rho = { type = "weibull", mean = 2400.0, cv = 0.05, seed = 4, correlation_length = 0.01 }/' \
  cases/tutorial/notched_plate.toml >"$OUT/thick_notched_plate.toml"
sed -e 's/^modules = .*/modules = [60, 4, 60]/; s/^edge2 = .*/edge2 = [0.0, 2.2e-4, 0.0]/' \
  cases/fgm_plate/graded_modulus_toughness.toml >"$OUT/thick_graded_modulus_toughness.toml"
for n in thick_notched_plate thick_graded_modulus_toughness; do
  rm -rf "${OUT:?}/$n"
  start=$(date +%s.%N)
  "$LDEM" run "$OUT/$n.toml" --out "$OUT/$n/1" --no-plot --threads 1 >/dev/null 2>&1
  echo "$n: 1 process, $(printf '%.0f' "$(echo "$(date +%s.%N) - $start" | bc)") s"
  for grid in "2 1" "4 1" "3 1" "2 2"; do
    read -r py pz <<<"$grid"
    mpirun -np $((py * pz)) --oversubscribe "$LDEM" run "$OUT/$n.toml" --out "$OUT/$n/${py}x$pz" \
      --no-plot --threads 1 --process-grid "$py" "$pz" >/dev/null 2>&1
    /usr/bin/python3 tests/compare_runs.py "$OUT/$n/1" "$OUT/$n/${py}x$pz" || fails=$((fails + 1))
  done
done
# Memory: an 80^3 cube (7.2 million bars) with a random E and Gf per bar, on one process and
# on two; the peak resident memory of each process (Debian package `time`), the folders
# compared.
sed -e 's/^modules = .*/modules = [80, 80, 80]/' -e '/^plane_strain/d' \
  -e 's/^edge2 = .*/edge2 = [0.0, 0.41, 0.0]/' -e 's/^end = .*/end = 2.0e-5/' \
  -e 's/^E = .*/E = { type = "weibull", mean = 35.0e9, cv = 0.1, seed = 3 }/' \
  -e 's/^Gf = .*/Gf = { type = "weibull", mean = 12.0, cv = 0.1, seed = 5 }/' \
  -e 's/^energy_every = .*/energy_every = 50\nvtu = false/' \
  cases/tutorial/notched_plate.toml >"$OUT/cube80.toml"
rm -rf "${OUT:?}/cube80"
/usr/bin/time -f "cube80, 1 process: peak %M kB, %e s" \
  "$LDEM" run "$OUT/cube80.toml" --out "$OUT/cube80/1" --no-plot --threads 1 2>&1 | grep peak
mpirun -np 2 --oversubscribe sh -c 'exec /usr/bin/time -o "$0.$OMPI_COMM_WORLD_RANK" \
  -f "cube80, rank $OMPI_COMM_WORLD_RANK of 2: peak %M kB, %e s" "$@"' "$OUT/cube80-time" \
  "$LDEM" run "$OUT/cube80.toml" --out "$OUT/cube80/2" --no-plot --threads 1 >/dev/null 2>&1
cat "$OUT/cube80-time.0" "$OUT/cube80-time.1"
/usr/bin/python3 tests/compare_runs.py "$OUT/cube80/1" "$OUT/cube80/2" || fails=$((fails + 1))
exit $fails
