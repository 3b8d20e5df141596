"""Grading a whole class: every (student, task) pair, each distinct scene rendered once, and a report.

The folders are described in :mod:`service.classgrade.submissions`.  A run checks everything of the teaching assistant's
before it grades anyone (:func:`grade_class`): the task scenes and students' own scenes, the tasks file, the
report folder, and the server or cluster the work goes to; any fault there stops the run with
:class:`ClassError`, and no student is marked for it.  Then the references are rendered, and only then is
each submission graded.  References are kept in ``REPORT/references/<scene key>.png`` (the service's
canonical scene hash), so a re-run renders only what it does not have.  Renders and comparisons are tasks
(bytes in, bytes out) run in a pool of processes (every core), on a Dask cluster with ``cluster``, or as
requests to a running service with ``server``: the same tasks, the same pipeline
(:mod:`service.work.pipeline`), the same report.

The TA's scenes are trusted: with ``limits`` (``--limits``) every scene is priced with the service's limits
before anything renders, and a render has its ``render_timeout`` and budget.  A fault of where the work runs
(a pool process killed, the Dask scheduler lost, a server connection reset) is retried :data:`~.faults.RETRIES` times
with backoff; every reference and every grade is kept as it finishes (``REPORT/resume/<student>/<task>.json``
for a grade), so a run stopped by a fault that persists resumes where it stopped.
"""

from ..course.errors import ClassError
from .records import ClassRun
from .run import Outcome, grade_class

__all__ = ["ClassError", "ClassRun", "Outcome", "grade_class"]
