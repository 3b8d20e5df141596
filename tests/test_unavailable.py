"""Why a sandbox cannot start, in words a TA can act on (service.programs.unavailable): bubblewrap's line, then
the cause and the remedy; and the compose stack's workers, which grade programs, allowed to start it."""

from pathlib import Path

import pytest
import yaml

from service.programs import unavailable
from service.programs.unavailable import explain

ROOT = Path(__file__).resolve().parent.parent
#: bubblewrap's words in a Docker container: with Docker's defaults, then with its seccomp profile lifted only
NO_NAMESPACE = (
    "bwrap: No permissions to create new namespace, likely because the kernel does not allow non-privileged "
    "user namespaces. See <https://deb.li/bubblewrap> or <file:///usr/share/doc/bubblewrap/README.Debian.gz>."
)
NO_PROC = "bwrap: Can't mount proc on /newroot/proc: Operation not permitted"


@pytest.mark.parametrize("line", [NO_NAMESPACE, NO_PROC])
def test_in_a_container_the_cause_is_dockers_profile_and_the_remedy_its_options(monkeypatch, line):
    monkeypatch.setattr(unavailable, "in_container", lambda: True)
    said = explain(line)
    assert said.startswith(line)
    assert "Docker's default seccomp profile" in said and "masked /proc" in said and "kernel is not the cause" in said
    assert "--security-opt seccomp=unconfined --security-opt systempaths=unconfined" in said
    assert "--privileged" in said and "--no-sandbox" in said


def test_outside_a_container_the_cause_is_the_kernels_setting(monkeypatch):
    monkeypatch.setattr(unavailable, "in_container", lambda: False)
    said = explain(NO_NAMESPACE)
    assert "user.max_user_namespaces" in said and "--no-sandbox" in said and "Docker" not in said
    assert explain(NO_PROC) == NO_PROC  # (no cause phongray knows)


def test_a_process_limit_is_named():
    said = explain("bwrap: Creating new namespace failed: Resource temporarily unavailable")
    assert "a limit on processes was reached: the grading user's (ulimit -u" in said


def test_the_compose_stacks_workers_may_start_the_sandbox():
    """A worker grades students' programs in bubblewrap's sandbox, which Docker's defaults do not let start."""
    services = yaml.safe_load((ROOT / "docker" / "compose.yaml").read_text())["services"]
    privileged = {name for name, service in services.items() if service.get("privileged")}
    assert privileged == {"worker-1", "worker-2"}  # (only the workers run programs)
