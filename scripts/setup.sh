#!/usr/bin/env bash
# Installs what faceanim needs on a fresh Debian machine with Python 3.11: the package, editable, with
# its test tools. (No system packages are needed yet; later parts, such as rendering and browser
# tests, add theirs here.)
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e ".[test]"
