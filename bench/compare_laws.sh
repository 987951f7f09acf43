#!/usr/bin/env bash
# What the fatigue law costs: each case run with the paper's bilinear law and with
# law = "bilinear_fatigue" (A so small that no bar's life runs out, so both runs do the same
# mechanics and the second adds only the cycle count), in alternating rounds so that the
# machine's drift hits both alike. Output: every run, then per case the median of the per-round
# ratios fatigue / bilinear of bar updates per second (summary.json), their min and max.
#
# usage: bench/compare_laws.sh LDEM [ROUNDS=5] [CASE:END ...]
#   default cases: the coarse subcritical plate to 1 s (a Weibull Gf: every row in the per-bar
#   kernel) and the homogeneous FGM plate (a uniform material: the intact fast paths).
#   COUNT_EVERY (default 10): the fatigue law's count_every. THREADS (default 2).
#   Each run without snapshots, analyses or plots, energy rows every 100000 steps.
set -euo pipefail
LDEM=$(realpath "${1:?ldem}")
ROUNDS=${2:-5}
shift 2 || shift $#
CASES=("$@")
SRC=$(cd "$(dirname "$0")/.." && pwd)
[ ${#CASES[@]} -gt 0 ] ||
  CASES=("$SRC/cases/subcritical_fatigue_coarse.toml:1.0" "$SRC/cases/fgm_plate/homogeneous.toml:")
COUNT_EVERY=${COUNT_EVERY:-10}
THREADS=${THREADS:-2}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The case without outputs beyond the logs, its end time replaced when one is given; with `law`
# the fatigue law with a tiny A.
variant() { # case end law out
  /usr/bin/python3 - "$@" <<'EOF'
import re, sys
case, end, law, out = sys.argv[1:5]
text = open(case).read()
text = re.sub(r"(?m)^(energy_every|vtu_every|vtu|plots|crack|fatigue) = .*\n", "", text)
if end:
    text = re.sub(r"(?m)^end = .*$", f"end = {end}", text)
if law:
    text = re.sub(r"(?m)^\[material\]\n", '[material]\nlaw = "bilinear_fatigue"\n', text, count=1)
    text += f"\n[fatigue]\nA = 1e-30\nm = 4.0\ncount_every = {law}\n"
if "[output]" in text:
    text = text.replace("[output]\n", "[output]\nenergy_every = 100000\nvtu = false\nplots = false\n", 1)
else:
    text += "\n[output]\nenergy_every = 100000\nvtu = false\nplots = false\n"
open(out, "w").write(text)
EOF
}
rate() { sed -n 's/.*"bar_updates_per_s": \([^,]*\),.*/\1/p' "$1/summary.json"; }

for spec in "${CASES[@]}"; do
  case_file=${spec%%:*} end=${spec#*:}
  name=$(basename "$case_file" .toml)
  variant "$case_file" "$end" "" "$WORK/$name-bilinear.toml"
  variant "$case_file" "$end" "$COUNT_EVERY" "$WORK/$name-fatigue.toml"
  ratios=()
  for r in $(seq "$ROUNDS"); do
    for law in bilinear fatigue; do
      rm -rf "$WORK/out"
      "$LDEM" run "$WORK/$name-$law.toml" --out "$WORK/out" --threads "$THREADS" --no-plot \
        >/dev/null 2>&1
      eval "$law=$(rate "$WORK/out")"
    done
    ratio=$(/usr/bin/python3 -c "print(f'{$fatigue / $bilinear:.3f}')")
    echo "$name round $r: bilinear $bilinear fatigue $fatigue ratio $ratio"
    ratios+=("$ratio")
  done
  printf '%s\n' "${ratios[@]}" | /usr/bin/python3 -c "
import statistics, sys
v = [float(x) for x in sys.stdin]
print(f'$name: fatigue / bilinear median {statistics.median(v):.3f} (min {min(v):.3f}, max {max(v):.3f}, $ROUNDS rounds, count_every $COUNT_EVERY, $THREADS threads)')"
done
