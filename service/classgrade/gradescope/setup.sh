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
# the runtime the TA named for the programs (course/program.json, course/runtime-requirements.txt): Debian
# packages installed for the system's Python, which the sandbox shows; a Python environment built of a
# requirements file with the image's python3 at /opt/phongray-runtime, shown read-only to every run
packages="$("$VENV/bin/python" -c 'import json, sys; print(" ".join(json.load(open(sys.argv[1])).get("packages", [])))' \
    "$SOURCE/course/program.json" 2>/dev/null || true)"
if [ -n "$packages" ]; then
  apt-get update -q
  # shellcheck disable=SC2086  # (the names are Debian packages', checked when the bundle was made)
  apt-get install -y -q $packages
fi
if [ -f "$SOURCE/course/runtime-requirements.txt" ]; then
  RUNTIME=/opt/phongray-runtime
  if ! /usr/bin/python3 -m venv "$RUNTIME"; then
    rm -rf "$RUNTIME"
    apt-get update -q
    apt-get install -y -q python3-venv
    /usr/bin/python3 -m venv "$RUNTIME"
  fi
  "$RUNTIME/bin/pip" install -q --disable-pip-version-check -r "$SOURCE/course/runtime-requirements.txt"
  chmod -R a+rX "$RUNTIME"
  echo "phongray: the programs' runtime is built in $RUNTIME"
fi
"$VENV/bin/phongray" --version
echo "phongray: installed with Python $version in $VENV"
