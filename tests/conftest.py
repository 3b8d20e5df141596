import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))


def pytest_collection_finish(session) -> None:  # noqa: ANN001
    """Every module is imported now (about 235,000 objects): a full garbage collection of them would take about
    160 ms, and in the middle of a test that times the server from this process (its /healthz probes) that
    pause is this process's, not the server's.  Frozen, later collections pass them by (the server does the
    same with its started app, service.http.server.worker_app)."""
    import gc

    gc.collect()
    gc.freeze()


#: the test modules that run students' programs in bubblewrap's sandbox
SANDBOXED = {"test_programs.py", "test_experiment.py", "test_job.py", "test_class_programs.py", "test_bundled.py"}


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
