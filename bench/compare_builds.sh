#!/usr/bin/env bash
# Two builds of ldem against each other, in alternating rounds (the old build, then the new, on
# each lattice and thread count in turn), so that the machine's drift hits both alike. Each
# round gives a ratio new / old of bar updates per second; the script prints every run, then per
# benchmark the median of the per-round ratios with their min and max, and the medians of both
# rates.
#
# usage: bench/compare_builds.sh OLD_LDEM NEW_LDEM [ROUNDS=7] [LATTICE:STEPS ...]
#   default lattices: 64x64x64:600 60x60x1:6000 100x1x41:6000, each on 1 and 2 threads
#   (THREADS="1 2"); then each case of PLATES (default the homogeneous FGM plate; PLATES=""
#   skips them) without output: the case with its crack analysis and plots off, energy rows
#   every 100000 steps and no snapshots, on 2 threads, its rate from summary.json.
set -euo pipefail
OLD=${1:?old ldem}
NEW=${2:?new ldem}
ROUNDS=${3:-7}
shift 3 || shift $#
CASES=("$@")
[ ${#CASES[@]} -gt 0 ] || CASES=(64x64x64:600 60x60x1:6000 100x1x41:6000)
THREADS=${THREADS:-"1 2"}
PLATES=${PLATES-cases/fgm_plate/homogeneous.toml}
SRC=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
OUT=$WORK/runs.txt
rate() { sed -n 's/.*bar_updates_per_s=\([^ ]*\).*/\1/p'; }
for p in $PLATES; do
  sed -e 's/^crack = true/crack = false/' "$SRC/$p" >"$WORK/$(basename "$p")"
  printf '\n[output]\nenergy_every = 100000\nvtu = false\nplots = false\n' >>"$WORK/$(basename "$p")"
done
for round in $(seq "$ROUNDS"); do
  for c in "${CASES[@]}"; do
    IFS=: read -r dims steps <<<"$c"
    IFS=x read -r nx ny nz <<<"$dims"
    for t in $THREADS; do
      for which in old new; do
        bin=$OLD
        [ "$which" = new ] && bin=$NEW
        r=$("$bin" bench --modules "$nx" "$ny" "$nz" --steps "$steps" --threads "$t" | tail -1 | rate)
        echo "$round ${dims}_t$t $which $r" | tee -a "$OUT"
      done
    done
  done
  for p in $PLATES; do
    name=$(basename "$p" .toml)
    for which in old new; do
      bin=$OLD
      [ "$which" = new ] && bin=$NEW
      rm -rf "$WORK/plate"
      "$bin" run "$WORK/$name.toml" --out "$WORK/plate" --threads 2 --no-plot >/dev/null 2>&1
      r=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["bar_updates_per_s"])' \
        "$WORK/plate/summary.json")
      echo "$round ${name}_t2 $which $r" | tee -a "$OUT"
    done
  done
done
python3 - "$OUT" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    rnd, bench, which, r = line.split()
    runs.setdefault(bench, {}).setdefault(rnd, {})[which] = float(r)
print("benchmark | per-round new/old: median (min to max) | median old | median new (1e6/s)")
for bench, rounds in runs.items():
    ratios = [v["new"] / v["old"] for v in rounds.values() if "old" in v and "new" in v]
    old = statistics.median(v["old"] for v in rounds.values())
    new = statistics.median(v["new"] for v in rounds.values())
    print("%s | %.3f (%.3f to %.3f) | %.0f | %.0f" % (bench, statistics.median(ratios),
          min(ratios), max(ratios), old / 1e6, new / 1e6))
PY
