"""phongray hidden from the sandbox: no installation of it is there for a student's program to import.

A sandbox shows the system's ``/usr``, and with it every Python package installed for the system's Pythons: a
phongray installed there (``pip install`` for the system's Python, an editable install, a copy) would let a
program of nine lines render every hidden scene as the reference does.  So the first sandbox a process makes
looks, with every ``python3*`` of the sandbox's ``PATH``, for what of phongray each could import
(:data:`FIND`): its distribution's metadata (``phongray-*.dist-info``, its ``RECORD``'s files, an editable
install's ``.pth`` and finder) and its top-level modules (``tracer``, ``service``, ``schemas``, ``bench``,
``phongray``) found by Python's own finders and recognised by their files' names.  Every sandbox after it
covers each with an empty read-only folder, or an empty file (:func:`argv`); and the look is made again,
through those covers, to see that nothing of phongray's is left (a covered path is still there, empty).  What
is left stops the batch with :class:`SandboxUnavailable` (the TA's: remove that installation, or install
phongray in a virtual environment).

The look is made once per process and per set of folders the sandbox shows (a Dask worker's own machine has
its own installations; a TA's runtime, ``--runtime``, is looked into as well: a virtual environment that
holds phongray is covered too), and costs two sandboxed runs of each Python, a fraction of a second.
"""

from __future__ import annotations

import importlib
import json
import shlex
import tempfile
import threading
from pathlib import Path

from .limits import Limits
from .sandbox import SandboxUnavailable

#: phongray's top-level modules: a package or module of one of these names whose files are phongray's is hidden
PACKAGES = ("tracer", "service", "schemas", "bench")
MODULES = ("phongray",)

#: the look, run by each Python in the sandbox: a JSON list of the paths of phongray it could import (argv: the
#: module names, and each package's file names to recognise it by)
FIND = r"""
import importlib.util, json, os, sys

names, marks = sys.argv[1].split(","), json.loads(sys.argv[2])
found = []

def existing(path):
    while path and not os.path.lexists(path):
        path = os.path.dirname(path)
    return path

def phongrays(location, name):
    if name not in marks:
        return True
    try:
        held = set(os.listdir(location))
    except OSError:
        return False
    return 2 * len(held & set(marks[name])) >= len(marks[name])

def empty(path):
    try:
        return not os.listdir(path) if os.path.isdir(path) else os.path.getsize(path) == 0
    except OSError:
        return True

def metadata(entry, item):
    low = item.lower()
    path = os.path.join(entry, item)
    if empty(path):
        return
    if low.startswith("phongray-") and low.endswith((".dist-info", ".egg-info")):
        found.append(path)
        for listed in ("RECORD", "installed-files.txt", "top_level.txt"):
            try:
                lines = open(os.path.join(path, listed)).read().splitlines()
            except OSError:
                continue
            for line in lines:
                parts = line.split(",")[0].replace("\\", "/").strip().split("/")
                listed = "/".join(parts) if parts[0] == "__pycache__" else parts[0]  # (not others' caches)
                if listed and parts[0] not in ("..", ".") and os.path.lexists(os.path.join(entry, listed)):
                    found.append(os.path.join(entry, listed))
    elif "phongray" in low and (low.endswith(".pth") or low.startswith("__editable__")):
        found.append(path)

for entry in sys.path[1:]:
    if os.path.isdir(entry):
        try:
            items = os.listdir(entry)
        except OSError:
            items = []
        for item in items:
            metadata(entry, item)

for name in names:
    try:
        spec = importlib.util.find_spec(name)
    except Exception:
        spec = None
    if spec is None:
        continue
    places = list(spec.submodule_search_locations or []) or ([spec.origin] if spec.origin else [])
    for place in places:
        if os.path.dirname(os.path.abspath(place)) == os.getcwd():
            continue
        if empty(place) or (os.path.isdir(place) and not phongrays(place, name)):
            continue
        found.append(existing(place))

print(json.dumps(sorted(set(p + "/" if os.path.isdir(p) else p for p in found if p))))
"""

#: each Python of the sandbox's PATH runs the look (its output is appended to the run's output file)
PYTHONS = r"""
out="$1"
printf '' > "$out"
IFS=:
for dir in $PATH; do
  for py in "$dir"/python3 "$dir"/python3.[0-9]*; do
    case "$py" in *-config) continue ;; esac
    [ -x "$py" ] && [ -f "$py" ] || continue
    "$py" find.py "$NAMES" "$MARKS" >> "$out" 2>/dev/null || echo '[]' >> "$out"
  done
done
echo '[]' >> "$out"
"""


def _marks() -> dict[str, list[str]]:
    """Each of phongray's packages by the names of its files (this phongray's: a copy of another version shares
    most of them)."""
    marks = {}
    for name in PACKAGES:
        folder = Path(importlib.import_module(name).__file__ or ".").parent
        marks[name] = sorted(p.name for p in folder.iterdir() if not p.name.startswith("__pycache__"))
    return marks


def _look(runtime: str | None) -> list[str]:
    """What of phongray the sandbox's Pythons can import, as the sandbox is now (its current covers), with the
    TA's ``runtime`` shown (its ``bin`` first on the ``PATH``)."""
    from .runner import ProgramRun, run_program

    with tempfile.TemporaryDirectory(prefix="phongray-hidden-") as place:
        folder = Path(place, "look")
        folder.mkdir()
        (folder / "find.py").write_text(FIND)
        names = ",".join(PACKAGES + MODULES)
        script = PYTHONS.replace('"$NAMES"', shlex.quote(names)).replace('"$MARKS"', shlex.quote(json.dumps(_marks())))
        (folder / "pythons.sh").write_text(script)
        Path(place, "scene.json").write_text("{}")
        limits = Limits(wall_seconds=60.0, cpu_seconds=60)
        look = ProgramRun(folder, "/bin/sh pythons.sh {output}", Path(place, "scene.json"), limits, runtime=runtime)
        outcome = run_program(look)
    found: set[str] = set()
    for line in (outcome.image or b"").decode("utf-8", "replace").splitlines():
        try:
            found.update(p for p in json.loads(line) if isinstance(p, str) and p.startswith("/") and p != "/")
        except ValueError:
            continue
    return sorted(found)


Shown = tuple[tuple[str, ...], str | None]


class _Hidden:
    """The covers of each set of folders the sandbox shows (keyed by bubblewrap's arguments that show the
    system's, and the TA's runtime), or why phongray cannot be hidden there."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.covers: dict[Shown, list[str]] = {}
        self.failed: dict[Shown, str] = {}
        self.looking = False

    def of(self, shown: Shown) -> list[str]:
        with self.lock:
            if self.looking:  # (the look's own sandboxes: as the sandbox is, covers so far)
                return self.covers.get(shown, [])
            if shown in self.failed:
                raise SandboxUnavailable(self.failed[shown])
            if shown not in self.covers:
                self._hide(shown)
            return self.covers[shown]

    def _hide(self, shown: Shown) -> None:
        self.looking = True
        try:
            self.covers[shown] = []
            found = _look(shown[1])
            self.covers[shown] = found
            left = _look(shown[1]) if found else []
        finally:
            self.looking = False
        if left:
            del self.covers[shown]
            self.failed[shown] = (
                f"phongray is installed where students' programs can import it ({', '.join(left)}) and cannot "
                f"be hidden there: remove that installation (install phongray in a virtual environment)"
            )
            raise SandboxUnavailable(self.failed[shown])


HIDDEN = _Hidden()


def argv(system: list[str], runtime: str | None = None) -> list[str]:
    """bubblewrap's arguments that cover every installation of phongray in the folders a sandbox shows (the
    system's, shown by the arguments ``system``, and the TA's ``runtime``): an empty read-only folder over a
    folder, ``/dev/null`` over a file; to follow the arguments that show them.  :class:`SandboxUnavailable`
    when one cannot be hidden."""
    args: list[str] = []
    for path in HIDDEN.of((tuple(system), runtime)):
        if path.endswith("/"):  # (the look says a folder so)
            args += ["--perms", "0555", "--size", "4096", "--tmpfs", path[:-1], "--remount-ro", path[:-1]]
        else:
            args += ["--ro-bind", "/dev/null", path]
    return args
