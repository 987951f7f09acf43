#!/usr/bin/env bash
# The ldem command line as a user meets it: exit codes, messages, and output folders that are
# never created or changed by bad input. usage: test_cli.sh LDEM SOURCE_DIR
set -uo pipefail
LDEM=$1
SRC=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fails=0
pass=0
ok() { pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
# has PATTERN: the piped input holds a line matching PATTERN. It reads the input to the end (grep -q
# stops at the first match, and the writer, killed by SIGPIPE, then fails the pipeline under pipefail).
has() { grep -- "$1" >/dev/null; }
GOOD="$SRC/cases/tutorial/notched_plate.toml"

# expect_error NAME PATTERN CASEFILE [extra args]: exit 2, message matches, no output folder.
expect_error() {
  local name=$1 pattern=$2 case=$3
  shift 3
  local out="$T/out_$name"
  "$LDEM" run "$case" --out "$out" --no-plot "$@" >"$T/stdout" 2>"$T/stderr"
  local rc=$?
  if [ $rc -ne 2 ]; then bad "$name: exit code $rc, expected 2"; return; fi
  if ! grep -q -- "$pattern" "$T/stderr"; then bad "$name: message '$(cat "$T/stderr")' lacks '$pattern'"; return; fi
  if [ -e "$out" ]; then bad "$name: output folder was created"; return; fi
  ok
}
# variant NAME SED_EXPRESSION: the tutorial case edited.
variant() { sed "$2" "$GOOD" >"$T/$1.toml"; echo "$T/$1.toml"; }

"$LDEM" >/dev/null 2>&1 && "$LDEM" --help | has "run" && ok || bad "ldem without arguments"
"$LDEM" --version | has "^ldem " && ok || bad "--version"

expect_error missing_case "cannot read the case file" "$T/nope.toml"
expect_error malformed "malformed TOML" "$(variant malformed 's/^L = 0.005/L = = 0.005/')"
expect_error unknown_key 'did you mean "Gf"' "$(variant unknown 's/^Gf = /Gff = /')"
expect_error wrong_type 'material.E: expected a number (Pa), got "x"' "$(variant type 's/^E = 35.0e9/E = "x"/')"
expect_error out_of_range "material.nu: expected a value (0, 0.5), got 0.7" "$(variant range 's/^rho = 2400.0/rho = 2400.0\nnu = 0.7/')"
expect_error missing_key "lattice.L: missing required key" "$(variant missing '/^L = 0.005/d')"
expect_error low_kr "K_r = e_r / e_p < 1" "$(variant kr 's/^Gf = 10.0/Gf = 0.5/')"
expect_error unstable_dt "above the stable limit" "$(variant dt 's/^safety = .*//; s/^damping = 200.0/damping = 200.0\nrule = "dt"\ndt = 1e-5/')"
expect_error empty_set 'node set "top" (box' "$(variant empty 's/^face = "z+"/box_min = [1, 1, 1]\nbox_max = [2, 2, 2]/')"
expect_error precrack_outside "crosses no bar: it lies outside the body" "$(variant outside 's/^origin = \[-0.0001, -0.001, 0.05125\]/origin = [1.0, -0.001, 0.05125]/')"
# Numbers that no case means: not finite, absurd, or two probes writing one column.
expect_error nan_velocity "velocity\[0\].value: expected 3 finite numbers" "$(variant nanv 's/^value = \[0.0, 0.0, 0.02\]/value = [0.0, 0.0, nan]/')"
expect_error nan_probe "probe\[1\].at: expected 3 finite numbers" "$(variant nanp 's/^at = \[0.0525, 0.0025, 0.05\]/at = [nan, 0.0025, 0.05]/')"
expect_error damping "damp.toml:[0-9]*: time.damping: expected a coefficient below 2 / dt" "$(variant damp 's/^damping = 200.0/damping = 1e300/')"
expect_error end "end.toml:[0-9]*: time.end: expected at most 1e+12 steps" "$(variant end 's/^end = 4.0e-3/end = 1e300/')"
expect_error tiny_L "lattice.L: expected a value \[1e-09, 1000\] (m), got 1e-300" "$(variant tinyL 's/^L = 0.005/L = 1e-300/')"
expect_error tiny_rho "material.rho: expected a value \[0.001, 1e+06\] (kg/m^3), got 1e-300" "$(variant tinyrho 's/^rho = 2400.0/rho = 1e-300/')"
expect_error huge_dt "time.dt: expected a value (0, 1000\] (s), got 1e+300" "$(variant hugedt 's/^safety = 0.5/rule = "dt"\ndt = 1e300/')"
expect_error probe_twice 'probe\[1\].name: expected a name no other probe has (a column of probes.csv); got "pull_force" again' "$(variant twice 's/^name = "bar_ahead_of_notch"/name = "pull_force"/')"
expect_error device "/dev/zero: expected the case file as a regular file; got a device" /dev/zero
expect_error directory "expected the case file as a regular file; got a directory" "$SRC/cases"
expect_error threads "--threads: expected a whole number from 0 to [0-9]* (0: all; at most 4 times this machine's" "$GOOD" --threads 100000
expect_error checkpoint_nan "--checkpoint-seconds: expected a finite number of at least 0; got 'nan'" "$GOOD" --checkpoint-seconds nan
# Usage errors exit 2 with a readable message, whatever CLI11 would return.
for args in "bogus" "run" "run $GOOD --out" "bench --modules 0 1 1" "resume"; do
  # shellcheck disable=SC2086
  "$LDEM" $args >/dev/null 2>"$T/stderr"
  rc=$?
  [ $rc -eq 2 ] && ! grep -q "[0-9]\{20\}" "$T/stderr" && ok || bad "usage error 'ldem $args': rc $rc, $(cat "$T/stderr")"
done
"$LDEM" run "$GOOD" --out "" --no-plot >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q -- "--out: expected a folder; got an empty name" "$T/stderr" && [ ! -e results/notched_plate ] && ok || bad "--out '': rc $rc, $(cat "$T/stderr")"
"$LDEM" run "$GOOD" --out /proc/ldem-test/out --no-plot >/dev/null 2>"$T/stderr"
rc=$?
if [ $rc -eq 2 ] && grep -q "cannot create the folder" "$T/stderr" && [ ! -e /proc/ldem-test ]; then ok; else bad "unwritable folder: rc $rc, $(cat "$T/stderr")"; fi

mkdir -p "$T/full" && echo keep >"$T/full/marker"
"$LDEM" run "$GOOD" --out "$T/full" --no-plot >/dev/null 2>"$T/stderr"
rc=$?
if [ $rc -eq 2 ] && grep -q "not empty" "$T/stderr" && [ "$(ls "$T/full")" = "marker" ]; then ok; else bad "non-empty folder: rc $rc, $(ls "$T/full")"; fi

# A real run, checked by an independent reader, then re-plotted.
if "$LDEM" run "$GOOD" --out "$T/run" --threads 2 >"$T/stdout" 2>"$T/stderr"; then ok; else bad "tutorial run: $(cat "$T/stderr")"; fi
/usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/run" && ok || bad "outputs of the tutorial run"
[ -s "$T/run/crack.png" ] && [ -s "$T/run/energy.png" ] && [ -s "$T/run/probes.png" ] && [ -s "$T/run/response.png" ] && ok || bad "PNG plots missing"
rm -f "$T/run/crack.png" "$T/run/energy.png"
"$LDEM" plot "$T/run" && [ -s "$T/run/crack.png" ] && ok || bad "ldem plot"
"$LDEM" run "$GOOD" --out "$T/run" --force --no-plot >/dev/null 2>&1 && ok || bad "--force into a used folder"

# A shaped body: the tutorial plate with a hole through it. Its snapshots hold the present
# nodes and bars only, with their numbers in the body; 1 and 2 threads give the same bytes.
{ cat "$GOOD"; printf '\n[[geometry]]\nremove = { type = "cylinder", start = [0.14, -1, 0.05], end = [0.14, 1, 0.05], radius = 0.02 }\n'; } >"$T/hole.toml"
if "$LDEM" run "$T/hole.toml" --out "$T/hole1" --threads 1 --no-plot >/dev/null 2>"$T/stderr" &&
  "$LDEM" run "$T/hole.toml" --out "$T/hole2" --threads 2 >/dev/null 2>&1; then ok; else bad "hole run: $(cat "$T/stderr")"; fi
/usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/hole2" && ok || bad "outputs of the run with a hole"
for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/hole1" | grep '\.vtu$'); do
  cmp -s "$T/hole1/$f" "$T/hole2/$f" || bad "hole run: $f differs between 1 and 2 threads"
done
# 800 modules less the hole's: those whose centres lie within 4 L of its axis, 52 (the centres
# ((i + 1/2) L, (k + 1/2) L) with (i - 27.5)^2 + (k - 9.5)^2 <= 16).
has "^modules_present = 748$" <"$T/hole1/case.resolved.toml" && ok || bad "hole run: modules_present"

# Interrupt and resume: SIGINT or SIGTERM at several moments, resumed on another thread count,
# and a hard kill after periodic checkpoints; every output byte-identical to an uninterrupted
# run. The case is copied so that a changed case can be tested too; it lasts four times the
# tutorial's (about 1.5 s on 2 threads here), so that the signals below arrive before its end.
sed 's/^end = 4.0e-3/end = 16.0e-3/' "$GOOD" >"$T/case.toml"
"$LDEM" run "$T/case.toml" --out "$T/ref" --no-plot >/dev/null 2>&1
same_as_ref() {
  local d=$1 f
  for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/ref" | grep '\.vtu$'); do
    cmp -s "$T/ref/$f" "$d/$f" || { echo "differs: $d/$f"; return 1; }
  done
}
for spec in "INT 0.25 130 1" "INT 0.5 130 2" "TERM 0.35 143 1"; do
  read -r sig after code threads <<<"$spec"
  d="$T/int_${sig}_$after"
  timeout -s "$sig" --preserve-status "$after" "$LDEM" run "$T/case.toml" --out "$d" --no-plot --threads 2 >/dev/null 2>"$T/stderr"
  rc=$?
  if [ $rc -ne "$code" ] || ! grep -q "ldem resume $d" "$T/stderr" || [ ! -s "$d/checkpoint/state.ckpt" ]; then
    bad "SIG$sig after $after s: rc $rc, $(cat "$T/stderr")"; continue
  fi
  grep -q '"interrupted": true' "$d/summary.json" || bad "SIG$sig: summary not marked interrupted"
  if "$LDEM" resume "$d" --threads "$threads" --no-plot >/dev/null 2>"$T/stderr" && same_as_ref "$d"; then ok; else bad "resume after SIG$sig at $after s: $(cat "$T/stderr")"; fi
done
# A resume keeps the options of the run it continues: a run started with --no-plot and resumed
# without it makes no pictures either. summary.json names the case by one path however it was
# typed.
timeout -s INT --preserve-status 0.3 "$LDEM" run "$T/case.toml" --out "$T/noplot" --no-plot >/dev/null 2>&1
if "$LDEM" resume "$T/noplot" >/dev/null 2>"$T/stderr" && [ ! -e "$T/noplot/crack.png" ] && [ ! -e "$T/noplot/energy.png" ] &&
  same_as_ref "$T/noplot"; then ok; else bad "resume kept --no-plot: $(cat "$T/stderr"), $(ls "$T/noplot")"; fi
mkdir -p "$T/sub"
"$LDEM" run "$T/sub/../case.toml" --out "$T/typed" --no-plot >/dev/null 2>&1
grep -q "\"case\": \"$(realpath "$T/case.toml")\"" "$T/typed/summary.json" && ok || bad "summary.json's case as typed: $(grep '"case"' "$T/typed/summary.json")"
# A hard kill (no chance to clean up) after periodic checkpoints: resume from the last one.
cp "$T/case.toml" "$T/ckpt.toml"
"$LDEM" run "$T/ckpt.toml" --out "$T/ref2" --no-plot >/dev/null 2>&1
# Killed as soon as its first checkpoint exists (a fixed delay was either too short or too
# long depending on the machine's load): kill_after_checkpoint CASE OUT EVERY.
kill_after_checkpoint() {
  "$LDEM" run "$1" --out "$2" --no-plot --checkpoint-every "$3" >/dev/null 2>&1 &
  local pid=$!
  for _ in $(seq 3000); do
    [ -s "$2/checkpoint/state.ckpt" ] && break
    sleep 0.01
  done
  kill -9 $pid 2>/dev/null
  wait $pid 2>/dev/null
}
kill_after_checkpoint "$T/ckpt.toml" "$T/kill" 200
: >"$T/stderr"
if [ -s "$T/kill/checkpoint/state.ckpt" ] && "$LDEM" resume "$T/kill" --no-plot >/dev/null 2>"$T/stderr" &&
  cmp -s "$T/ref2/energy.csv" "$T/kill/energy.csv" && cmp -s "$T/ref2/events.csv" "$T/kill/events.csv" &&
  cmp -s "$T/ref2/probes.csv" "$T/kill/probes.csv"; then ok; else bad "resume after a hard kill: $(cat "$T/stderr")"; fi
# The same for a shaped body (the plate with a hole, four times the tutorial's run): its mask
# is built again from the case, and every output, snapshots and body.npy included, is the
# uninterrupted run's.
{ cat "$T/case.toml"; printf '\n[[geometry]]\nremove = { type = "cylinder", start = [0.14, -1, 0.05], end = [0.14, 1, 0.05], radius = 0.02 }\n'; } >"$T/holeck.toml"
"$LDEM" run "$T/holeck.toml" --out "$T/holeref" --no-plot >/dev/null 2>&1
kill_after_checkpoint "$T/holeck.toml" "$T/holekill" 2000
: >"$T/stderr"
if [ -s "$T/holekill/checkpoint/state.ckpt" ] && "$LDEM" resume "$T/holekill" --no-plot >/dev/null 2>"$T/stderr" &&
  /usr/bin/python3 "$SRC/tests/compare_runs.py" "$T/holeref" "$T/holekill" >/dev/null; then ok; else bad "shaped body resumed after a hard kill: $(cat "$T/stderr")"; fi
# The fatigue law (law = "bilinear_fatigue"): the tutorial plate with a short life, so that its
# bars' lives run out during the run besides those the bilinear law breaks. energy.csv has the
# fatigue column; 1 and 2 threads, and a run killed after a checkpoint and resumed, give the
# same bytes.
sed -e 's/^e_p = 1.0e-4 .*/e_p = 1.0e-4\nlaw = "bilinear_fatigue"\n\n[fatigue]\nA = 2.0e6\nm = 2.0/' \
  -e 's/^end = 4.0e-3 .*/end = 8.0e-3/' "$GOOD" >"$T/fatigue.toml"
"$LDEM" run "$T/fatigue.toml" --out "$T/fat1" --no-plot --threads 1 >/dev/null 2>"$T/stderr" || bad "fatigue run: $(cat "$T/stderr")"
"$LDEM" run "$T/fatigue.toml" --out "$T/fat2" --no-plot --threads 2 >/dev/null 2>&1
head -1 "$T/fat1/energy.csv" | has ",damping_dissipated,fatigue_dissipated,balance_error$" && ok || bad "fatigue column: $(head -1 "$T/fat1/energy.csv")"
# The tutorial plate is damped; without damping a fatigue case gets a warning.
! grep -q "time.damping = 0 with a fatigue law" "$T/stderr" && ok || bad "damped fatigue case warned: $(cat "$T/stderr")"
sed -e 's/^damping = .*//' "$T/fatigue.toml" >"$T/undamped.toml"
"$LDEM" check "$T/undamped.toml" 2>&1 >/dev/null | has "warning: time.damping = 0 with a fatigue law" && ok ||
  bad "no warning for an undamped fatigue case"
same_fatigue() {
  local f
  for f in energy.csv events.csv probes.csv $(ls "$T/fat1" | grep '\.vtu$'); do
    cmp -s "$T/fat1/$f" "$1/$f" || { echo "differs: $1/$f"; return 1; }
  done
}
same_fatigue "$T/fat2" && ok || bad "fatigue law on 1 and 2 threads"
kill_after_checkpoint "$T/fatigue.toml" "$T/fatk" 3000
if [ -s "$T/fatk/checkpoint/state.ckpt" ] && "$LDEM" resume "$T/fatk" --no-plot >/dev/null 2>"$T/stderr" &&
  same_fatigue "$T/fatk"; then ok; else bad "fatigue law resumed after a hard kill: $(cat "$T/stderr")"; fi
# Cycle jumping: the same plate moved up and down at 1000 Hz with a long life; a run killed
# after a checkpoint, inside the jumps, resumes to the same bytes.
sed -e 's/^e_p = 1.0e-4 .*/e_p = 1.0e-4\nlaw = "bilinear_fatigue"\n\n[fatigue]\nA = 1.0e18\nm = 4.0\njump = true/' \
  -e 's/^value = \[0.0, 0.0, 0.02\]/value = [0.0, 0.0, 0.002]/' \
  -e 's/^ramp = 2.0e-4/function = [{ type = "growing_sine", amplitude = 1.0, frequency = 1000.0, t_start = 0.0, tau = 1.0 }]/' \
  -e 's/^end = 4.0e-3 .*/end = 0.02/' -e 's/^energy_every = 50/energy_every = 100/' "$GOOD" >"$T/jump.toml"
"$LDEM" run "$T/jump.toml" --out "$T/jump1" --no-plot >/dev/null 2>"$T/stderr" || bad "jump run: $(cat "$T/stderr")"
# (a term that ends would not keep its cycles through a jump: refused)
sed 's/tau = 1.0 }]/tau = 1.0, t_end = 0.01 }]/' "$T/jump.toml" >"$T/jump_end.toml"
expect_error jump_t_end "fatigue.jump: expected loads whose terms go on to the end (a jump skips their cycles), got t_end = 0.01 s" "$T/jump_end.toml"
grep -q '"jumped_cycles": [1-9]' "$T/jump1/summary.json" && ok || bad "no cycles jumped: $(grep jumped "$T/jump1/summary.json")"
kill_after_checkpoint "$T/jump.toml" "$T/jumpk" 20000
if [ -s "$T/jumpk/checkpoint/state.ckpt" ] && "$LDEM" resume "$T/jumpk" --no-plot >/dev/null 2>"$T/stderr" &&
  cmp -s "$T/jump1/energy.csv" "$T/jumpk/energy.csv" && cmp -s "$T/jump1/events.csv" "$T/jumpk/events.csv" &&
  grep -q "$(grep jumped_cycles "$T/jump1/summary.json")" "$T/jumpk/summary.json"; then ok; else bad "jumping run resumed after a hard kill: $(cat "$T/stderr")"; fi
# Bad checkpoints are refused with their reason, and nothing is changed.
timeout -s INT --preserve-status 0.3 "$LDEM" run "$T/case.toml" --out "$T/bad" --no-plot >/dev/null 2>&1
cp "$T/bad/checkpoint/state.ckpt" "$T/good.ckpt"
# Every file of a folder with its checksum (the checkpoint aside): what a refused resume must
# leave as it was.
fingerprint() { (cd "$1" && find . -path ./checkpoint -prune -o -type f -print0 | sort -z | xargs -0 md5sum); }
expect_resume_error() {
  local before
  before=$(fingerprint "$T/bad")
  "$LDEM" resume "$T/bad" --no-plot >/dev/null 2>"$T/stderr"
  local rc=$?
  if [ $rc -eq 2 ] && grep -q -- "$1" "$T/stderr" && [ "$(fingerprint "$T/bad")" = "$before" ]; then ok; else bad "resume with $2: rc $rc, $(cat "$T/stderr")"; fi
  cp "$T/good.ckpt" "$T/bad/checkpoint/state.ckpt"
}
head -c 1000 "$T/good.ckpt" >"$T/bad/checkpoint/state.ckpt"
expect_resume_error "truncated checkpoint" "a truncated checkpoint"
printf '\xff' | dd of="$T/bad/checkpoint/state.ckpt" bs=1 seek=5000 conv=notrunc 2>/dev/null
expect_resume_error "checksum mismatch" "a corrupt checkpoint"
printf '\x09' | dd of="$T/bad/checkpoint/state.ckpt" bs=1 seek=8 conv=notrunc 2>/dev/null
expect_resume_error "format version 9" "another format version"
printf '\x03' | dd of="$T/bad/checkpoint/state.ckpt" bs=1 seek=8 conv=notrunc 2>/dev/null
expect_resume_error "format version 3, written by an older ldem" "an older format version"
# A checkpoint must belong to the folder it is in, and the folder must hold what it recorded;
# each check comes before the first change, so that putting things back makes the run whole.
sed 's/^title = .*/title = "another case"/' "$T/case.toml" >"$T/other.toml"
timeout -s INT --preserve-status 0.3 "$LDEM" run "$T/other.toml" --out "$T/other" --no-plot >/dev/null 2>&1
cp "$T/other/checkpoint/state.ckpt" "$T/bad/checkpoint/state.ckpt"
expect_resume_error "case.resolved.toml: changed since the checkpoint was written (or the checkpoint is another run's)" "another case's checkpoint"
timeout -s INT --preserve-status 0.8 "$LDEM" run "$T/case.toml" --out "$T/later" --no-plot >/dev/null 2>&1
cp "$T/later/checkpoint/state.ckpt" "$T/bad/checkpoint/state.ckpt"
expect_resume_error "energy.csv: does not begin with the [0-9]* bytes the checkpoint" "a later checkpoint of the same case"
mv "$T/bad/lattice_000000.vtu" "$T/snapshot.vtu"
expect_resume_error "lattice_000000.vtu: missing (the checkpoint recorded" "a deleted snapshot"
mv "$T/snapshot.vtu" "$T/bad/lattice_000000.vtu"
cp "$T/bad/case.resolved.toml" "$T/resolved.toml"
echo "# edited" >>"$T/bad/case.resolved.toml"
expect_resume_error "case.resolved.toml: changed since the checkpoint" "an edited case.resolved.toml"
cp "$T/resolved.toml" "$T/bad/case.resolved.toml"
if "$LDEM" resume "$T/bad" --no-plot >/dev/null 2>"$T/stderr" && same_as_ref "$T/bad"; then ok; else bad "resume once all is put back: $(cat "$T/stderr")"; fi
cp "$T/good.ckpt" "$T/bad/checkpoint/state.ckpt"
echo "# changed" >>"$T/case.toml"
expect_resume_error "the case file changed since the checkpoint" "a changed case"
# A finished run goes on from its end checkpoint: the tutorial plate run to 2 ms and then
# resumed with --end 4 ms writes, byte for byte, what one run to 4 ms with the same output
# intervals writes; summary.json says where it was continued. An end before the checkpoint's
# time is refused and changes nothing.
sed -e 's/^end = 4.0e-3/end = 2.0e-3/' -e 's/^energy_every = 50/energy_every = 50\nvtu_every = 300/' "$GOOD" >"$T/short.toml"
sed -e 's/^energy_every = 50/energy_every = 50\nvtu_every = 300/' "$GOOD" >"$T/long.toml"
"$LDEM" run "$T/long.toml" --out "$T/long" --no-plot >/dev/null 2>&1
"$LDEM" run "$T/short.toml" --out "$T/cont" --no-plot >/dev/null 2>&1
[ -s "$T/cont/checkpoint/state.ckpt" ] && ok || bad "no end checkpoint"
before=$(fingerprint "$T/cont")
"$LDEM" resume "$T/cont" --end 1.0e-3 >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q -- "--end: expected a time after the checkpoint's, t = 0.00200" "$T/stderr" &&
  [ "$(fingerprint "$T/cont")" = "$before" ] && ok || bad "resume --end before the checkpoint: rc $rc, $(cat "$T/stderr")"
"$LDEM" resume "$T/cont" --end 4.0e-3 >/dev/null 2>"$T/stderr" || bad "resume --end: $(cat "$T/stderr")"
for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/long" | grep '\.vtu$'); do
  cmp -s "$T/long/$f" "$T/cont/$f" || bad "resume --end: $f differs from the run to the later end"
done
[ "$(ls "$T/long" | grep -c '\.vtu$')" = "$(ls "$T/cont" | grep -c '\.vtu$')" ] && ok || bad "resume --end: other snapshots"
grep -q '"continued": \[{"step": [0-9]*, "time": 0.00200[0-9]*, "end_time": 0.004}\]' "$T/cont/summary.json" &&
  grep -q '"end_time": 0.004' "$T/cont/summary.json" && ok || bad "resume --end: summary.json: $(cat "$T/cont/summary.json")"
# A run goes on under another case file (--case): the 2 ms run resumed from its end checkpoint
# under a copy of the 4 ms case writes the 4 ms run's bytes, replaces case.resolved.toml with
# the new case's (the run's kept as case.resolved.until_step_<n>.toml) and names the case in
# summary.json; a case with another material is refused and changes nothing.
"$LDEM" run "$T/short.toml" --out "$T/chg" --no-plot >/dev/null 2>&1
cp "$T/long.toml" "$T/again.toml"
sed 's/^Gf = 10.0 /Gf = 12.0 /' "$T/long.toml" >"$T/othermat.toml"
before=$(fingerprint "$T/chg")
"$LDEM" resume "$T/chg" --case "$T/othermat.toml" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "othermat.toml: \[material\] differs from the run's" "$T/stderr" &&
  [ "$(fingerprint "$T/chg")" = "$before" ] && ok || bad "resume --case with another material: rc $rc, $(cat "$T/stderr")"
"$LDEM" resume "$T/chg" --case "$T/again.toml" >/dev/null 2>"$T/stderr" || bad "resume --case: $(cat "$T/stderr")"
for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/long" | grep '\.vtu$'); do
  cmp -s "$T/long/$f" "$T/chg/$f" || bad "resume --case: $f differs from the run to the later end"
done
cmp -s "$T/long/case.resolved.toml" "$T/chg/case.resolved.toml" && ls "$T/chg"/case.resolved.until_step_*.toml >/dev/null 2>&1 &&
  grep -q "\"case\": \"$(realpath "$T/again.toml")\"}\]" "$T/chg/summary.json" && ok || bad "resume --case: resolved case or summary.json: $(ls "$T/chg"), $(grep continued "$T/chg/summary.json")"
"$LDEM" resume "$T/nowhere" >/dev/null 2>"$T/stderr"
[ $? -eq 2 ] && grep -q "no checkpoint to resume from" "$T/stderr" && ok || bad "resume without a checkpoint"

# A numerical blow-up (an absurd imposed velocity) is caught within 10 steps, with its node.
sed 's/^value = \[0.0, 0.0, 0.02\]/value = [0.0, 0.0, 1.0e300]/' "$GOOD" >"$T/blowup.toml"
"$LDEM" run "$T/blowup.toml" --out "$T/blowup" --no-plot >/dev/null 2>"$T/stderr"
rc=$?
if [ $rc -eq 3 ] && grep -q "numerical blow-up detected at step [0-9]*" "$T/stderr" && grep -q "node [0-9]* at (" "$T/stderr" &&
  [ -s "$T/blowup/energy.csv" ]; then ok; else bad "blow-up: rc $rc, $(cat "$T/stderr")"; fi

# A heterogeneous material: fields.csv and fields.png, and the per-bar fields in the VTU.
sed 's/^Gf = 10.0 .*/Gf = { type = "weibull", mean = 10.0, cv = 0.1, seed = 3 }/; s/^end = 4.0e-3/end = 2.0e-4/' "$GOOD" >"$T/weibull.toml"
if "$LDEM" run "$T/weibull.toml" --out "$T/weibull" >/dev/null 2>"$T/stderr" && [ -s "$T/weibull/fields.png" ] &&
  [ "$(head -1 "$T/weibull/fields.csv")" = "bar,x,y,z,E,Gf,e_p,e_r" ] &&
  grep -q 'Name="Gf"' "$T/weibull/lattice_000000.vtu"; then ok; else bad "Weibull fields: $(cat "$T/stderr")"; fi

# A choice of snapshot arrays (output.vtu_arrays): the snapshots hold those alone, read by VTK;
# a name the run does not have is refused before any output.
sed 's/^energy_every = 50/energy_every = 50\nvtu_arrays = ["displacement", "damage"]/' "$GOOD" >"$T/arrays.toml"
"$LDEM" run "$T/arrays.toml" --out "$T/arrays" --no-plot >/dev/null 2>"$T/stderr" &&
  /usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/arrays" | has "arrays \['damage', 'displacement'\]" &&
  [ "$(stat -c %s "$T/arrays/lattice_000001.vtu")" -lt "$(stat -c %s "$T/long/lattice_000001.vtu")" ] && ok || bad "vtu_arrays: $(cat "$T/stderr")"
sed 's/^energy_every = 50/energy_every = 50\nvtu_arrays = ["displacement", "dmg"]/' "$GOOD" >"$T/arrays_bad.toml"
"$LDEM" run "$T/arrays_bad.toml" --out "$T/arrays_bad" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && [ ! -e "$T/arrays_bad" ] && grep -q 'arrays_bad.toml:[0-9]*: output.vtu_arrays: expected names among "displacement", "velocity", "stress", "node_strain", "damage", "state", "axial_force", "strain", "E", "Gf", "e_p", "e_r" (this law.s), got "dmg"' "$T/stderr" && ok || bad "vtu_arrays with a bad name: rc $rc, $(cat "$T/stderr")"

# The stress and the strain at the nodes, named: a symmetric tensor per point each, which VTK
# reads.
sed 's/^energy_every = 50/energy_every = 50\nvtu_arrays = ["damage", "stress", "node_strain"]/' "$T/long.toml" >"$T/stress.toml"
"$LDEM" run "$T/stress.toml" --out "$T/stress" --no-plot >/dev/null 2>"$T/stderr" &&
  grep -q 'Name="stress" NumberOfComponents="6"' "$T/stress/lattice_000001.vtu" &&
  grep -q 'Name="node_strain" NumberOfComponents="6"' "$T/stress/lattice_000001.vtu" &&
  /usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/stress" >/dev/null && ok ||
  bad "vtu_arrays with stress: $(cat "$T/stderr")"

# Compressed snapshots (output.vtu_compression = "zlib"): VTK reads them, every array the same
# numbers as the uncompressed run's, and they are smaller.
sed 's/^energy_every = 50/energy_every = 50\nvtu_compression = "zlib"/' "$T/long.toml" >"$T/zlib.toml"
if "$LDEM" run "$T/zlib.toml" --out "$T/zlib" --no-plot >/dev/null 2>"$T/stderr" &&
  /usr/bin/python3 "$SRC/tests/check_outputs.py" "$T/zlib" >/dev/null &&
  /usr/bin/python3 - "$T/long" "$T/zlib" <<'PY'
import sys, os, vtk
from vtk.util.numpy_support import vtk_to_numpy
import numpy as np
a_dir, b_dir = sys.argv[1], sys.argv[2]
names = sorted(f for f in os.listdir(a_dir) if f.endswith(".vtu"))
assert names == sorted(f for f in os.listdir(b_dir) if f.endswith(".vtu"))
for name in names:
    out = []
    for d in (a_dir, b_dir):
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(os.path.join(d, name))
        r.Update()
        out.append(r.GetOutput())
    a, b = out
    for data in ("GetPointData", "GetCellData"):
        A, B = getattr(a, data)(), getattr(b, data)()
        assert A.GetNumberOfArrays() == B.GetNumberOfArrays(), name
        for i in range(A.GetNumberOfArrays()):
            n = A.GetArrayName(i)
            assert np.array_equal(vtk_to_numpy(A.GetArray(n)), vtk_to_numpy(B.GetArray(n))), (name, n)
    assert np.array_equal(vtk_to_numpy(a.GetCells().GetConnectivityArray()),
                          vtk_to_numpy(b.GetCells().GetConnectivityArray())), name
    assert os.path.getsize(os.path.join(b_dir, name)) < os.path.getsize(os.path.join(a_dir, name)) / 2, name
PY
then ok; else bad "compressed snapshots: $(cat "$T/stderr")"; fi

# crack.png of a 3-D body: the tutorial plate made 12 x 8 x 10 modules, notched through its
# 8-module depth, cracks across z in an x-y plane: the default shows that crack face on (x-y,
# coloured by z) beside a slice through the middle of the thinnest direction (y = 20 mm);
# --slice and --view choose; a bad one is refused (exit 2, what was expected) before any
# picture is written.
sed 's/^modules = \[40, 1, 20\].*/modules = [12, 8, 10]/; s/^plane_strain = .*//; s/^origin = .*/origin = [-0.0001, -0.001, 0.02625]/; s/^edge1 = .*/edge1 = [0.0251, 0.0, 0.0]/; s/^edge2 = .*/edge2 = [0.0, 0.042, 0.0]/; s/^at = .*/at = [0.0275, 0.0025, 0.025]/' "$GOOD" >"$T/cube.toml"
if "$LDEM" run "$T/cube.toml" --out "$T/cube" >"$T/stdout" 2>"$T/stderr" &&
  grep -q "crack.png: the crack face on, x-y (colour: z); slice y = 20 mm" "$T/stdout" && [ -s "$T/cube/crack.png" ] &&
  "$LDEM" plot "$T/cube" --slice x=0.03 | has "crack.png: slice x = 30 mm" &&
  "$LDEM" plot "$T/cube" --view xz | has "crack.png: every bar projected on the x-z plane"; then ok; else bad "3-D crack.png: $(cat "$T/stdout" "$T/stderr")"; fi
rm -f "$T/cube/crack.png" "$T/cube/energy.png"
"$LDEM" plot "$T/cube" --slice y=1 >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "slice: expected y between 0 and 0.04 m (the body); got 1" "$T/stderr" && [ ! -e "$T/cube/crack.png" ] && [ ! -e "$T/cube/energy.png" ] && ok || bad "bad --slice: rc $rc, $(cat "$T/stderr")"
"$LDEM" plot "$T/cube" --view xx >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "view: expected two different axes among x, y, z" "$T/stderr" && ok || bad "bad --view: rc $rc, $(cat "$T/stderr")"
# `ldem plot` on a folder that is not an output folder: an error naming the file, no traceback.
mkdir -p "$T/not-a-run"
"$LDEM" plot "$T/not-a-run" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "not-a-run/case.resolved.toml: cannot read the resolved case" "$T/stderr" &&
  ! grep -q "Traceback\|matplotlib" "$T/stderr" && ok || bad "ldem plot on a non-output folder: rc $rc, $(cat "$T/stderr")"

# The crack analysis: a shipped plate with [analysis] crack = true leaves crack_tip.csv,
# crack_speed.png and analysis.crack; `ldem analyze crack` on a folder that is not an output
# folder is an error naming the file.
FGM="$SRC/cases/fgm_plate/homogeneous.toml"
if "$LDEM" run "$FGM" --out "$T/fgm" >/dev/null 2>"$T/stderr" &&
  [ "$(head -1 "$T/fgm/crack_tip.csv")" = "time,branch,tip_x,tip_z,length,speed,speed_se,softening_length,softened_ahead,flagged,jump" ] && [ -s "$T/fgm/crack_speed.png" ] &&
  grep -q '"branching_length_m"' "$T/fgm/summary.json" && grep -q '"secondary_branching"' "$T/fgm/summary.json" &&
  grep -q '"max_crack_speed_m_s"' "$T/fgm/summary.json" && grep -q '"branch_angles_deg"' "$T/fgm/summary.json" &&
  "$LDEM" analyze crack "$T/fgm" | has "^crack: length"; then ok; else bad "crack analysis: $(cat "$T/stderr")"; fi
"$LDEM" analyze crack "$T" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "case.resolved.toml: cannot read the resolved case" "$T/stderr" && ok || bad "analyze on a non-output folder: rc $rc, $(cat "$T/stderr")"

# The fatigue analysis: the coarse fatigue plate, cut short after a few cycles, leaves
# fatigue.csv, the front and the fatigue pictures, and analysis.fatigue with the Paris keys;
# `ldem analyze fatigue` on a run without a cyclic load is an error that says what is missing.
sed 's/^end = 8.1667 .*/end = 0.13/; s/^vtu_every = .*/vtu = false/' "$SRC/cases/subcritical_fatigue_coarse.toml" >"$T/fatigue.toml"
if "$LDEM" run "$T/fatigue.toml" --out "$T/fatigue" >/dev/null 2>"$T/stderr" &&
  [ "$(head -1 "$T/fatigue/fatigue.csv")" = "N,a,da_dN,delta_K,in_fit" ] &&
  [ "$(head -1 "$T/fatigue/fatigue_front.csv")" = "t,N,a" ] && [ -s "$T/fatigue/fatigue_front.png" ] &&
  [ -s "$T/fatigue/fatigue_load.png" ] && [ -s "$T/fatigue/fatigue_paris.png" ] &&
  grep -q '"paris_m"' "$T/fatigue/summary.json" && grep -q '"unstable_t_over_tmax"' "$T/fatigue/summary.json" &&
  "$LDEM" analyze fatigue "$T/fatigue" --window cycles | has "no unstable failure"; then ok; else bad "fatigue analysis: $(cat "$T/stderr")"; fi
"$LDEM" analyze fatigue "$T/fgm" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "the fatigue analysis needs a cyclic \[\[load\]\]" "$T/stderr" && ok || bad "fatigue analysis without loads: rc $rc, $(cat "$T/stderr")"

# An ensemble: its table with median and range, one folder per run; a bad case file stops it
# before anything is written.
if "$LDEM" ensemble "$FGM" --runs 2 --no-plot --out "$T/ens" >/dev/null 2>"$T/stderr" &&
  [ -s "$T/ens/homogeneous/run_01/summary.json" ] && grep -q "^| median" "$T/ens/ensemble.md" &&
  [ "$(wc -l <"$T/ens/ensemble.csv")" -eq 3 ] && grep -q '"perturbation"' "$T/ens/homogeneous/run_01/summary.json"; then ok; else bad "ensemble: $(cat "$T/stderr")"; fi
# (its runs side by side, as many as the cores, each one's output in its folder's log)
cores=$(nproc)
grep -q "ensemble of 2 runs, $((cores < 2 ? 1 : 2)) at a time on $cores cores" "$T/stderr" &&
  grep -q "ldem: done" "$T/ens/homogeneous/run_00.log" && grep -q "ldem: done" "$T/ens/homogeneous/run_01.log" &&
  ok || bad "ensemble's runs side by side: $(cat "$T/stderr")"
# Two runs started without --threads share the cores (util/core_share.hpp): the second finds
# the first and takes its share from its first step, the first gives up a share within a second
# (or had one from the start, if other tests' runs were going on: they are counted too, so the
# counts are not fixed here; tests/test_core_share.cpp has them). On one core nothing is shared.
if [ "$cores" -ge 2 ]; then
  { sed 's/^end = .*/end = 2.0e-3/' "$FGM"; printf '\n[output]\nvtu = false\n'; } >"$T/share_long.toml"
  sed 's/^end = .*/end = 1.5e-4/' "$T/share_long.toml" >"$T/share_short.toml"
  "$LDEM" run "$T/share_long.toml" --out "$T/share_a" --no-plot >/dev/null 2>"$T/share_a.err" &
  a=$!
  sleep 1
  "$LDEM" run "$T/share_short.toml" --out "$T/share_b" --no-plot >/dev/null 2>"$T/share_b.err"
  sleep 2.5
  kill -TERM $a 2>/dev/null
  wait $a
  shared="ldem: [0-9]* runs on this machine's $cores cores: [0-9]* threads* from step"
  grep -q "$shared 0\$" "$T/share_b.err" && grep -q "$shared" "$T/share_a.err" && ok ||
    bad "two runs sharing the cores: $(cat "$T/share_a.err" "$T/share_b.err")"
fi
"$LDEM" ensemble "$FGM" "$T/nope.toml" --runs 2 --out "$T/ens_bad" >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && [ ! -e "$T/ens_bad" ] && grep -q "nope.toml: cannot read the case file" "$T/stderr" && ok || bad "ensemble with a bad case: rc $rc, $(cat "$T/stderr")"

# A full disk: the output folder on a small tmpfs (root only; skipped otherwise). The run
# stops with exit 2 and says which file failed; no file under its final name is cut short:
# every snapshot has the size of the first, a log under its final name or kept as .part ends
# with a whole row, and a snapshot that failed leaves no .part behind.
if [ "$(id -u)" -eq 0 ] && mkdir -p "$T/tmpfs" && mount -t tmpfs -o size=600k tmpfs "$T/tmpfs" 2>/dev/null; then
  "$LDEM" run "$GOOD" --out "$T/tmpfs/vtu" --no-plot >/dev/null 2>"$T/stderr"
  rc=$?
  whole=1
  first=$(stat -c %s "$T/tmpfs/vtu/lattice_000000.vtu" 2>/dev/null || echo 0)
  for f in "$T/tmpfs/vtu"/lattice_*.vtu; do [ "$(stat -c %s "$f")" = "$first" ] || whole=0; done
  ls "$T/tmpfs/vtu"/*.vtu.part >/dev/null 2>&1 && whole=0
  for f in "$T/tmpfs/vtu"/*.csv "$T/tmpfs/vtu"/*.csv.part; do [ -e "$f" ] && [ "$(tail -c 1 "$f" | od -An -c | tr -d ' ')" != '\n' ] && whole=0; done
  [ $rc -eq 2 ] && grep -q "write failed (No space left on device)" "$T/stderr" && [ $whole = 1 ] && ok || bad "full disk, snapshots: rc $rc, $(cat "$T/stderr"), $(ls -l "$T/tmpfs/vtu")"
  umount "$T/tmpfs"
  mount -t tmpfs -o size=48k tmpfs "$T/tmpfs"
  sed 's/^energy_every = 50/energy_every = 5\nvtu = false/' "$GOOD" >"$T/novtu.toml"
  "$LDEM" run "$T/novtu.toml" --out "$T/tmpfs/logs" --no-plot >/dev/null 2>"$T/stderr"
  rc=$?
  whole=1
  for f in "$T/tmpfs/logs"/*.csv "$T/tmpfs/logs"/*.csv.part; do [ -e "$f" ] && [ "$(tail -c 1 "$f" | od -An -c | tr -d ' ')" != '\n' ] && whole=0; done
  [ $rc -eq 2 ] && grep -q "whole rows, are kept in .*\.csv\.part" "$T/stderr" && [ $whole = 1 ] && [ ! -e "$T/tmpfs/logs/summary.json" ] && ok || bad "full disk, logs: rc $rc, $(cat "$T/stderr"), $(ls -l "$T/tmpfs/logs")"
  umount "$T/tmpfs"
fi

# The lowest eigenfrequencies of the tutorial plate: a table with a positive frequency and the
# comparison with the step; a count below 1 or not below the free DOF is refused.
"$LDEM" modes "$GOOD" --count 3 >"$T/stdout" 2>"$T/stderr" &&
  awk '$1 ~ /^[0-9]+$/ && $2 + 0 > 0 { found = 1 } END { exit !found }' "$T/stdout" &&
  grep -q "^lowest frequency [0-9.e+]* Hz: its period .* time steps" "$T/stdout" && ok || bad "ldem modes: $(cat "$T/stderr")"
"$LDEM" modes "$GOOD" --count 0 >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "^ldem: error: --count: expected a number of modes >= 1, got 0" "$T/stderr" && ok || bad "modes --count 0: rc $rc, $(cat "$T/stderr")"
"$LDEM" modes "$GOOD" --count 100000 >/dev/null 2>"$T/stderr"
rc=$?
[ $rc -eq 2 ] && grep -q "below the number of free DOF (4880), got 100000" "$T/stderr" && ok || bad "modes --count 100000: rc $rc, $(cat "$T/stderr")"

# Every shipped case is valid.
while IFS= read -r c; do
  "$LDEM" check "$c" >/dev/null 2>"$T/stderr" && ok || bad "ldem check $c: $(cat "$T/stderr")"
done < <(find "$SRC/cases" -name '*.toml' | sort)

# The case-format reference is the one the declarations generate.
"$LDEM" case-format | diff -q - "$SRC/docs/case-format.md" >/dev/null && ok || bad "docs/case-format.md is stale: run ldem case-format > docs/case-format.md"

echo "cli: $pass passed, $fails failed"
[ $fails -eq 0 ]
