#!/usr/bin/env bash
# Run a phongray autograder bundle as Gradescope would, on this machine: a Debian root made with debootstrap
# (once, in $ROOTFS), the bundle unpacked into /autograder/source, setup.sh run once as root, then
# run_autograder from /autograder on the images of a submission folder; prints /autograder/results/results.json.
# bubblewrap isolates it (no image registry is needed); pip in it uses this machine's pip settings.
# Needs debootstrap and a Debian mirror ($DEBIAN_MIRROR) the first time, and pip's package index for setup.sh.
#   docker/gradescope-dry-run.sh autograder.zip SUBMISSION_DIR [ROOTFS]
set -euo pipefail
zip=$(realpath "$1"); submission=$(realpath "$2"); rootfs=${3:-/var/tmp/phongray-gradescope-root}
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
if [ ! -x "$rootfs/usr/bin/python3" ]; then
  if ! command -v debootstrap >/dev/null; then
    echo "gradescope-dry-run.sh: debootstrap is needed (apt-get install debootstrap), and a Debian mirror" \
      "(DEBIAN_MIRROR, now $MIRROR); without them, run the autograder as docs/course.md says (a dry run)" >&2
    exit 2
  fi
  debootstrap --variant=minbase --include=python3,python3-venv,python3-pip,ca-certificates,unzip bookworm \
    "$rootfs" "$MIRROR"
fi
# this machine's CA bundle and pip settings, so that pip reaches the package index as it does here
cp /etc/ssl/certs/ca-certificates.crt "$rootfs/etc/ssl/certs/ca-certificates.crt"
cp /etc/resolv.conf "$rootfs/etc/resolv.conf"
[ -f /etc/pip.conf ] && cp /etc/pip.conf "$rootfs/etc/pip.conf"
[ -d /etc/xdg/pip ] && mkdir -p "$rootfs/etc/xdg" && cp -r /etc/xdg/pip "$rootfs/etc/xdg/"
binds=()
for d in /opt/wheels /opt/pypi /opt/pypi-more; do
  if [ -d "$d" ]; then binds+=(--ro-bind "$d" "$d"); fi
done
rm -rf "$rootfs/autograder" && mkdir -p "$rootfs/autograder/source" "$rootfs/autograder/submission" \
  "$rootfs/autograder/results"
(cd "$rootfs/autograder/source" && unzip -q "$zip")
cp -r "$submission/." "$rootfs/autograder/submission/"
box() { bwrap --bind "$rootfs" / --proc /proc --dev /dev --tmpfs /tmp "${binds[@]}" --chdir "$1" \
          --setenv PATH /usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin --setenv HOME /root "${@:2}"; }
echo "== setup.sh (once, as Gradescope builds the image)"
SECONDS=0
box /autograder/source bash ./setup.sh
echo "(setup.sh: $SECONDS s)"
cp "$rootfs/autograder/source/run_autograder" "$rootfs/autograder/run_autograder"
echo "== run_autograder (per submission), from /autograder"
SECONDS=0
box /autograder ./run_autograder || echo "run_autograder exited $?"
echo "(run_autograder: $SECONDS s)"
echo "== /autograder/results/results.json"
cat "$rootfs/autograder/results/results.json"
