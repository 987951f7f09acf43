#!/usr/bin/env bash
# Fuzzes the case-file reader with libFuzzer (clang, AddressSanitizer, UndefinedBehaviorSanitizer)
# for a bounded time, from a corpus of the shipped cases and malformed variants.
# usage: fuzz.sh SOURCE_DIR [SECONDS=30]
set -euo pipefail
SRC=$1
SECONDS_MAX=${2:-30}
T=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$T"' EXIT
# -DNDEBUG as in the release build: toml++ 3.3's own debug assertion fires on a table header
# split by a newline ("[\n[x]]"), which a release build reports as malformed TOML.
clang++ -std=c++20 -O1 -g -DNDEBUG -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -I"$SRC/src" "$SRC/tests/fuzz_case.cpp" "$SRC/src/io/case_parse.cpp" "$SRC/src/io/case_keys.cpp" \
  "$SRC/src/lattice/node_set.cpp" "$SRC/src/lattice/lattice.cpp" "$SRC/src/lattice/shape.cpp" \
  "$SRC/src/solver/time_function.cpp" \
  "$SRC/src/util/text_file.cpp" \
  -lfmt -ltomlplusplus -o "$T/fuzz_case"
mkdir -p "$T/corpus"
i=0
for f in $(find "$SRC/cases" -name '*.toml'); do
  cp "$f" "$T/corpus/case$i.toml"
  sed 's/= /= = /' "$f" >"$T/corpus/bad$i.toml"
  sed 's/\[\[/[/' "$f" >"$T/corpus/table$i.toml"
  i=$((i + 1))
done
"$T/fuzz_case" -max_total_time="$SECONDS_MAX" -rss_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$T/" "$T/corpus" 2>"$T/log" || { tail -40 "$T/log"; ls "$T"; exit 1; }
grep -E "stat::number_of_executed_units|Done" "$T/log" | tail -2
echo "fuzz: 1 passed, 0 failed"
