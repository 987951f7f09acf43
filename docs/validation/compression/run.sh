#!/usr/bin/env bash
# The study of docs/validation/compression.md: the rock cylinder of cases/specimens/ in uniaxial
# compression three ways, each to 0.2 mm of travel (about 4 min each on 2 cores):
#   mu03  between platens with friction 0.3 (cases/specimens/rock_cylinder_platens.toml);
#   mu0   the same platens without friction;
#   held  its end faces held and driven (cases/specimens/rock_cylinder.toml, its probes added).
# Into results/compression/; then plot.py draws docs/validation/compression/*.png and prints the
# table. usage: run.sh [LDEM]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../../.." && pwd)
LDEM=${1:-$ROOT/build/release/ldem}
OUT=$ROOT/results/compression
mkdir -p "$OUT"
PLATENS=$ROOT/cases/specimens/rock_cylinder_platens.toml
run() { /usr/bin/time -f "$2: %e s" "$LDEM" run "$1" --out "$OUT/$2" --force --no-plot >/dev/null; }
run "$PLATENS" mu03
sed -e 's/^friction = 0.3/friction = 0.0/' \
  -e 's/^title = .*/title = "Rock cylinder between frictionless platens: D = 50 mm, H = 100 mm"/' \
  "$PLATENS" >"$OUT/mu0.toml"
[ "$(grep -c '^friction = 0.0' "$OUT/mu0.toml")" = 2 ] ||
  { echo "run.sh: the platens' friction is not where it was" >&2; exit 1; }
run "$OUT/mu0.toml" mu0
# The held ends with the platen case's gauges (its load probe is already a reaction on the head)
# and the head's travel.
{ cat "$ROOT/cases/specimens/rock_cylinder.toml"; sed -n '/^name = "axial_strain"/,$p' "$PLATENS" |
  sed '1s/^/\n[[probe]]\n/'
  printf '\n[[probe]]\nname = "travel"\nkind = "displacement"\nset = "head"\ncomponent = "z"\n'; } \
  >"$OUT/held.toml"
run "$OUT/held.toml" held
