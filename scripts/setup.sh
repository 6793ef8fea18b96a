#!/usr/bin/env bash
# Installs everything voxgi needs on a fresh Debian/Ubuntu machine: the
# Debian packages for headless OpenGL (EGL on Mesa llvmpipe, Xvfb for a real
# window), a virtual environment in .venv with the package and its Python
# dependencies, and the compiled kernels (numba caches them beside the code,
# so the first real run does not spend 10-30 s compiling). With --web (the
# test command passes it) also node, Chromium and the npm packages that check
# bake files as other tools read them (tests/web).
# Idempotent: skips what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
WEB=0
[ "${1:-}" = "--web" ] && WEB=1
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
pkgs="libegl1 libgl1 libgl1-mesa-dri libgomp1 xvfb xauth"
py_ok=1
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || py_ok=0
missing=""
for p in $pkgs; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
[ "$py_ok" = 1 ] || missing="$missing python3 python3-venv python3-pip"
if [ "$WEB" = 1 ]; then
  dpkg -s chromium >/dev/null 2>&1 || missing="$missing chromium"
  command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || missing="$missing nodejs npm"
fi
if [ -n "$missing" ]; then
  echo "setup: installing Debian packages:$missing"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
# reinstall only when the package's metadata changed (the code itself is installed editable)
stamp=".venv/.voxgi-installed"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing the Python packages into .venv"
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  # setuptools warns on every editable install that a folder named like the package may shadow it:
  # ours is the package itself
  PYTHONWARNINGS="ignore:Editable installation" .venv/bin/python -m pip install -q -e ".[dev]"
  echo "$want" > "$stamp"
fi
if [ "$WEB" = 1 ] && [ ! -d tests/web/node_modules/three ]; then
  echo "setup: installing the npm packages of tests/web (glTF-Validator, three.js, puppeteer-core)"
  (cd tests/web && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
fi
# compile (or load) the kernels of the render methods and the bake's tiers once, on tiny inputs
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "setup: compiling the kernels (once: later runs load them from numba's cache)"
warm() {
  .venv/bin/python -m baker "$@" >"$tmp/log" 2>&1 ||
    { echo "setup: the warm-up run failed:"; cat "$tmp/log"; exit 1; }
}
warm render cornell_box --width 8 --height 8 --method voxels --preset preview --resolution 8 --photons 2000 \
  -o "$tmp/w.png"
warm render cornell_box --width 8 --height 8 --method pathtrace --spp 1 -o "$tmp/w.exr"
warm bake cornell_box --preset preview --resolution 8 --photons 2000 -o "$tmp/w.glb"
# the default preset's lightcuts texels and frames (without these a user's first default bake spends ~15 s compiling)
warm bake cornell_box --preset default --resolution 8 --photons 2000 --direct-vpls 64 --texel-density 8 \
  -o "$tmp/d.glb"
warm render cornell_box --method lightcuts --width 8 --height 8 --resolution 8 --photons 2000 --direct-vpls 64 \
  -o "$tmp/c.png"
warm render "$tmp/w.glb" --method lightmap --width 8 --height 8 -o "$tmp/l.png"
echo "setup: ready ($(.venv/bin/python --version), venv in .venv)"
