#!/usr/bin/env bash
# Installs what faceanim needs on a fresh Debian machine with Python 3.11: the package, editable, with
# video and face tracking (PyAV and MediaPipe wheels bring their own FFmpeg and models) and its test
# tools. No system packages are needed yet; later parts (rendering, browser tests) add theirs here.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e ".[capture,test]"
