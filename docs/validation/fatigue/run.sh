#!/usr/bin/env bash
# The studies of docs/validation/fatigue.md. Usage, from the repository's root after the
# release build:
#   bash docs/validation/fatigue/run.sh seeds      # the paper's plate, fatigue law, seeds 1-3
#   bash docs/validation/fatigue/run.sh seeds_coarse # the same on the coarse lattice
#   bash docs/validation/fatigue/run.sh paper      # the coarse plate with the paper's law alone
#   bash docs/validation/fatigue/run.sh exponents  # the LEFM plate with m = 3, 6, 10
#   bash docs/validation/fatigue/run.sh undamped   # the LEFM plate (m = 6) without damping
#   bash docs/validation/fatigue/run.sh homogeneous # the LEFM plate, every bar with a life
#   bash docs/validation/fatigue/run.sh mesh       # the LEFM plate (m = 6) with L halved
#   bash docs/validation/fatigue/run.sh frequency  # the LEFM plate (m = 6) at 100 Hz
#   bash docs/validation/fatigue/run.sh threshold  # the LEFM plate (m = 6) with a threshold
#   bash docs/validation/fatigue/run.sh monotonic  # the LEFM plate under a slow ramp
#   /usr/bin/python3 docs/validation/fatigue/plot.py   # the pictures
# Results go to results/fatigue/<study>/; each run prints its fatigue analysis. THREADS sets
# the threads per run (default 1, so that two studies can run side by side on 2 cores).
set -euo pipefail
ldem=${LDEM:-./build/release/ldem}
threads=${THREADS:-1}
out=results/fatigue
work=$out/cases
mkdir -p "$work"

# variant NAME SOURCE SED-EXPRESSION...: a copy of a case with its keys changed.
variant() {
  local name=$1 src=$2
  shift 2
  local args=()
  for e in "$@"; do args+=(-e "$e"); done
  sed "${args[@]}" "$src" >"$work/$name.toml"
  echo "$work/$name.toml"
}
run() {
  local case=$1 dir=$2
  /usr/bin/time -f "wall %e s, peak %M kB" "$ldem" run "$case" --out "$dir" --force \
    --threads "$threads" --no-plot 2>&1 | grep -E "fatigue|note|Paris|done|wall|error" || true
}

paper=cases/fatigue/paper_plate_coarse.toml
paper_fine=cases/fatigue/paper_plate.toml
lefm=cases/fatigue/lefm_plate.toml
case ${1:-} in
seeds)
  # The paper's lattice (L = 7.5 mm); SEEDS to choose others.
  for s in ${SEEDS:-1 2 3}; do
    c=$(variant paper_fine_seed$s $paper_fine "s/seed = 1 }/seed = $s }/")
    run "$c" "$out/seeds/seed$s"
  done ;;
seeds_coarse)
  for s in ${SEEDS:-1 2 3}; do
    c=$(variant paper_seed$s $paper "s/seed = 1 }/seed = $s }/")
    run "$c" "$out/seeds_coarse/seed$s"
  done ;;
paper)
  c=$(variant paper_bilinear $paper 's/^law = "bilinear_fatigue"/law = "bilinear"/' \
    '/^\[fatigue\]/,/^jump = true/d')
  run "$c" "$out/paper/bilinear" ;;
exponents)
  # A for each m: a bar cycled at the strain range 2.5e-5 lasts 1e4 cycles whatever m.
  # m = 10 stalls longer: 9 s of resolved time instead of 6.
  for mAe in "3 6.4e9 6.0" "6 4.1e23 6.0" "10 1.0e42 9.0"; do
    set -- $mAe
    c=$(variant lefm_m$1 $lefm "s/^A = .*/A = $2/" "s/^m = .*/m = $1.0/" "s/^end = 6.0 /end = $3 /")
    run "$c" "$out/exponents/m$1"
  done ;;
undamped)
  # The m = 6 plate without damping: the ringing of each break stays in the body.
  c=$(variant lefm_undamped $lefm '/^damping = /d')
  run "$c" "$out/undamped/m6" ;;
homogeneous)
  # The same plate with a fatigue life in every bar (no fatigue box).
  c=$(variant lefm_whole $lefm '/^box_min/d' '/^box_max/d' 's/^end = 6.0 /end = 1.5 /')
  run "$c" "$out/homogeneous/whole" ;;
mesh)
  # L = 5 mm: 80 x 163 modules, the crack's plane a quarter module above row 81's bottom, the
  # pre-crack to 0.06 m (12 modules), A given for bars of 10 mm (fatigue.length).
  c=$(variant lefm_half_L $lefm 's/^modules = \[40, 1, 81\]/modules = [80, 1, 163]/' \
    's/^L = 0.01$/L = 0.005/' 's/0.0, 0.0, 0.402\]/0.0, 0.0, 0.406]/' \
    's/0.4, 0.01, 0.403\]/0.4, 0.005, 0.4065]/' 's/-0.001, -0.001, 0.4025\]/-0.001, -0.001, 0.40625]/' \
    's/^jump = true/jump = true\nlength = 0.01/' 's/^energy_every = 170/energy_every = 340/')
  run "$c" "$out/mesh/half" ;;
frequency)
  c=$(variant lefm_f100 $lefm 's/frequency = 200.0/frequency = 100.0/g' 's/tau = 0.00667/tau = 0.01333/g' \
    's/^energy_every = 170/energy_every = 340/' 's/^end = 6.0 /end = 12.0/')
  run "$c" "$out/frequency/f100" ;;
threshold)
  # A threshold of 2e-5 against the pre-crack tip's strain range, about 2.7e-5 at a peak of
  # 0.3 MPa (the first bar's life without a threshold) and in proportion to the load: 1.8e-5
  # at 0.2 MPa (no growth) and 2.25e-5 at 0.25 MPa (PEAKS to choose others).
  for p in ${PEAKS:-0.2 0.25 0.3}; do
    c=$(variant lefm_th_$p $lefm 's/^jump = true/jump = true\nthreshold = 2.0e-5\njump_max = 1.0e8/' \
      "s/traction = \[0.0, 0.0, 0.3e6\]/traction = [0.0, 0.0, ${p}e6]/" \
      "s/traction = \[0.0, 0.0, -0.3e6\]/traction = [0.0, 0.0, -${p}e6]/" 's/^end = 6.0 /end = 1.0 /')
    run "$c" "$out/threshold/peak_$p"
  done ;;
monotonic)
  # The plate's strength under a slow ramp (0 to 4 MPa over 0.1 s, 70 periods of its lowest
  # mode), the paper's law alone, with the pre-crack at 0.06 m and at 0.22 m, near where the
  # fatigue runs became unstable (LENGTHS to choose others).
  for a in ${LENGTHS:-0.06 0.22}; do
    e=$(awk -v a=$a 'BEGIN { printf "%.4f", a + 0.001 }')
    c=$(variant lefm_ramp_$a $lefm 's/^law = "bilinear_fatigue"/law = "bilinear"/' \
      '/^\[fatigue\]/,/^box_max/d' '/^\[analysis\]/,/^fatigue_fit_elastic/d' \
      's/{ type = "exp_rise", value = 0.55, tau = 0.005 },/{ type = "ramp", value = 13.333, duration = 0.1 },/' \
      '/growing_sine/d' "s/edge1 = \[0.061, 0.0, 0.0\]/edge1 = [$e, 0.0, 0.0]/" 's/^end = 6.0 /end = 0.1 /')
    run "$c" "$out/monotonic/a_$a"
  done ;;
*)
  sed -n '2,16p' "$0"
  exit 2 ;;
esac
