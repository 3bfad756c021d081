#!/usr/bin/env bash
# Installs, builds and runs every test: the Release suite, then the same suite
# built with AddressSanitizer + UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)"
if [[ "${RELIEF_SKIP_SANITIZERS:-0}" != "1" ]]; then
  echo "== the suite again under ASan/UBSan =="
  # -O1 -g1: a cold sanitised build takes about as long as its tests on a
  # 2-core machine (13 and 15-20 min), so compile time matters as much as
  # code speed here.
  RELIEF_BUILD_DIR=build-asan scripts/build.sh -DRELIEF_SANITIZE=ON -DRELIEF_BUILD_BENCH=OFF \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$(nproc)" -E "shared data"
fi
