#!/usr/bin/env bash
# Fuzzes `ldem resume` with damaged checkpoints and output folders. One interrupted run of the
# tutorial plate is the seed; each round copies it, damages it one way (a byte of the checkpoint
# flipped, the checkpoint cut short, a log cut short or grown, a file deleted, a byte of
# case.resolved.toml changed, another run's checkpoint swapped in, a byte of a snapshot
# flipped) at a place drawn from the round's seed, and resumes it. A round passes when the
# resume either refuses (exit 2) with the folder exactly as it was (the checkpoint aside), or
# succeeds with the uninterrupted run's bytes (a snapshot damaged by hand stays damaged: that
# file aside). Anything else (a crash, a hang, a refusal that changed the folder, a success
# with other bytes) fails, and the round's seed and damage are printed.
# usage: fuzz_resume.sh LDEM SOURCE_DIR [ROUNDS=40] [SEED=1]
set -uo pipefail
LDEM=$1
SRC=$2
ROUNDS=${3:-40}
SEED=${4:-1}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
sed 's/^end = 4.0e-3/end = 16.0e-3/' "$SRC/cases/tutorial/notched_plate.toml" >"$T/case.toml"
sed 's/^title = .*/title = "another case"/' "$T/case.toml" >"$T/other.toml"
"$LDEM" run "$T/case.toml" --out "$T/ref" --no-plot >/dev/null 2>&1 || { echo "reference run failed"; exit 1; }
# The seed folder: interrupted once its first periodic checkpoint exists.
interrupted() { # CASE DIR
  "$LDEM" run "$1" --out "$2" --no-plot --checkpoint-every 2000 >/dev/null 2>&1 &
  local pid=$!
  for _ in $(seq 3000); do
    [ -s "$2/checkpoint/state.ckpt" ] && break
    sleep 0.01
  done
  kill -INT $pid 2>/dev/null
  wait $pid 2>/dev/null
  [ -s "$2/checkpoint/state.ckpt" ]
}
interrupted "$T/case.toml" "$T/seed" || { echo "no checkpoint in the seed run"; exit 1; }
interrupted "$T/other.toml" "$T/other" || { echo "no checkpoint in the other run"; exit 1; }
fingerprint() { (cd "$1" && find . -path ./checkpoint -prune -o -type f -print0 | sort -z | xargs -0 md5sum); }
# A number in [0, n) from the round's generator (bash's RANDOM, seeded per round).
draw() { echo $(((RANDOM * 32768 + RANDOM) % $1)); }
flip_byte() { # FILE: one byte at a drawn place xor 0x5a
  local size at b
  size=$(stat -c %s "$1")
  [ "$size" -gt 0 ] || return
  at=$(draw "$size")
  b=$(dd if="$1" bs=1 skip="$at" count=1 2>/dev/null | od -An -tu1 | tr -d ' ')
  printf "\\x$(printf %02x $(((${b:-0} ^ 0x5a) & 255)))" | dd of="$1" bs=1 seek="$at" conv=notrunc 2>/dev/null
  echo "flipped byte $at of $(basename "$1")"
}
fails=0
refused=0
resumed=0
for round in $(seq 1 "$ROUNDS"); do
  RANDOM=$((SEED * 100003 + round))
  d="$T/r$round"
  cp -r "$T/seed" "$d"
  skip=""
  case $((round % 8)) in
  0) what=$(flip_byte "$d/checkpoint/state.ckpt") ;;
  1) n=$(draw "$(stat -c %s "$d/checkpoint/state.ckpt")"); truncate -s "$n" "$d/checkpoint/state.ckpt"; what="checkpoint cut to $n bytes" ;;
  2) f=$(ls "$d"/*.csv* | sed -n "$(($(draw "$(ls "$d"/*.csv* | wc -l)") + 1))p"); n=$(draw "$(stat -c %s "$f")"); truncate -s "$n" "$f"; what="$(basename "$f") cut to $n bytes" ;;
  3) f=$(ls "$d"/*.csv* | sed -n "$(($(draw "$(ls "$d"/*.csv* | wc -l)") + 1))p"); head -c "$(($(draw 5000) + 1))" /dev/urandom >>"$f"; what="$(basename "$f") grown" ;;
  4) f=$(find "$d" -path "$d/checkpoint" -prune -o -type f -print | sort | sed -n "$(($(draw "$(find "$d" -path "$d/checkpoint" -prune -o -type f -print | wc -l)") + 1))p"); rm -f "$f"; what="$(basename "$f") deleted" ;;
  5) what=$(flip_byte "$d/case.resolved.toml") ;;
  6) cp "$T/other/checkpoint/state.ckpt" "$d/checkpoint/state.ckpt"; what="another case's checkpoint" ;;
  7) f=$(ls "$d"/lattice_*.vtu | sed -n "$(($(draw "$(ls "$d"/lattice_*.vtu | wc -l)") + 1))p"); what=$(flip_byte "$f"); skip=$(basename "$f") ;;
  esac
  before=$(fingerprint "$d")
  timeout 120 "$LDEM" resume "$d" --no-plot >/dev/null 2>"$T/stderr"
  rc=$?
  verdict=""
  if [ $rc -eq 2 ]; then
    refused=$((refused + 1))
    [ "$(fingerprint "$d")" = "$before" ] || verdict="refused, but changed the folder"
  elif [ $rc -eq 0 ]; then
    resumed=$((resumed + 1))
    for f in energy.csv events.csv probes.csv lattice.pvd $(ls "$T/ref" | grep '\.vtu$'); do
      [ "$f" = "$skip" ] && continue
      cmp -s "$T/ref/$f" "$d/$f" || { verdict="resumed, but $f differs"; break; }
    done
  else
    verdict="exit code $rc"
  fi
  if [ -n "$verdict" ]; then
    echo "FAIL: round $round (seed $SEED), $what: $verdict; $(head -c 400 "$T/stderr")"
    fails=$((fails + 1))
  fi
  rm -rf "$d"
done
echo "fuzz_resume: $ROUNDS rounds ($refused refused, $resumed resumed), $((ROUNDS - fails)) passed, $fails failed"
[ $fails -eq 0 ]
