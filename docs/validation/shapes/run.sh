#!/usr/bin/env bash
# The studies of docs/validation/shapes.md. usage: run.sh STUDY [LDEM]
#   specimens  the four shipped specimens (cases/specimens/), each into results/shapes/<case>
#   tension    the same concrete pulled apart in a plain plate: its tensile strength, the
#              reference of the Brazilian disc's splitting strength
#   kirsch     the plate with a hole against Kirsch (the unit test, its table printed)
# Then plot.py makes the figures of docs/validation/shapes/ from results/shapes/.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../../.." && pwd)
LDEM=${2:-$ROOT/build/release/ldem}
OUT=$ROOT/results/shapes
mkdir -p "$OUT"
case ${1:-} in
specimens)
  for c in brazilian_disc plate_with_hole notched_beam rock_cylinder; do
    /usr/bin/time -f "$c: %e s" "$LDEM" run "$ROOT/cases/specimens/$c.toml" --out "$OUT/$c" --force >/dev/null
  done
  ;;
tension)
  # 50 x 100 mm, L = 1 mm, plane strain; the top face pulled at 10 mm/s (0.2 ms ramp), the
  # bottom on rollers, damping as the disc's; the centres of the layers along both faces driven
  # with the homogeneous field (docs/model.md, section 2: the remedy for the soft first layer),
  # so that the plate does not part at its first layer; the pull is the two reactions' sum.
  cat >"$OUT/tension.toml" <<'CASE'
[case]
title = "Direct tension: the disc's concrete, 50 mm x 100 mm"
[lattice]
modules = [50, 1, 100]
L = 0.001
plane_strain = "y"
[material]
E = 30.0e9
rho = 2400.0
Gf = 100.0
e_p = 1.0e-4
[[node_set]]
name = "bottom"
face = "z-"
[[node_set]]
name = "top"
face = "z+"
[[node_set]]
name = "top_centres"
face_centres = "z+"
[[node_set]]
name = "bottom_centres"
face_centres = "z-"
[[fixed]]
set = "bottom"
dofs = "z"
[[velocity]]
set = "bottom_centres"
dofs = "z"
value = [0.0, 0.0, 0.00005]
ramp = 2.0e-4
[[velocity]]
set = "top"
dofs = "z"
value = [0.0, 0.0, 0.01]
ramp = 2.0e-4
[[velocity]]
set = "top_centres"
dofs = "z"
value = [0.0, 0.0, 0.00995]
ramp = 2.0e-4
[time]
end = 6.0e-3
damping = 2000.0
[output]
energy_every = 100
[[probe]]
name = "load"
kind = "reaction"
set = "top"
component = "z"
[[probe]]
name = "load_centres"
kind = "reaction"
set = "top_centres"
component = "z"
CASE
  "$LDEM" run "$OUT/tension.toml" --out "$OUT/tension" --force >/dev/null
  ;;
kirsch)
  LDEM_KIRSCH_PROFILE=1 "$ROOT/build/release/tests/ldem_tests" \
    --gtest_filter=ShapedBody.APlateWithAHoleShowsKirschsStressConcentration | grep "^R ="
  ;;
*)
  sed -n '2,7p' "$0"
  exit 2
  ;;
esac
