#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan/UBSan) and runs one of them.
#   scripts/fuzz.sh TARGET [SECONDS] [extra libFuzzer flags...]
# TARGET: chunk ply las xyz pcd e57 archive laz_writer stream polygon. New inputs go to build-fuzz/corpus/
# TARGET (seeded from tests/fuzz/corpus/TARGET), crashes to build-fuzz/
# artifacts/TARGET/. Needs RELIEF_WITH_FUZZ=1 scripts/install-deps.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${1:?usage: scripts/fuzz.sh TARGET [SECONDS] [libFuzzer flags...]}
seconds=${2:-600}
shift $(( $# >= 2 ? 2 : 1 ))
# Largest input per target: a few times the biggest seed, so mutations can
# grow a file without the fuzzer spending its time on megabyte inputs.
case "$target" in
  chunk) max_len=4096 ;;
  ply|xyz|pcd) max_len=2048 ;;
  las) max_len=16384 ;;
  e57) max_len=8192 ;;
  archive) max_len=32768 ;;
  laz_writer) max_len=8192 ;;
  stream) max_len=2048 ;;
  polygon) max_len=4096 ;;
  *) echo "fuzz.sh: unknown target '$target'" >&2; exit 2 ;;
esac
build=${RELIEF_FUZZ_BUILD_DIR:-build-fuzz}
cmake -S . -B "$build" -DRELIEF_FUZZ=ON -DRELIEF_BUILD_TESTS=OFF -DRELIEF_BUILD_BENCH=OFF \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 >/dev/null
cmake --build "$build" -j2 --target "fuzz_$target"
mkdir -p "$build/corpus/$target" "$build/artifacts/$target"
exec nice -n 10 "$build/tests/fuzz/fuzz_$target" -rss_limit_mb=2048 -max_len="$max_len" -timeout=10 \
  -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$build/artifacts/$target/" "$@" \
  "$build/corpus/$target" "tests/fuzz/corpus/$target"
