#!/usr/bin/env bash
# The study of docs/validation/beam.md: the notched beam of cases/specimens/notched_beam_cmod.toml
# under CMOD control at L = 2 mm (the shipped case, to a CMOD of 0.6 mm: about 3 min on 2 cores)
# and L = 1 mm (the same beam, notch and supports with modules half as large: 440 x 1 x 100, to
# 0.3 mm: about 9 min), and the deflection-controlled beam of
# cases/specimens/notched_beam.toml beside them. Into
# results/beam/; then plot.py draws docs/validation/beam/*.png and prints the table.
# usage: run.sh [LDEM]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../../.." && pwd)
LDEM=${1:-$ROOT/build/release/ldem}
OUT=$ROOT/results/beam
mkdir -p "$OUT"
CASE=$ROOT/cases/specimens/notched_beam_cmod.toml
run() { /usr/bin/time -f "$2: %e s" "$LDEM" run "$1" --out "$OUT/$2" --force --no-plot >/dev/null; }
run "$CASE" cmod_L2
# L = 1 mm: twice the modules along x and z (the notch, supports, load line and gauge are given
# in metres and land on the same places), to 0.06 s (0.3 mm), a row every 2000 steps.
sed -e 's/^modules = \[220, 1, 50\].*/modules = [440, 1, 100]/' -e 's/^L = 0.002/L = 0.001/' \
  -e 's/^end = 0.12 .*/end = 0.06/' "$CASE" >"$OUT/cmod_L1.toml"
grep -q '^end = 0.06' "$OUT/cmod_L1.toml" && grep -q '^L = 0.001' "$OUT/cmod_L1.toml" ||
  { echo "run.sh: the case's L or end is not where it was" >&2; exit 1; }
run "$OUT/cmod_L1.toml" cmod_L1
run "$ROOT/cases/specimens/notched_beam.toml" deflection_L2
