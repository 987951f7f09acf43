#!/usr/bin/env bash
# `ldem run` and `ldem resume` across MPI processes against one process: the same output folder
# (tests/compare_runs.py says what may differ and why), checkpoints resumed on another number
# of processes, and bad input refused once with no folder created.
# usage: test_mpi_run.sh LDEM SOURCE_DIR MPIEXEC PROCESSES...
set -uo pipefail
LDEM=$1
SRC=$2
MPIEXEC=$3
shift 3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fails=0
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
compare() { /usr/bin/python3 "$SRC/tests/compare_runs.py" "$1" "$2" || bad "$3"; }
mpi() { local np=$1; shift; "$MPIEXEC" -np "$np" --oversubscribe "$LDEM" "$@"; }

# The shipped cases, shortened: the tutorial plate (imposed velocities, damping, a notch), the
# graded plate (E and Gf graded along z, the paper's step rule, a pre-crack, probes) and the
# fatigue plate (Weibull toughness, fixed border, loads, bar-force and load probes).
sed 's/^end = .*/end = 1.0e-3/' "$SRC/cases/tutorial/notched_plate.toml" >"$T/tutorial.toml"
# (graded.toml: without an end checkpoint, so that the resumes below start from periodic ones,
# before the end)
{ sed 's/^end = .*/end = 6.0e-6/' "$SRC/cases/fgm_plate/graded_modulus_toughness.toml"
  printf '\n[output]\nend_checkpoint = false\n'; } >"$T/graded.toml"
sed 's/^end = .*/end = 0.004/' "$SRC/cases/subcritical_fatigue_coarse.toml" >"$T/fatigue.toml"
# And the tutorial plate with the fatigue law and cycle jumping, moved up and down at 1000 Hz
# for 35 cycles (JUMP_END; the sanitized build 12: a jump, before any bar runs out of life):
# bars run out of life, lives jump (the life of each bar is in the snapshots). Only the bars
# that meet a box around the notch's plane have a life; the processes' windows cut the box.
sed -e 's/^e_p = 1.0e-4 .*/e_p = 1.0e-4\nlaw = "bilinear_fatigue"\n\n[fatigue]\nA = 1.0e18\nm = 4.0\njump = true\nbox_min = [0.0, 0.0, 0.045]\nbox_max = [0.2, 0.005, 0.055]/' \
  -e 's/^value = \[0.0, 0.0, 0.02\]/value = [0.0, 0.0, 0.002]/' \
  -e 's/^ramp = 2.0e-4/function = [{ type = "growing_sine", amplitude = 1.0, frequency = 1000.0, t_start = 0.0, tau = 1.0 }]/' \
  -e "s/^end = .*/end = ${JUMP_END:-0.035}/" -e 's/^energy_every = 50/energy_every = 100/' \
  "$SRC/cases/tutorial/notched_plate.toml" >"$T/jumping.toml"
# And the tutorial plate under its weight at 1000 g (a body force on every node) and a total
# force spread over its surface near a corner (the strip's nodes lie on several processes),
# with a probe of each load.
{ sed 's/^end = .*/end = 1.0e-3/' "$SRC/cases/tutorial/notched_plate.toml"
  printf '\n[[node_set]]\nname = "everything"\nall = true\n\n[[node_set]]\nname = "strip"\nshape = { type = "box", min = [0.0, -1.0, 0.08], max = [0.06, 1.0, 0.1] }\nsurface = true\n'
  printf '\n[[load]]\nname = "weight"\nset = "everything"\nacceleration = [0.0, 0.0, -1.0e4]\n\n[[load]]\nname = "push"\nset = "strip"\ntotal = [50.0, 0.0, -20.0]\nfunction = [{ type = "ramp", duration = 5.0e-4 }]\n'
  printf '\n[[probe]]\nname = "weight"\nkind = "load"\nload = "weight"\n\n[[probe]]\nname = "push"\nkind = "load"\nload = "push"\n'; } >"$T/loaded.toml"
# And the tutorial plate pulled by a controller that opens the notch's mouth at 2 cm/s (its
# gauge's two nodes lie on either side of the 2-process cut: the factor comes from the gauge's
# terms gathered each step).
sed -e 's/^end = .*/end = 1.0e-3/' -e 's/^value = \[0.0, 0.0, 0.02\]/value = [0.0, 0.0, 0.1]/' \
  -e 's/^ramp = 2.0e-4/control = { probe = "notch_opening", rate = 0.02 }/' \
  "$SRC/cases/tutorial/notched_plate.toml" >"$T/controlled.toml"
grep -q '^control = ' "$T/controlled.toml" || bad "controlled.toml: the tutorial's velocity is not where it was"
# And the tutorial plate pressed on its sides while it is pulled: a frictional platen moving in
# on its left face and a roller with friction on its right face (both across the 2-process
# cut), with a probe of each platen's force and of the roller's travel.
{ sed 's/^end = .*/end = 1.0e-3/' "$SRC/cases/tutorial/notched_plate.toml"
  printf '\n[[platen]]\nname = "left"\npoint = [-1.0e-5, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\nvelocity = [0.5, 0.0, 0.0]\nramp = 2.0e-4\nfriction = 0.3\n'
  printf '\n[[platen]]\nname = "roller"\nshape = "cylinder"\npoint = [0.21, 0.0, 0.05]\naxis = [0.0, 1.0, 0.0]\nradius = 0.01\nvelocity = [-0.5, 0.0, 0.0]\nramp = 2.0e-4\nfriction = 0.3\n'
  printf '\n[[probe]]\nname = "left_x"\nkind = "platen"\nplaten = "left"\ncomponent = "x"\n\n[[probe]]\nname = "left_z"\nkind = "platen"\nplaten = "left"\ncomponent = "z"\n\n[[probe]]\nname = "roller_x"\nkind = "platen"\nplaten = "roller"\ncomponent = "x"\n\n[[probe]]\nname = "travel"\nkind = "platen_displacement"\nplaten = "roller"\ncomponent = "x"\n'; } >"$T/pressed.toml"
for c in tutorial graded fatigue jumping loaded controlled pressed; do
  "$LDEM" run "$T/$c.toml" --out "$T/$c-1" --no-plot --threads 1 >/dev/null 2>"$T/err" ||
    bad "$c on one process: $(cat "$T/err")"
  for np in "$@"; do
    mpi "$np" run "$T/$c.toml" --out "$T/$c-$np" --no-plot --threads 1 >/dev/null 2>"$T/err" ||
      bad "$c on $np processes: $(cat "$T/err")"
    compare "$T/$c-1" "$T/$c-$np" "$c: $np processes against one"
  done
done

# A thick plate (the tutorial's, 4 modules through y, the notch through all of them, a random
# modulus per bar and a correlated random density), split over y as well as z: 2 x 1, 3 x 1
# and 2 x 2 boxes (THICK_GRIDS; the sanitized build runs 2 x 2 alone); a checkpoint of the
# 2 x 2 run resumed on 3 processes (the grid they choose, 1 x 3).
# Its snapshots are compressed and hold the stress and the strain at the nodes (the processes
# compress shares of every array's blocks; the nodes by a cut take the neighbours' modules).
sed -e 's/^end = .*/end = 1.2e-3/; s/^modules = .*/modules = [40, 4, 20]/' \
  -e 's/^\[output\]/[output]\nend_checkpoint = false\nvtu_compression = "zlib"\nvtu_arrays = ["displacement", "velocity", "stress", "node_strain", "damage", "state", "axial_force", "strain", "E", "Gf", "e_p", "e_r"]/' \
  -e 's/^edge2 = .*/edge2 = [0.0, 0.022, 0.0]/' \
  -e 's/^E = .*/E = { type = "weibull", mean = 35.0e9, cv = 0.1, seed = 3 }/' \
  -e 's/^rho = .*/rho = { type = "weibull", mean = 2400.0, cv = 0.05, seed = 4, correlation_length = 0.01 }/' \
  "$SRC/cases/tutorial/notched_plate.toml" >"$T/thick.toml"
# (with gauges whose nodes lie on several processes: the top's mean displacement, an
# extensometer across the z cut and an opening across the y cut)
printf '\n[[probe]]\nname = "lvdt"\nkind = "displacement"\nset = "top"\n\n[[probe]]\nname = "extensometer"\nkind = "strain"\nfrom = [0.15, 0.01, 0.03]\nto = [0.15, 0.01, 0.07]\n\n[[probe]]\nname = "across"\nkind = "opening"\nfrom = [0.18, 0.0, 0.06]\nto = [0.18, 0.02, 0.06]\ncomponent = "y"\n' >>"$T/thick.toml"
"$LDEM" run "$T/thick.toml" --out "$T/thick-1" --no-plot --threads 1 >/dev/null 2>"$T/err" ||
  bad "thick plate on one process: $(cat "$T/err")"
for grid in ${THICK_GRIDS:-2x1 3x1 2x2}; do
  py=${grid%x*} pz=${grid#*x}
  mpi $((py * pz)) run "$T/thick.toml" --out "$T/thick-$py$pz" --no-plot --threads 1 \
    --process-grid $py $pz >/dev/null 2>"$T/err" || bad "thick plate on $py x $pz: $(cat "$T/err")"
  compare "$T/thick-1" "$T/thick-$py$pz" "thick plate: $py x $pz processes against one"
done
# A shaped body across processes: the thick plate with a hole through its thickness, a
# spherical pore cut from one face and a stiffer, denser top layer ([[region]]), on 2 x 2 boxes (windows hold absent modules, the snapshots
# their present nodes and bars only).
{ sed "s/^end = .*/end = ${HOLED_END:-0.8e-3}/" "$T/thick.toml"; printf '\n[[geometry]]\nremove = { type = "cylinder", start = [0.14, -1, 0.05], end = [0.14, 1, 0.05], radius = 0.02 }\n\n[[geometry]]\nremove = { type = "sphere", centre = [0.09, 0.02, 0.03], radius = 0.012 }\n\n[[region]]\nshape = { type = "box", min = [0, -1, 0.06], max = [0.2, 1, 0.1] }\nE = 50.0e9\nrho = { type = "weibull", mean = 2600.0, cv = 0.05, seed = 9 }\n'; } >"$T/holed.toml"
"$LDEM" run "$T/holed.toml" --out "$T/holed-1" --no-plot --threads 1 >/dev/null 2>"$T/err" ||
  bad "holed plate on one process: $(cat "$T/err")"
mpi 4 run "$T/holed.toml" --out "$T/holed-22" --no-plot --threads 1 --process-grid 2 2 \
  >/dev/null 2>"$T/err" || bad "holed plate on 2 x 2: $(cat "$T/err")"
compare "$T/holed-1" "$T/holed-22" "holed plate: 2 x 2 processes against one"
# The same holes in a plate of one material, whose step takes each bar's area factor from a
# byte and masks the vectors at the body's surface (docs/architecture.md, "Shaped bodies").
{ sed -e "s/^end = .*/end = ${HOLED_END:-0.8e-3}/; s/^modules = .*/modules = [40, 4, 20]/" \
    -e 's/^edge2 = .*/edge2 = [0.0, 0.022, 0.0]/' "$SRC/cases/tutorial/notched_plate.toml"
  printf '\n[[geometry]]\nremove = { type = "cylinder", start = [0.14, -1, 0.05], end = [0.14, 1, 0.05], radius = 0.02 }\n\n[[geometry]]\nremove = { type = "sphere", centre = [0.09, 0.02, 0.03], radius = 0.012 }\n'; } >"$T/holed-uniform.toml"
"$LDEM" run "$T/holed-uniform.toml" --out "$T/holed-u1" --no-plot --threads 1 >/dev/null \
  2>"$T/err" || bad "uniform holed plate on one process: $(cat "$T/err")"
mpi 4 run "$T/holed-uniform.toml" --out "$T/holed-u22" --no-plot --threads 1 --process-grid 2 2 \
  >/dev/null 2>"$T/err" || bad "uniform holed plate on 2 x 2: $(cat "$T/err")"
compare "$T/holed-u1" "$T/holed-u22" "uniform holed plate: 2 x 2 processes against one"
mpi 4 run "$T/thick.toml" --out "$T/thick-ck" --no-plot --threads 1 --process-grid 2 2 \
  --checkpoint-every 1500 >/dev/null 2>"$T/err" || bad "checkpointed 2 x 2 run: $(cat "$T/err")"
mpi 3 resume "$T/thick-ck" --no-plot --threads 1 >/dev/null 2>"$T/err" &&
  grep -q "resuming" "$T/err" || bad "resume of a 2 x 2 checkpoint on 3: $(cat "$T/err")"
compare "$T/thick-1" "$T/thick-ck" "checkpoint of 2 x 2 processes resumed on 1 x 3"

# Checkpoints: written by P processes, resumed by one and by P + 1 (and one process's by P):
# the resumed runs redo the steps after the checkpoint and must write the same folder.
for np in "$@"; do
  mpi "$np" run "$T/graded.toml" --out "$T/ck-$np" --no-plot --threads 1 --checkpoint-every 150 \
    >/dev/null 2>"$T/err" || bad "checkpointed run on $np processes: $(cat "$T/err")"
  for resume_np in 1 $((np + 1)); do
    cp -r "$T/ck-$np" "$T/ck-$np-$resume_np"
    if [ "$resume_np" = 1 ]; then
      "$LDEM" resume "$T/ck-$np-$resume_np" --no-plot --threads 1 >/dev/null 2>"$T/err"
    else
      mpi "$resume_np" resume "$T/ck-$np-$resume_np" --no-plot --threads 1 >/dev/null 2>"$T/err"
    fi
    [ $? -eq 0 ] && grep -q "resuming" "$T/err" || bad "resume on $resume_np of $np: $(cat "$T/err")"
    compare "$T/graded-1" "$T/ck-$np-$resume_np" "checkpoint of $np processes resumed on $resume_np"
  done
done
"$LDEM" run "$T/graded.toml" --out "$T/ck-1" --no-plot --threads 1 --checkpoint-every 150 \
  >/dev/null 2>&1
# The checkpoint file is the same bytes whoever wrote it (each process writes its nodes and
# bars at their places, io/checkpoint.hpp).
for np in "$@"; do
  cmp -s "$T/ck-1/checkpoint/state.ckpt" "$T/ck-$np/checkpoint/state.ckpt" ||
    bad "the checkpoint of $np processes differs from one process's"
done
np=${!#}
mpi "$np" resume "$T/ck-1" --no-plot --threads 1 >/dev/null 2>"$T/err" || bad "resume of one process's checkpoint on $np: $(cat "$T/err")"
compare "$T/graded-1" "$T/ck-1" "checkpoint of one process resumed on $np"

# A finished run continued (`resume --end`): the graded plate run to 4 us on the last count of
# processes, then from its end checkpoint to 6 us on one process more, writes the logs and
# snapshots of one process's run to 6 us with the same output intervals.
sed -e 's/^end_checkpoint = false/vtu_every = 10/' "$T/graded.toml" >"$T/graded-long.toml"
sed -e 's/^end = .*/end = 4.0e-6/' "$T/graded-long.toml" >"$T/graded-short.toml"
"$LDEM" run "$T/graded-long.toml" --out "$T/long-ref" --no-plot --threads 1 >/dev/null 2>&1
mpi "$np" run "$T/graded-short.toml" --out "$T/cont" --no-plot --threads 1 >/dev/null 2>"$T/err" &&
  mpi $((np + 1)) resume "$T/cont" --end 6.0e-6 --threads 1 >/dev/null 2>"$T/err" ||
  bad "run on $np and resume --end on $((np + 1)): $(cat "$T/err")"
for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/long-ref" | grep '\.vtu$'); do
  cmp -s "$T/long-ref/$f" "$T/cont/$f" || bad "resume --end on $((np + 1)) processes: $f differs"
done

# Snapshots with a choice of arrays (output.vtu_arrays, a material field among them): the same
# folder from 2 processes as from one.
sed 's/^end_checkpoint = false/vtu_arrays = ["displacement", "state", "E"]/' "$T/graded.toml" >"$T/arrays.toml"
"$LDEM" run "$T/arrays.toml" --out "$T/arrays-1" --no-plot --threads 1 >/dev/null 2>&1
mpi 2 run "$T/arrays.toml" --out "$T/arrays-2" --no-plot --threads 1 >/dev/null 2>"$T/err" ||
  bad "vtu_arrays on 2 processes: $(cat "$T/err")"
compare "$T/arrays-1" "$T/arrays-2" "vtu_arrays: 2 processes against one"
/usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/arrays-2" >/dev/null || bad "vtu_arrays: the snapshots of 2 processes"

# Ctrl-C: mpirun passes it on to the processes (as SIGTERM), which agree on a step, write the
# body's checkpoint and stop; resumed on another number of processes, the folder is the
# uninterrupted run's. LONG_END: the run's end time, long enough that the signal arrives first.
sed "s/^end = .*/end = ${LONG_END:-500.0e-6}/" "$SRC/cases/fgm_plate/graded_modulus_toughness.toml" >"$T/long.toml"
"$LDEM" run "$T/long.toml" --out "$T/long-1" --no-plot --threads 1 >/dev/null 2>&1
"$MPIEXEC" -np 2 --oversubscribe "$LDEM" run "$T/long.toml" --out "$T/long-2" --no-plot \
  --threads 1 >/dev/null 2>"$T/err" &
pid=$!
for _ in $(seq 600); do # until the run is under way: a few energy rows written
  [ "$(cat "$T/long-2/energy.csv.part" 2>/dev/null | wc -l)" -gt 20 ] && break
  sleep 0.05
done
kill -INT $pid
wait $pid
if [ -s "$T/long-2/checkpoint/state.ckpt" ] && grep -q "stopped by SIG" "$T/err"; then
  mpi 3 resume "$T/long-2" --no-plot --threads 1 >/dev/null 2>"$T/err" || bad "resume after Ctrl-C: $(cat "$T/err")"
  compare "$T/long-1" "$T/long-2" "Ctrl-C on 2 processes, resumed on 3"
else
  bad "Ctrl-C on 2 processes: no checkpoint ($(cat "$T/err"))"
fi

# Bad input: one message, exit 2, no folder. A body of 1 module across x cannot be split.
printf '[case]\ntitle = "thin"\n[lattice]\nmodules = [4, 1, 1]\nL = 0.01\n[material]\nE = 35.0e9\nrho = 2400.0\nGf = 10.0\ne_p = 1.0e-4\n[time]\nend = 1.0e-5\n' >"$T/thin.toml"
"$LDEM" check "$T/thin.toml" >/dev/null 2>&1 || bad "the thin case is not valid on one process"
mpi 2 run "$T/thin.toml" --out "$T/thin" --no-plot >/dev/null 2>"$T/err"
rc=$?
if [ $rc -ne 2 ] || [ "$(grep -c "cannot be shared by 2 processes" "$T/err")" -ne 1 ] || [ -e "$T/thin" ]; then
  bad "a body thinner than the processes: rc $rc, $(cat "$T/err")"
fi
mpi 2 run "$SRC/cases/tutorial/notched_plate.toml" --out "$T/grid" --no-plot --process-grid 2 1 \
  >/dev/null 2>"$T/err"
rc=$?
if [ $rc -ne 2 ] || [ "$(grep -c -- "--process-grid 2 1: the body has 1 x 20 modules" "$T/err")" -ne 1 ] ||
  [ -e "$T/grid" ]; then
  bad "a grid the body cannot take: rc $rc, $(cat "$T/err")"
fi
mpi 2 run "$SRC/cases/tutorial/notched_plate.toml" --out "$T/grid" --no-plot --process-grid 3 1 \
  >/dev/null 2>"$T/err"
rc=$?
if [ $rc -ne 2 ] || [ "$(grep -c "product is the number of processes started, 2" "$T/err")" -ne 1 ] ||
  [ -e "$T/grid" ]; then
  bad "a grid of another process count: rc $rc, $(cat "$T/err")"
fi
sed 's/^E = 35.0e9/E = "x"/' "$SRC/cases/tutorial/notched_plate.toml" >"$T/typo.toml"
mpi 2 run "$T/typo.toml" --out "$T/typo" --no-plot >/dev/null 2>"$T/err"
rc=$?
if [ $rc -ne 2 ] || [ "$(grep -c "material.E: expected a number" "$T/err")" -ne 1 ] || [ -e "$T/typo" ]; then
  bad "a bad case on 2 processes: rc $rc, $(cat "$T/err")"
fi
# Errors about the whole body, found by the processes together (no process holds it): K_r < 1
# in every bar and a time.end shorter than the step. The message is one process's, word for
# word.
sed 's/^Gf = .*/Gf = 0.5/' "$SRC/cases/tutorial/notched_plate.toml" >"$T/brittle.toml"
sed 's/^end = .*/end = 1.0e-12/' "$SRC/cases/tutorial/notched_plate.toml" >"$T/short.toml"
for c in brittle short; do
  "$LDEM" run "$T/$c.toml" --out "$T/$c-1" --no-plot >/dev/null 2>"$T/err1"
  mpi 3 run "$T/$c.toml" --out "$T/$c-3" --no-plot >/dev/null 2>"$T/err"
  rc=$?
  if [ $rc -ne 2 ] || [ "$(grep -c "ldem: error" "$T/err")" -ne 1 ] || [ -e "$T/$c-3" ] ||
    [ "$(grep "ldem: error" "$T/err")" != "$(grep "ldem: error" "$T/err1")" ]; then
    bad "the $c case on 3 processes: rc $rc, $(cat "$T/err") against $(cat "$T/err1")"
  fi
done

if [ $fails -ne 0 ]; then echo "$fails failures"; exit 1; fi
echo "all distributed runs agree with one process"
