#!/usr/bin/env bash
# Installs what faceanim needs on a fresh Debian machine with Python 3.11: the package, editable, with
# video and face tracking (PyAV and MediaPipe wheels bring their own FFmpeg and models) and its test
# tools, and the Khronos glTF validator (npm) for the export tests. No system packages are needed yet;
# later parts (rendering, browser tests) add theirs here.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e ".[capture,test]"
# The Khronos glTF validator, for the export tests (they skip where Node.js is absent).
if command -v npm >/dev/null 2>&1; then
  npm install --silent --no-audit --no-fund --prefix tools/node gltf-validator@2.0.0-dev.3.10 >/dev/null
fi
