#!/usr/bin/env bash
# Installs everything voxgi needs on a fresh Debian/Ubuntu machine: the
# Debian packages for headless OpenGL (EGL on Mesa llvmpipe, Xvfb for a real
# window), a virtual environment in .venv and the Python packages.
# Idempotent: skips what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
pkgs="libegl1 libgl1 libgl1-mesa-dri libgomp1 xvfb xauth"
py_ok=1
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || py_ok=0
missing=""
for p in $pkgs; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
[ "$py_ok" = 1 ] || missing="$missing python3 python3-venv python3-pip"
if [ -n "$missing" ]; then
  echo "setup: installing Debian packages:$missing"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
.venv/bin/python -m pip install -q -e ".[dev]"
echo "setup: ready ($(.venv/bin/python --version), venv in .venv)"
