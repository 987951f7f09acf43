#!/usr/bin/env bash
# What a shaped body costs: a cylinder cut from a square prism against the prism itself (and
# the prism with a Weibull E, whose per-bar material takes the per-bar kernels), an elastic
# pull of N^3 modules for 512 steps, in alternating rounds so that the machine's drift hits all
# alike. Output: every run's bar updates per second (per present bar) and bytes per present
# module (summary.json), then the medians of the per-round ratios cylinder / prism.
#
# usage: bench/compare_shapes.sh LDEM [ROUNDS=3] [N=64]
#   THREADS (default 2). Each run without snapshots, analyses or plots.
set -euo pipefail
LDEM=$(realpath "${1:?ldem}")
ROUNDS=${2:-3}
N=${3:-64}
THREADS=${THREADS:-2}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The prism: N^3 modules of 10 mm, elastic (e_p = 1e-3 is not reached), its base held in z, its
# top pulled at 0.01 m/s, to 512 steps; the other bodies add to it. No checkpoint at the end:
# the run's wall time (summary.json) would count writing it, and its file holds every module of
# the box, present or not (about 0.3 s at 64^3, as long as 150 steps of the prism).
case_file() { # name extra
  local size
  size=$(/usr/bin/python3 -c "print($N * 0.01)")
  cat >"$WORK/$1.toml" <<TOML
[lattice]
modules = [$N, $N, $N]
L = 0.01

[material]
E = $([ "$1" = weibull ] && echo '{ type = "weibull", mean = 30.0e9, cv = 0.1, seed = 1 }' || echo 30.0e9)
rho = 2400.0
Gf = 1000.0
e_p = 1.0e-3

[[node_set]]
name = "base"
face = "z-"

[[node_set]]
name = "top"
face = "z+"

[[fixed]]
set = "base"
dofs = "z"

[[velocity]]
set = "top"
dofs = "z"
value = [0.0, 0.0, 0.01]

[time]
end = 8.0e-4

[output]
energy_every = 1000
vtu = false
plots = false
end_checkpoint = false
$2
TOML
  if [ "$1" = cylinder ]; then
    local r
    r=$(/usr/bin/python3 -c "print($N * 0.005)")
    # (its axis through the whole prism: from below its base to above its top)
    printf '\n[[geometry]]\nadd = { type = "cylinder", start = [%s, %s, -1], end = [%s, %s, %s], radius = %s }\n' \
      "$r" "$r" "$r" "$r" "$((N + 1))" "$r" >>"$WORK/$1.toml"
  fi
}
field() { sed -n "s/.*\"$2\": \\([^,}]*\\).*/\\1/p" "$1/summary.json" | head -1; }

for body in prism cylinder weibull; do
  case_file "$body" ""
done
declare -A rate bytes
ratios=() mem=()
for r in $(seq "$ROUNDS"); do
  for body in prism cylinder weibull; do
    rm -rf "$WORK/out"
    "$LDEM" run "$WORK/$body.toml" --out "$WORK/out" --threads "$THREADS" --no-plot \
      >"$WORK/log" 2>&1 || { cat "$WORK/log" >&2; exit 1; }
    rate[$body]=$(field "$WORK/out" bar_updates_per_s)
    bytes[$body]=$(field "$WORK/out" bytes_per_module)
    echo "round $r $body: ${rate[$body]} bar updates/s, ${bytes[$body]} bytes/module"
  done
  ratios+=("$(/usr/bin/python3 -c "print(${rate[cylinder]} / ${rate[prism]})")")
  mem+=("$(/usr/bin/python3 -c "print(${bytes[cylinder]} / ${bytes[prism]})")")
done
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }
echo "cylinder / prism, bar updates per second per present bar: median $(median "${ratios[@]}")" \
  "(rounds: ${ratios[*]})"
echo "cylinder / prism, bytes per present module: median $(median "${mem[@]}") (rounds: ${mem[*]})"
