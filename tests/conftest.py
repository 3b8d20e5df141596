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
