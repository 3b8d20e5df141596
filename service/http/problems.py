"""What every endpoint answers when it cannot do what was asked: the error record, its JSON, and the
translation of a scene's problems, a limit or a busy worker into a status code."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any, TypeVar

from fastapi import Request
from fastapi.responses import JSONResponse

from schemas import SceneError
from schemas.locate import Located, located
from service.admission.limits import LimitError
from service.http.models import ErrorAnswer
from service.work.jobs import AnswersFull, Busy, Job, OutOfMemory, RenderService, TooSlow, prepare

T = TypeVar("T")

ERRORS: dict[int | str, dict[str, Any]] = {
    413: {"description": "a limit was exceeded", "model": ErrorAnswer},
    415: {"description": "wrong content type", "model": ErrorAnswer},
    422: {"description": "invalid scene or image, with every problem", "model": ErrorAnswer},
    503: {"description": "every render slot is busy, or the render ran past its time", "model": ErrorAnswer},
}


class HTTPProblem(Exception):
    """An error answer; ``part`` names the form part it concerns (``"image"``: the submission, not the scene)."""

    def __init__(
        self,
        status: int,
        detail: str,
        errors: list[Located] | None = None,
        headers: dict[str, str] | None = None,
        part: str | None = None,
    ):
        self.status, self.detail, self.errors, self.headers, self.part = status, detail, errors, headers, part


class SafeJSONResponse(JSONResponse):
    """JSON that can always be sent: text that is not valid Unicode (a lone surrogate from a scene's
    ``"\\ud800"``) goes out as a JSON escape instead of failing to encode."""

    def render(self, content: Any) -> bytes:
        try:
            return super().render(content)
        except UnicodeEncodeError:
            return json.dumps(content, ensure_ascii=True, allow_nan=False, separators=(",", ":")).encode()


def problem_response(exc: HTTPProblem) -> JSONResponse:
    body: dict[str, Any] = {"detail": exc.detail}
    if exc.errors is not None:
        body["errors"] = exc.errors
    if exc.part is not None:
        body["part"] = exc.part
    headers = dict(exc.headers or {})
    if exc.status in (408, 413):  # the rest of the body is not read: the connection cannot be reused
        headers["Connection"] = "close"
    return SafeJSONResponse(body, status_code=exc.status, headers=headers)


def scene_errors(exc: SceneError, text: bytes | str) -> list[Located]:
    """Every problem with its path, message and (where found) the line of the JSON text."""
    return located(exc.problems, text)


def require_plain(request: Request) -> None:
    """A body sent encoded (``Content-Encoding: gzip``) is refused, not read as if it were the JSON or the form:
    the service takes bodies as they are."""
    encoding = request.headers.get("content-encoding", "").strip().lower()
    if encoding not in ("", "identity"):
        raise HTTPProblem(415, f"content encoding {encoding!r} is not taken: send the body as it is")


def require_json(request: Request) -> None:
    require_plain(request)
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json" and not kind.endswith("+json"):
        raise HTTPProblem(415, f"content type must be application/json, got {kind or 'none'}")


def answering(work: Callable[[], T], body: bytes | str) -> T:
    """``work()``, with scene problems as 422 (with their lines) and limits as their own status."""
    try:
        return work()
    except SceneError as exc:
        raise HTTPProblem(422, "invalid scene", scene_errors(exc, body)) from None
    except LimitError as exc:
        raise HTTPProblem(exc.status, str(exc)) from None


def prepared(body: bytes | str, overrides: dict[str, int | None], service: RenderService) -> Job:
    return answering(lambda: prepare(body, overrides, service.settings), body)


def unavailable(exc: Exception, service: RenderService) -> HTTPProblem:
    """503 with Retry-After for a render that cannot be had now: the slots busy (Retry-After: when the work
    waiting for them is likely done, :meth:`service.work.slots.Slots.retry_after`), past its time, no cluster."""
    settings = service.settings
    retry = settings.retry_after
    if isinstance(exc, AnswersFull):
        detail = (
            f"the image answers this worker holds leave no room for this one now (max_answer_bytes = "
            f"{settings.max_answer_bytes}); try again shortly"
        )
    elif isinstance(exc, OutOfMemory):
        detail = "the render ran out of memory beside this worker's other work; try again shortly"
    elif isinstance(exc, Busy):
        retry = service.slots.retry_after(retry)
        waiting = service.slots.waiting  # (the others: this request has left the queue)
        others = f", {waiting} more still waiting" if waiting else ""
        slots = settings.max_concurrent_renders
        detail = (
            f"every render slot is busy ({slots} render{'s' if slots != 1 else ''} at once; this one waited longer "
            f"than queue_wait = {settings.queue_wait:g} s{others}); try again in {retry} s"
        )
    elif isinstance(exc, TooSlow):
        detail = f"the render ran past the limit render_timeout = {settings.render_timeout:g} s"
    else:
        detail = "the render cluster cannot be reached; try again shortly"
    return HTTPProblem(503, detail, headers={"Retry-After": str(retry)})
