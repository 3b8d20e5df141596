import ctypes
import multiprocessing.util
import os
import sys
import tempfile
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

#: prctl's option that makes this process the reaper of its orphaned descendants
PR_SET_CHILD_SUBREAPER = 36
#: the machine's temporary folder, as the first process of the session found it (pytest-xdist's processes
#: inherit a TMPDIR of that process's own)
OUTER_TMPDIR = "TESTS_OUTER_TMPDIR"


def _own_temporary_folder() -> None:
    """Every temporary file and folder of this process's tests (students' run folders, builds, bundles) in a
    folder of its own, which its children inherit through ``TMPDIR``: a test that checks it left no run folder
    behind looks there, not at what other programs on the machine (another test session, the tests another
    process of this session runs, a TA's ``grade-class --run``) are doing in ``/tmp``.  Each of pytest-xdist's
    processes imports this file and makes its own, inside the one of the process that started it (whose
    TMPDIR it inherits).  Open to be traversed (0711), as ``/tmp`` is, so that a sandbox's user reaches the
    run folder made for it.  multiprocessing's own folder (where a forkserver's socket is), which
    multiprocessing removes as this process exits, is made in the machine's temporary folder instead: these go
    at the session's end (pytest_sessionfinish), before the processes exit."""
    tempfile.tempdir = os.environ.setdefault(OUTER_TMPDIR, tempfile.gettempdir())
    multiprocessing.util.get_temp_dir()
    tempfile.tempdir = None
    folder = tempfile.mkdtemp(prefix="phongray-tests-")
    os.chmod(folder, 0o711)
    os.environ["TMPDIR"] = folder
    tempfile.tempdir = None  # (read TMPDIR again)


def _reap_orphans() -> None:
    """This process adopts whatever its children leave orphaned (a student's daemon that double-forked away
    from its parent), so that every process its tests started, directly or not, stays among its descendants,
    which is all that :func:`helpers.own_processes` looks at.  Under pytest-xdist each process that runs tests
    is its own reaper: what one's tests leave is never among another's."""
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


#: the most processes that run the tests at once (``-n auto`` in pyproject.toml, pytest-xdist): each test runs
#: renders, servers and pools of its own that use every core, so that more processes than this add memory, not
#: speed
MOST_WORKERS = 4


@pytest.hookimpl(optionalhook=True)  # (pytest-xdist's hook)
def pytest_xdist_auto_num_workers(config) -> int | None:  # noqa: ANN001
    """How many processes run the tests under ``-n auto``: one a core this process may use, at most
    MOST_WORKERS, and none on one core (the tests then run here).  ``-n N`` on the command line, or
    PYTEST_XDIST_AUTO_NUM_WORKERS, chooses instead; ``-n 0`` runs every test in this process."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # (pytest-xdist's own reading of it)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return 0 if cores < 2 else min(cores, MOST_WORKERS)


#: the modules that take longest, longest first (seconds each took in a whole run in one process, ``-n 0
#: --durations=0``, 2 cores: 60 to 150 each; the fuzz subset first, whose own pool of processes takes every core
#: while the other processes' tests wait on servers and sandboxes).  The processes take the tests a module at a
#: time, the next module in this order as one runs out; a long module begun last would keep one process working
#: alone at the end
LONGEST = (
    "test_fuzz.py",
    "test_diagnosis.py",
    "test_classgrade.py",
    "test_class_programs.py",
    "test_e2e.py",
    "test_cluster.py",
    "test_bounded_diagnosis.py",
    "test_cli.py",
    "test_sightlines.py",
    "test_reliability_class.py",
    "test_student_oop.py",
    "test_budget.py",
    "test_accepting.py",
    "test_fuzz_api.py",
    "test_rush.py",
    "test_variants.py",
    "test_attacks.py",
    "test_limits.py",
    "test_culling.py",
    "test_guard.py",
)


def _longest_first(items) -> None:  # noqa: ANN001
    """The modules of LONGEST first, in its order; the others after them, in the order they were collected (each
    module's tests keep theirs)."""
    rank = {name: k for k, name in enumerate(LONGEST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST)))


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
    _one_id_each(items)
    _longest_first(items)
    _without_bubblewrap(items)


def _one_id_each(items) -> None:  # noqa: ANN001
    """schemathesis makes an item of each API operation of a test (tests/test_fuzz_api.py), named after it
    (``test_api_conforms_to_its_openapi[POST /render]``) but all under the test's own node id.  pytest-xdist
    hands tests out by node id: of items that share one, only the first would run (the other operations never
    fuzzed, and nothing said).  Each gets its own name as its id."""
    from collections import Counter

    count = Counter(item.nodeid for item in items)
    for item in items:
        if count[item.nodeid] > 1:
            own = f"{item.nodeid.rpartition('::')[0]}::{item.name}"
            if hasattr(item, "_id"):  # (pytest 9's structured id)
                from _pytest.nodes import NodeId

                item._id = NodeId.parse(own)
            else:
                item._nodeid = own
    assert len({item.nodeid for item in items}) == len(items), "tests that share a node id: xdist runs only one"


def _without_bubblewrap(items) -> None:  # noqa: ANN001
    """Without bubblewrap (``apt-get install bubblewrap``) the sandbox's tests are skipped, saying so, on a
    developer's machine; CI installs it and sets PHONGRAY_REQUIRE_SANDBOX, so that there they fail instead."""
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
