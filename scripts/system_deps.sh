#!/usr/bin/env bash
# The Debian packages the tests need, installed only where one is missing (`make test` runs
# this first; so does CI through it). Rendering of the environments (tests/envs/test_render.py):
# MuJoCo's EGL backend needs the first four; render_mode="human" (MuJoCo's viewer, GLFW) is
# tested on a virtual display (xvfb-run: xvfb, xauth).
set -euo pipefail
PACKAGES="libegl1 libegl-mesa0 libopengl0 libgl1-mesa-dri xvfb xauth"
if ! command -v dpkg >/dev/null 2>&1; then
    echo "system_deps: not a Debian system; the rendering tests need EGL (or OSMesa), Xvfb" \
         "and xauth: install your system's equivalents of: $PACKAGES" >&2
    exit 0
fi
missing=""
for p in $PACKAGES; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "system_deps: installing$missing" >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
