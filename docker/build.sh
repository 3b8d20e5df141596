#!/usr/bin/env bash
# Build the phongray image on a machine that reaches no image registry: make a Debian bookworm base with
# debootstrap (from the configured Debian mirror) once, import it as phongray-base:bookworm, and build on it,
# letting pip in the build trust the CA bundle this machine's pip uses ($PIP_CERT).
#   docker/build.sh            # then: docker-compose -f docker/compose.yaml up -d
set -euo pipefail
cd "$(dirname "$0")/.."
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
if ! docker image inspect phongray-base:bookworm >/dev/null 2>&1; then
  root=$(mktemp -d)
  debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates,bubblewrap bookworm "$root" "$MIRROR"
  tar -C "$root" -c . | docker import - phongray-base:bookworm
  rm -rf "$root"
fi
if [ -n "${PIP_CERT:-}" ] && [ -f "$PIP_CERT" ]; then cp "$PIP_CERT" docker/pip-cert.pem; fi
trap 'rm -f docker/pip-cert.pem' EXIT
docker build --network host --build-arg BASE=phongray-base:bookworm -t phongray:latest .
