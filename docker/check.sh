#!/usr/bin/env bash
# Build the image, start the compose stack (a Dask scheduler, two workers, two API replicas), render an example
# through each replica, compare the bytes with a local render, and take the stack down again.  Needs dockerd
# running, debootstrap (for the base, once) and docker-compose.  Not part of the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
docker/build.sh
docker-compose -f docker/compose.yaml up -d
trap 'docker-compose -f docker/compose.yaml down' EXIT
for port in 8001 8002; do
  for _ in $(seq 60); do curl -sf "127.0.0.1:$port/healthz" >/dev/null && break; sleep 1; done
done
local_png=$(mktemp)
docker run --rm --network host -v "$PWD/examples:/examples:ro" phongray:latest \
  phongray render /examples/01_three_spheres.json -o - -q > "$local_png"
for port in 8001 8002; do
  curl -s -o "/tmp/phongray-$port.png" -w "replica on $port: HTTP %{http_code}, %{size_download} bytes in %{time_total} s\n" \
    --data @examples/01_three_spheres.json -H 'content-type: application/json' "127.0.0.1:$port/render"
  cmp -s "$local_png" "/tmp/phongray-$port.png" && echo "replica on $port: the same bytes as a local render"
done
docker-compose -f docker/compose.yaml ps
