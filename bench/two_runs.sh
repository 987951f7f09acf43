#!/usr/bin/env bash
# Two runs of one case started together, without --threads, against one alone: each run's loop
# time from its `done` line, ROUNDS times.
#
# usage: bench/two_runs.sh LDEM CASE [ROUNDS=3]
set -euo pipefail
LDEM=$(realpath "${1:?ldem}")
CASE=${2:?case file}
ROUNDS=${3:-3}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
seconds() { grep -oE "in [0-9.]+ s, results" "$1" | grep -oE "[0-9.]+"; }
for r in $(seq "$ROUNDS"); do
  "$LDEM" run "$CASE" --out "$WORK/one" --no-plot --force 2>"$WORK/one.err" >/dev/null
  "$LDEM" run "$CASE" --out "$WORK/a" --no-plot --force 2>"$WORK/a.err" >/dev/null &
  "$LDEM" run "$CASE" --out "$WORK/b" --no-plot --force 2>"$WORK/b.err" >/dev/null
  wait
  echo "round $r: alone $(seconds "$WORK/one.err") s, two at once $(seconds "$WORK/a.err") and $(seconds "$WORK/b.err") s"
done
