"""A cgroup of its own for each run (service.programs.cgroup), against a folder laid out as cgroup v2's files are
(the kernel's own hierarchy is the machine's, not a test's to change): where a parent can be had, each run's
group is made in it with its limits, a command moved into it, the kernel's kill found in its events, and the
group removed; where not, why not is said."""

import os
import subprocess
from pathlib import Path

import pytest

from service.programs import cgroup
from service.programs.cgroup import CgroupError, Cgroups, RunGroup, find


def hierarchy(root: Path, enabled: str = "") -> Path:
    """A folder with a cgroup v2 root's files: the controllers it offers, those enabled for its children."""
    root.mkdir(exist_ok=True)
    (root / "cgroup.controllers").write_text("cpuset cpu io memory hugetlb pids rdma misc\n")
    (root / "cgroup.subtree_control").write_text(enabled)
    return root


def group_files(group: Path) -> None:
    """What the kernel puts in a new group: its controllers' files."""
    (group / "cgroup.controllers").write_text("memory pids\n")
    (group / "cgroup.subtree_control").write_text("")


def test_a_runs_group_holds_its_limits_and_its_command(tmp_path, monkeypatch):
    monkeypatch.setattr(cgroup, "REMOVE_SECONDS", 0.0)  # (a folder of files is no group the kernel removes)
    run = RunGroup(tmp_path / "run-1", 512 << 20, 32)
    assert (run.path / "memory.max").read_text() == str(512 << 20)
    assert (run.path / "memory.swap.max").read_text() == "0"
    assert (run.path / "memory.oom.group").read_text() == "1"
    assert int((run.path / "pids.max").read_text()) == 32 + cgroup.OUTER
    said = subprocess.run([*run.prefix, "sh", "-c", "echo $$"], capture_output=True, text=True, check=True)
    assert (run.path / "cgroup.procs").read_text().strip() == said.stdout.strip()  # moved in, then exec'd
    assert run.stop() is None
    (run.path / "memory.events").write_text("low 0\nhigh 0\nmax 12\noom 1\noom_kill 1\noom_group_kill 1\n")
    assert run.stop() == "memory"
    run.close()
    assert (run.path / "cgroup.kill").read_text() == "1"


def test_root_makes_the_parent_and_enables_its_controllers(tmp_path, monkeypatch):
    mount = hierarchy(tmp_path / "cgroup")
    parent = mount / "phongray"
    parent.mkdir()
    group_files(parent)
    made: list[Path] = []

    def check(self: Cgroups) -> None:
        made.append(self.parent)

    monkeypatch.setattr(Cgroups, "check", check)
    found = find(mount, root=True)
    assert found.parent == parent == made[0]
    assert (mount / "cgroup.subtree_control").read_text() == "+memory +pids +cpu"  # (the root offers cpu)
    assert (parent / "cgroup.subtree_control").read_text() == "+memory +pids"  # (this one does not)


def test_a_dead_graders_groups_are_removed(tmp_path):
    parent = tmp_path / "phongray"
    parent.mkdir()
    dead = subprocess.run(["sh", "-c", "echo $$"], capture_output=True, text=True, check=True).stdout.strip()
    for name in (f"run-{dead}-aa", f"run-{os.getpid()}-bb"):
        (parent / name).mkdir()
    Cgroups(parent).sweep()
    assert sorted(p.name for p in parent.iterdir()) == [f"run-{os.getpid()}-bb"]


@pytest.mark.parametrize(
    ("root", "given", "v2", "words"),
    [
        (False, None, True, "not root and PHONGRAY_CGROUP names no group"),
        (True, None, False, "not a cgroup v2 hierarchy (this machine uses cgroup v1)"),
        (True, "/nonexistent/group", True, "PHONGRAY_CGROUP=/nonexistent/group is not a cgroup v2 group"),
    ],
)
def test_where_no_group_can_be_made_it_says_why(tmp_path, root, given, v2, words):
    mount = hierarchy(tmp_path / "cgroup") if v2 else tmp_path
    with pytest.raises(CgroupError, match=words.replace("(", r"\(").replace(")", r"\)")):
        find(mount, given, root)


def test_a_parent_without_the_controllers_is_refused(tmp_path):
    parent = tmp_path / "delegated"
    parent.mkdir()
    (parent / "cgroup.controllers").write_text("cpu io\n")
    (parent / "cgroup.subtree_control").write_text("")
    with pytest.raises(CgroupError, match="does not offer the memory and pids controllers"):
        find(tmp_path, str(parent), root=False)


def test_a_runs_group_says_its_cpu_time_and_its_wait_for_one(tmp_path, monkeypatch):
    monkeypatch.setattr(cgroup, "REMOVE_SECONDS", 0.0)
    run = RunGroup(tmp_path / "run-1", 512 << 20, 32)
    (run.path / "cpu.stat").write_text("usage_usec 1500000\nuser_usec 1400000\nsystem_usec 100000\n")
    (run.path / "cpu.pressure").write_text(
        "some avg10=80.00 avg60=20.00 avg300=5.00 total=6200000\nfull avg10=0.00 avg60=0.00 avg300=0.00 total=0\n"
    )
    assert run.stop() is None
    assert (run.cpu_seconds, run.waited_seconds) == (1.5, 6.2)
    run.close()
