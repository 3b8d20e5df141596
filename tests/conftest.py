import ctypes
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

#: prctl's option that makes this process the reaper of its orphaned descendants
PR_SET_CHILD_SUBREAPER = 36


def _own_temporary_folder() -> None:
    """Every temporary file and folder of this test session (students' run folders, builds, bundles) in a
    folder of its own, which its children inherit through ``TMPDIR``: a test that checks it left no run folder
    behind looks there, not at what other programs on the machine (another test session, a TA's
    ``grade-class --run``) are doing in ``/tmp``.  Open to be traversed (0711), as ``/tmp`` is, so that a
    sandbox's user reaches the run folder made for it."""
    folder = tempfile.mkdtemp(prefix="phongray-tests-")
    os.chmod(folder, 0o711)
    os.environ["TMPDIR"] = folder
    tempfile.tempdir = None  # (read TMPDIR again)


def _reap_orphans() -> None:
    """This session adopts whatever its children leave orphaned (a student's daemon that double-forked away
    from its parent), so that every process it started, directly or not, stays among its descendants, which
    is all that :func:`helpers.own_processes` looks at."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)


_own_temporary_folder()
_reap_orphans()


def pytest_collection_finish(session) -> None:  # noqa: ANN001
    """Every module is imported now (about 235,000 objects): a full garbage collection of them would take about
    160 ms, and in the middle of a test that times the server from this process (its /healthz probes) that
    pause is this process's, not the server's.  Frozen, later collections pass them by (the server does the
    same with its started app, service.http.server.worker_app)."""
    import gc

    gc.collect()
    gc.freeze()


#: the test modules that run students' programs in bubblewrap's sandbox
SANDBOXED = {
    "test_programs.py",
    "test_experiment.py",
    "test_job.py",
    "test_class_programs.py",
    "test_bundled.py",
    "test_hidden.py",
    "test_copied.py",
    "test_guard.py",
    "test_seccomp.py",
    "test_runtime.py",
    "test_usage.py",
}


def pytest_collection_modifyitems(config, items) -> None:  # noqa: ANN001
    """Without bubblewrap (``apt-get install bubblewrap``) the sandbox's tests are skipped, saying so, on a
    developer's machine; CI installs it and sets PHONGRAY_REQUIRE_SANDBOX, so that there they fail instead."""
    import os
    import shutil

    import pytest

    if shutil.which("bwrap") is not None:
        return
    needing = [item for item in items if Path(str(item.fspath)).name in SANDBOXED]
    if needing and os.environ.get("PHONGRAY_REQUIRE_SANDBOX"):
        raise pytest.UsageError("bubblewrap is required (PHONGRAY_REQUIRE_SANDBOX is set) but bwrap is not on PATH")
    for item in needing:
        item.add_marker(
            pytest.mark.skip(
                reason="bubblewrap is not installed (apt-get install bubblewrap; CI "
                "installs it and sets PHONGRAY_REQUIRE_SANDBOX)"
            )
        )


def pytest_sessionfinish(session, exitstatus) -> None:  # noqa: ANN001
    """The session's own temporary folder goes with it (what a test left there was checked by that test)."""
    import shutil

    shutil.rmtree(os.environ["TMPDIR"], ignore_errors=True)
