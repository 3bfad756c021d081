#!/usr/bin/env bash
# Configures and builds Relief in ./build (or $RELIEF_BUILD_DIR), Release.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${RELIEF_BUILD_DIR:-build}"
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$build_dir" -j"$(nproc)"
