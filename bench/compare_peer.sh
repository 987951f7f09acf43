#!/usr/bin/env bash
# ldem against the LAMMPS peer run on the same lattices, interleaved (one LAMMPS run, then one
# ldem run, lattice after lattice, core count after core count, REPS rounds) so that a slow
# spell of the machine hits both codes alike. Prints every run, then per lattice and core
# count the min / median / max of bar updates per second and the ratio of the medians.
#
# usage: LAMMPS_RUN=/path/to/run_lammps.sh bench/compare_peer.sh [REPS=5] [LATTICE:STEPS ...]
#   default lattices: 64x64x64:2000 60x60x1:20000 100x1x41:20000
# Env: LDEM (default build/release/ldem), CORES (default "1 2").
set -euo pipefail
REPS=${1:-5}
shift || true
CASES=("$@")
[ ${#CASES[@]} -gt 0 ] || CASES=(64x64x64:2000 60x60x1:20000 100x1x41:20000)
LDEM=${LDEM:-$(dirname "$0")/../build/release/ldem}
: "${LAMMPS_RUN:?set LAMMPS_RUN to the path of run_lammps.sh (the LAMMPS peer run)}"
CORES=${CORES:-"1 2"}
OUT=$(mktemp)
trap 'rm -f "$OUT"' EXIT
rate() { sed -n 's/.*bar_updates_per_s=\([^ ]*\).*/\1/p'; }
for rep in $(seq "$REPS"); do
  for c in "${CASES[@]}"; do
    IFS=: read -r dims steps <<<"$c"
    IFS=x read -r nx ny nz <<<"$dims"
    for np in $CORES; do
      l=$("$LAMMPS_RUN" "$nx" "$ny" "$nz" "$steps" "$np" 2>&1)
      contended=$(echo "$l" | sed -n 's/.*contended=\([01]\).*/\1/p')
      echo "lammps $dims $np $(echo "$l" | tail -1 | rate) contended=${contended:-?}" | tee -a "$OUT"
      r=$("$LDEM" bench --modules "$nx" "$ny" "$nz" --steps "$steps" --threads "$np" | tail -1)
      echo "ldem $dims $np $(echo "$r" | rate)" | tee -a "$OUT"
    done
  done
done
python3 - "$OUT" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    code, dims, np_, rate = line.split()[:4]
    runs.setdefault((dims, np_), {}).setdefault(code, []).append(float(rate))
print("lattice cores | LAMMPS min/median/max (1e6) | ldem min/median/max (1e6) | ratio of medians")
for (dims, np_), by in runs.items():
    cols = []
    for code in ("lammps", "ldem"):
        v = sorted(by.get(code, [float("nan")]))
        cols.append("%.0f / %.0f / %.0f" % (v[0] / 1e6, statistics.median(v) / 1e6, v[-1] / 1e6))
    ratio = statistics.median(by["ldem"]) / statistics.median(by["lammps"])
    print("%s %s | %s | %s | %.2f" % (dims, np_, cols[0], cols[1], ratio))
PY
