#!/usr/bin/env bash
# The main job on the sample that ships in the repo: install, build, compress
# the sample as one chunk, decompress it and print size, bits per point and error.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
./build/tools/relief roundtrip tests/data/kinect_milk_scene_rgb.ply -o build/kinect_reconstructed.ply
