#!/usr/bin/env bash
# Set-up and main job: installs everything, then renders the built-in
# Cornell box with the reference path tracer to out/cornell_box.png (and .exr).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
.venv/bin/voxbake info scenes/cornell_box.glb
.venv/bin/voxbake render scenes/cornell_box.glb --method pathtrace --spp 256 --width 512 --height 512 \
  -o out/cornell_box.exr --stats out/cornell_box_stats.json
.venv/bin/voxbake render scenes/cornell_box.glb --method voxels --preset default --width 512 --height 512 \
  -o out/cornell_box_voxels.png --stats out/cornell_box_voxels_stats.json
.venv/bin/python -c "from baker import read_exr, write_image; write_image('out/cornell_box.png', read_exr('out/cornell_box.exr'))"
echo "demo: wrote out/cornell_box.png, out/cornell_box.exr, out/cornell_box_voxels.png"
