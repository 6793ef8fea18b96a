#!/usr/bin/env bash
# Set-up and main job: installs everything, then bakes the built-in Cornell
# box (out/cornell_box.glb), takes a headless snapshot of the bake
# (out/cornell_box_bake.png) and renders its quality frame by lightcuts
# (out/cornell_box.png and .exr).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
.venv/bin/voxbake info cornell_box
.venv/bin/voxbake bake cornell_box --preset default -o out/cornell_box.glb --stats out/cornell_box_bake_stats.json
.venv/bin/voxview snapshot out/cornell_box.glb --width 512 --height 512 -o out/cornell_box_bake.png
.venv/bin/voxbake render cornell_box --method lightcuts --preset default --width 512 --height 512 \
  -o out/cornell_box.exr --stats out/cornell_box_stats.json
.venv/bin/python -c "from baker import read_exr, write_image; write_image('out/cornell_box.png', read_exr('out/cornell_box.exr'))"
echo "demo: wrote out/cornell_box.glb (walk through it: .venv/bin/voxview out/cornell_box.glb),"
echo "      out/cornell_box_bake.png, out/cornell_box.png, out/cornell_box.exr"
