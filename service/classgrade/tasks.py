"""The tasks of class grading: bytes in, bytes out, so that they run alike in a local pool and on Dask workers."""

from __future__ import annotations

import time

from schemas import load_scene
from tracer import ImageTooLarge, OverBudget, RenderCancelled, encode_png, render
from tracer.budget import UNLIMITED

from ..admission.limits import budget, outgrown
from ..images import grading
from ..settings import Settings
from ..work import pipeline
from .records import GradeJob, Marked


def render_task(scene: bytes, limits: Settings | None = None) -> tuple[bytes | None, str]:
    """The reference PNG of a scene's text, or (None, the reason it cannot be rendered).  With the service's
    ``limits`` (``grade-class --limits``), a render still going after their ``render_timeout`` or outgrowing
    their budget (:func:`service.admission.limits.budget`) is stopped; without, the TA's scene is trusted."""
    deadline = None if limits is None else time.monotonic() + limits.render_timeout
    loaded = load_scene(scene)
    try:
        return encode_png(
            render(
                loaded,
                threads=1,
                budget=UNLIMITED if limits is None else budget(loaded, limits),
                cancel=None if deadline is None else lambda: time.monotonic() > deadline,
            )
        ), ""
    except ImageTooLarge as exc:
        return None, str(exc)
    except OverBudget as exc:
        assert limits is not None
        return None, str(outgrown(exc, limits))
    except RenderCancelled:
        assert limits is not None
        return None, (
            f"the render ran past the limit render_timeout = {limits.render_timeout:g} s (PHONGRAY_RENDER_TIMEOUT)"
        )


def grade_task(
    reference: bytes,
    image: bytes,
    tolerance: float,
    max_fraction: float,
    scene: bytes | None = None,
    accepted: dict[str, float] | None = None,
    diagnose: bool = True,
) -> Marked:
    """The grade of a submission against a reference PNG, with its heat-map and, given the reference's
    ``scene`` text, a failing one graded again against the task's ``accepted`` variants (None: the defaults)
    and, to ``diagnose``, the likely mistake of one that fails them too; or an invalid one whose reason lacks
    only the file's name."""
    try:
        graded = pipeline.grade_png(
            reference,
            image,
            tolerance,
            max_fraction,
            heatmap="verdict",
            explaining=None
            if scene is None
            else pipeline.Explaining(
                lambda: load_scene(scene), pipeline.Checks(accepted, diagnose), pipeline.Checking(threads=1)
            ),
        )
    except grading.ImageError as exc:
        return Marked.invalid(str(exc))
    return Marked.of(graded)


def local_grade(job: GradeJob) -> Marked:
    """:func:`grade_task` of a pair's job (the reference is already rendered: the scene is for the accepted
    variants and, unless not to ``diagnose``, the diagnosis of a failing pair)."""
    return grade_task(job.reference, job.image, job.tolerance, job.max_fraction, job.scene, job.accepted, job.diagnose)
