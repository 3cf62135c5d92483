#!/usr/bin/env bash
# Installs what faceanim needs on a fresh Debian machine with Python 3.11: the package, editable, with
# video and face tracking (PyAV and MediaPipe wheels bring their own FFmpeg and models) and its test
# tools, offscreen rendering (moderngl with Mesa's EGL from Debian, installed with apt-get when missing;
# run as root), and the tools the tests check our files with: the Khronos glTF validator (npm), Blender
# (headless glTF import) and Chromium (the web viewer's browser tests), from Debian.
set -euo pipefail
cd "$(dirname "$0")/.."
# Headless OpenGL for rendering: Mesa's EGL and its software rasteriser (llvmpipe) when absent.
if ! ldconfig -p | grep -q libEGL_mesa; then
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 >/dev/null
fi
# Blender imports our glTF in the export tests (its importer needs Debian's numpy); Chromium runs the
# viewer's browser tests. Both only where apt-get is available; the tests skip without them.
missing=()
command -v blender >/dev/null 2>&1 || missing+=(blender python3-numpy)
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
if ((${#missing[@]})) && command -v apt-get >/dev/null 2>&1; then
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
fi
python3 -m pip install --quiet --disable-pip-version-check -e ".[capture,render,plot,batch,test]"
# Node tools the tests use (they skip where Node.js is absent): the Khronos glTF validator, and
# playwright-core, which drives Debian's Chromium for the viewer's browser tests (no browser download).
if command -v npm >/dev/null 2>&1; then
  npm install --silent --no-audit --no-fund --prefix tools/node gltf-validator@2.0.0-dev.3.10 \
    playwright-core@1.49.1 >/dev/null
fi
