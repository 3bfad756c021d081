#!/usr/bin/env bash
# The main job on the sample that ships in the repo: install what is missing,
# build, compress the sample into an archive, look at it, query a box, render a
# preview, decompress everything and measure the error against the original.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
# Only the relief tool: the demo runs nothing else, and the test suites and
# benchmarks would take most of its time to compile.
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target relief
out=build/demo
rm -rf "$out" && mkdir -p "$out"
sample=tests/data/kinect_milk_scene_rgb.ply
relief=./build/tools/relief

echo "== compress $sample"
"$relief" compress "$sample" -o "$out/kinect.relief"
echo "== info"
"$relief" info "$out/kinect.relief"
echo "== query a 40 cm box around the middle of the table"
"$relief" query "$out/kinect.relief" --box -0.2,-0.2,-1.6,0.2,0.2,-0.8 -o "$out/box.ply"
echo "== preview (top-down, level of detail 4)"
"$relief" preview "$out/kinect.relief" --lod 4 -o "$out/preview.png"
echo "== decompress and compare with the original"
"$relief" decompress "$out/kinect.relief" -o "$out/kinect_decoded.ply"
"$relief" eval "$sample" "$out/kinect_decoded.ply"
echo "== files in $out"
ls -l "$out"
