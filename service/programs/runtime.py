"""What the TA gives students' programs besides the system: a runtime, checked before any student is run.

The sandbox shows a program the system's ``/usr``, so Debian's packages are there once installed
(``python3-numpy``, ``python3-pil``): the TA names them (``--runtime-packages``), a batch checks they are
installed here, and the autograder's ``setup.sh`` installs them.  A runtime folder (``--runtime DIR``: a
Python virtual environment made with the system's ``python3``, with NumPy and Pillow in it; or any prefix)
is bound read-only at its own path in the sandbox, its ``bin`` first on the programs' ``PATH``, so that
``python3`` is its Python; one that holds the machine's temporary folder, the TA's scenes, the students'
folders or the report, or lies inside one of them, or has no ``bin/``, is refused (:func:`exposes`).  For
Gradescope, the autograder builds one from a requirements file
(``--runtime-requirements``) at :data:`BUNDLED`, with the image's ``python3``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import tempfile
from pathlib import Path

from .runner import check_sandbox

#: where the autograder's setup.sh builds the runtime of a requirements file
BUNDLED = "/opt/phongray-runtime"
#: a Debian package's name (policy §5.6.1)
PACKAGE = re.compile(r"[a-z0-9][a-z0-9+.-]+")


def check_names(runtime: str | None, packages: tuple[str, ...]) -> None:
    """ValueError for a runtime that is not an absolute path, or a name that is not a Debian package's."""
    if runtime is not None and not runtime.startswith("/"):
        raise ValueError(f"--runtime {runtime}: name the folder by its absolute path (it is shown there)")
    for name in packages:
        if not PACKAGE.fullmatch(name):
            raise ValueError(f"--runtime-packages: {name!r} is not a Debian package's name")


def missing_packages(packages: tuple[str, ...]) -> list[str]:
    """The packages of ``packages`` that are not installed here (dpkg's word), all of them without dpkg."""
    missing = []
    for name in packages:
        try:
            said = subprocess.run(
                ["dpkg-query", "-W", "-f=${Status}", name], capture_output=True, text=True, check=False
            ).stdout
        except OSError:
            said = ""
        if not said.endswith("installed") or said.endswith("not-installed"):
            missing.append(name)
    return missing


def check_runtime(
    runtime: str | None, packages: tuple[str, ...], private: dict[str, Path | None] | None = None
) -> str | None:
    """What is wrong with the TA's runtime on this machine (one line), or None: a package not installed, a
    folder that is not one, or one that would show a program what it may not see (:func:`exposes`)."""
    missing = missing_packages(packages)
    if missing:
        return f"--runtime-packages: not installed here: {', '.join(missing)} (apt-get install {' '.join(missing)})"
    if runtime is not None and not Path(runtime).is_dir():
        return f"--runtime {runtime}: no such folder"
    return None if runtime is None else exposes(runtime, private or {})


def _holds(outer: str, inner: str) -> bool:
    return inner == outer or inner.startswith(outer.rstrip("/") + "/")


def exposes(runtime: str, private: dict[str, Path | None]) -> str | None:
    """Why the runtime folder cannot be shown to every program (one line), or None.  It is shown whole, read-only:
    it may not hold the machine's temporary folder (where every run's private copy of a student's folder is,
    while it runs), nor hold or be inside a folder of ``private`` (the TA's scenes, the students' folders, the
    report: by what they are), and it is a Python environment or a prefix, with a ``bin/`` folder.  Paths are
    compared once every link in them is resolved."""
    real = os.path.realpath(runtime)
    temporary = "the machine's temporary folder, where every run's private folders are"
    places: dict[str, str] = {temporary: tempfile.gettempdir()}
    places.update({what: str(path) for what, path in private.items() if path is not None})
    for what, path in places.items():
        other = os.path.realpath(path)
        if _holds(real, other):
            seen = "which every program would see: name the environment itself"
            return f"--runtime {runtime}: it holds {what} ({path}), {seen}"
        if what != temporary and _holds(other, real):
            return f"--runtime {runtime}: it is inside {what} ({path}), which no program may see"
    if not os.path.isdir(os.path.join(real, "bin")):
        return (
            f"--runtime {runtime}: it has no bin/ folder: name a Python environment (/usr/bin/python3 -m venv DIR) "
            f"or a prefix holding bin/"
        )
    return None


#: a program that writes its output with the runtime's Python (``{python}``: its path)
PYTHON_STARTS = "{python} -c \"import sys; open(sys.argv[1], 'w').write('ok')\" {output}"


def runtime_starts(runtime: str, sandbox: bool) -> str | None:
    """What stops the runtime's Python in a program's sandbox (one line), or None: a virtual environment made
    from a Python the sandbox does not show (not the system's ``/usr/bin/python3``) does not start there."""
    python = Path(runtime) / "bin" / "python3"
    if not os.path.lexists(python):  # (a link to a Python the sandbox does not show is one)
        return None
    outcome = check_sandbox(PYTHON_STARTS.replace("{python}", shlex.quote(str(python))), runtime) if sandbox else None
    if outcome is None or outcome.ok:
        return None
    said = outcome.stderr_tail.strip().splitlines()[-1:] or [outcome.detail]
    return (
        f"--runtime {runtime}: its python3 does not start in the sandbox ({said[0]}); make it with the "
        f"system's Python, /usr/bin/python3 -m venv {runtime}"
    )
