import os
import secrets
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))


def _own_sandbox_uids() -> None:
    """This session's runs of students' programs (run as root) get user ids of a range no other session
    draws from (PHONGRAY_SANDBOX_UIDS, inherited by the pool's processes and the Dask workers the tests
    start), so that a test that looks for a run's processes left running finds its own only."""
    from service.programs.sandbox import UID_BASE, UID_SPAN, UIDS_VARIABLE

    width = 1_000_000
    first = UID_BASE + width * secrets.randbelow(UID_SPAN // width)
    os.environ[UIDS_VARIABLE] = f"{first}-{first + width - 1}"


def _own_temporary_folder() -> None:
    """This session's temporary files (pytest's, and the runs' folders of students' programs) in a folder of
    its own, inherited by the processes it starts (TMPDIR), so that a test that looks for a run's folder left
    behind finds its own only; traversable by a run's user (0711), removed at the end."""
    import tempfile

    folder = tempfile.mkdtemp(prefix="phongray-tests-")
    os.chmod(folder, 0o711)
    os.environ["TMPDIR"] = folder
    tempfile.tempdir = None


_own_sandbox_uids()
_own_temporary_folder()


def pytest_unconfigure(config) -> None:  # noqa: ANN001
    import shutil

    shutil.rmtree(os.environ["TMPDIR"], ignore_errors=True)


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
    "test_guard.py",
    "test_seccomp.py",
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
