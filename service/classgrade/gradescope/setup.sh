#!/usr/bin/env bash
# phongray's autograder, step 1 (Gradescope runs it once, as root, when it builds the autograder's image):
# install phongray from the bundle into its own virtual environment, with a Python 3.11 or newer.
# On an image whose Python is older (Ubuntu 22.04 has 3.10), Python 3.11 comes from the deadsnakes PPA.
set -euo pipefail
ROOT="${PHONGRAY_AUTOGRADER_ROOT:-/autograder}"
SOURCE="$(cd "$(dirname "$0")" && pwd)"
VENV="$ROOT/phongray-venv"
export DEBIAN_FRONTEND=noninteractive

new_enough() { "$1" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; }

python=""
for candidate in python3 python3.13 python3.12 python3.11; do
  if command -v "$candidate" >/dev/null 2>&1 && new_enough "$candidate"; then
    python="$(command -v "$candidate")"
    break
  fi
done
if [ -z "$python" ]; then
  echo "phongray: this image's Python is older than 3.11; installing Python 3.11 (deadsnakes PPA)"
  apt-get update -q
  apt-get install -y -q software-properties-common
  add-apt-repository -y ppa:deadsnakes/ppa
  apt-get update -q
  apt-get install -y -q python3.11 python3.11-venv
  python="$(command -v python3.11)"
fi
version="$("$python" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
if ! "$python" -m venv "$VENV"; then  # Debian and Ubuntu ship venv (and ensurepip) apart from Python
  rm -rf "$VENV"
  apt-get update -q
  apt-get install -y -q "python$version-venv" || apt-get install -y -q python3-venv
  "$python" -m venv "$VENV"
fi
"$VENV/bin/pip" install -q --disable-pip-version-check "$SOURCE/phongray"
# a program assignment (course/program.json) runs each upload in bubblewrap's sandbox; prlimit and setpriv
# (util-linux) set its limits and its user
if [ -f "$SOURCE/course/program.json" ] && grep -q '"sandbox": true' "$SOURCE/course/program.json" \
    && ! command -v bwrap >/dev/null 2>&1; then
  apt-get update -q
  apt-get install -y -q bubblewrap util-linux
fi
"$VENV/bin/phongray" --version
echo "phongray: installed with Python $version in $VENV"
