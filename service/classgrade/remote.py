"""The tasks of class grading sent to a running service (``grade-class --server``), patient with its 503s and
its lost connections."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import fields
from typing import Any

from ..client import ServerError, post_form, post_json
from ..diagnosis import Diagnosis
from ..images.grading import Grade
from ..work.pipeline import Graded
from . import faults
from .records import GradeJob, Marked


def server_render(server: str, api_key: str | None, scene: bytes) -> tuple[bytes | None, str]:
    """:func:`~service.classgrade.tasks.render_task` by a running service (which has its own
    ``render_timeout``); a refusal of the scene (its limits, its time) is the reason."""
    try:
        return patient(post_json, server, "/render", scene, api_key=api_key), ""
    except ServerError as exc:
        if _too_slow(exc):
            return None, f"the server stopped it: {exc.detail}"
        if exc.ta_side or exc.status == 503:
            raise
        return None, f"the server refuses it: {exc.detail}"


def server_grade(server: str, api_key: str | None, job: GradeJob) -> Marked:
    """:func:`~service.classgrade.tasks.grade_task` of a pair's job by a running service (which renders the same
    reference, from its cache, and accepts its own default variants: a task's ``accepted`` is for local
    grading)."""

    fields = {
        "scene": job.scene,
        "tolerance": repr(job.tolerance),
        "max_fraction": repr(job.max_fraction),
        "diagnose": "true" if job.diagnose else "false",
    }
    files = {"image": ("submission.png", job.image, "image/png")}
    try:
        result = json.loads(patient(post_form, server, "/grade", fields, files, api_key=api_key))
        query = {"format": "png", "heatmap": "verdict", "legend": "false"}  # as grade_task draws it
        heat = patient(post_form, server, "/grade", fields, files, query, api_key=api_key)
    except ServerError as exc:
        if exc.status in (413, 422) and exc.part == "image":
            return Marked.invalid(exc.detail.removeprefix("image: "))
        raise
    return Marked.of(answered(result, heat))


def answered(answer: dict[str, Any], heatmap: bytes) -> Graded:
    """The grade of the service's JSON answer to /grade (:meth:`~service.work.pipeline.Graded.as_dict`), read back,
    with its ``heatmap``."""
    found = answer.get("diagnosis")
    return Graded(
        Grade(**{f.name: answer[f.name] for f in fields(Grade) if f.name in answer}),
        heatmap,
        None if found is None else Diagnosis.from_dict(found),
        answer.get("accepted"),
    )


#: the longest a request waits out a busy service's 503s (Retry-After), in seconds
BUSY_WAIT = 600.0


def _too_slow(exc: Exception) -> bool:
    """The service's 503 for a render past its ``render_timeout`` (the scene's, not to be waited out)."""
    return getattr(exc, "status", 0) == 503 and "render_timeout" in str(getattr(exc, "detail", ""))


def patient(func: Callable[..., bytes], server: str, *args: Any, **kw: Any) -> bytes:
    """A request to the service that waits out its 503s (their Retry-After, for at most :data:`BUSY_WAIT`
    seconds) and retries a lost connection (a worker restarting: reset, refused, closed)
    :data:`~service.classgrade.faults.RETRIES` times with backoff.  Every request of class grading is a pure
    function of its body, so sending it again is safe."""
    deadline = time.monotonic() + BUSY_WAIT
    lost = 0
    while True:
        try:
            return func(server, *args, **kw)
        except ServerError as exc:
            if exc.status == 503 and not _too_slow(exc) and time.monotonic() < deadline:
                time.sleep(exc.retry_after if exc.retry_after is not None else 1.0)
            elif exc.lost and lost < faults.RETRIES:
                time.sleep(faults.BACKOFF * 2**lost)
                lost += 1
            else:
                if exc.lost:
                    exc.args = (f"{exc} (after {lost} retries)",)
                raise
