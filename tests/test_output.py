"""`phongray render -o` is written whole or not at all: a failure never destroys the image that was there."""

import os
import resource
import signal
import subprocess
import sys

from helpers import SCENES

SCENE = str(SCENES / "01_three_spheres.json")


def render(out, *, file_limit=None):
    """``phongray render`` of the three spheres to ``out``, with files limited to ``file_limit`` bytes (a disk
    that fills up: a write past it fails with EFBIG, as on a full disk with ENOSPC)."""

    def limited():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # (else the kernel kills the writer instead)
        resource.setrlimit(resource.RLIMIT_FSIZE, (file_limit, file_limit))

    return subprocess.run(
        [sys.executable, "-m", "service.cli", "render", SCENE, "-o", str(out), "-q"],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=limited if file_limit else None,
    )


def test_a_write_that_fails_leaves_the_old_image_whole(tmp_path):
    out = tmp_path / "spheres.png"
    assert render(out).returncode == 0
    before = out.read_bytes()
    done = render(out, file_limit=1000)  # the new image does not fit
    assert done.returncode == 2 and done.stderr.startswith(f"phongray: {out}: cannot write: "), done.stderr
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spheres.png"]  # no temporary file left behind


def test_a_new_image_replaces_the_old_keeping_its_mode(tmp_path):
    out = tmp_path / "spheres.png"
    out.write_bytes(b"an old image")
    os.chmod(out, 0o640)
    assert render(out).returncode == 0
    assert out.read_bytes().startswith(b"\x89PNG") and (out.stat().st_mode & 0o777) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spheres.png"]


def test_a_link_is_written_through_and_a_device_as_it_is(tmp_path):
    target, link = tmp_path / "real.png", tmp_path / "link.png"
    target.write_bytes(b"old")
    link.symlink_to(target)
    assert render(link).returncode == 0
    assert link.is_symlink() and target.read_bytes().startswith(b"\x89PNG")
    null = tmp_path / "null.png"
    null.symlink_to("/dev/null")
    assert render(null).returncode == 0 and null.is_symlink()  # (no temporary file in /dev)
