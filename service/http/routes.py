"""The HTTP endpoints. Each validates, hands the work to :mod:`service.jobs` off the
event loop, and turns outcomes into status codes; none of them knows any physics."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar, get_args

import anyio
from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse
from starlette.datastructures import UploadFile

from schemas import SceneError, json_schema, validate_scene
from schemas.locate import located
from service import grading, pipeline
from service.heatmap import Kind
from service.http.jobs import (
    AnswersFull,
    Busy,
    ClusterDown,
    Job,
    OutOfMemory,
    RenderService,
    TooSlow,
    parse_counted,
    prepare,
)
from service.http.models import ErrorAnswer, GradeAnswer, ValidAnswer
from service.limits import LimitError
from service.passes import PassFile
from tracer import ImageTooLarge, RenderCancelled, decode_png
from tracer.memory import release

router = APIRouter()
T = TypeVar("T")
#: seconds between two looks at whether a waiting client is still there (each look is a turn of the event loop,
#: and a hundred waiters look at once)
DISCONNECT_POLL = 0.25

#: the request example: a real scene of examples/ (the one the package ships), so that "Try it out" renders
EXAMPLE_TEXT = (Path(__file__).parent.parent / "static" / "example.json").read_text()
SCENE_BODY = {"requestBody": {"required": True, "content": {"application/json": {
    "schema": {"$ref": "#/components/schemas/Scene"}, "example": json.loads(EXAMPLE_TEXT)}}}}
GRADE_BODY = {"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
    "type": "object", "required": ["scene", "image"],
    "properties": {"scene": {"type": "string", "description": "the scene, as JSON text or a JSON file",
                             "example": EXAMPLE_TEXT},
                   "image": {"type": "string", "format": "binary", "description": "the submitted PNG"},
                   "tolerance": {"type": "number", "minimum": 0, "maximum": 255, "default": 2},
                   "max_fraction": {"type": "number", "minimum": 0, "maximum": 1, "default": 0.001},
                   "diagnose": {"type": "boolean", "default": True,
                                "description": "name the likely mistake of a failing image (renders the scene "
                                               "once per classic mistake, in a render slot)"}}}}}}}
ERRORS: dict[int | str, dict[str, Any]] = {
    413: {"description": "a limit was exceeded", "model": ErrorAnswer},
    415: {"description": "wrong content type", "model": ErrorAnswer},
    422: {"description": "invalid scene or image, with every problem", "model": ErrorAnswer},
    503: {"description": "every render slot is busy, or the render ran past its time", "model": ErrorAnswer}}


PassName = Literal["background", "ambient", "diffuse", "specular", "reflection", "refraction", "shadow", "normal",
                   "depth", "object"]
PASS_HELP = ("render one pass instead of the image: an additive term (background, ambient, diffuse, specular, "
             "reflection, refraction; they sum to the image's linear value), a light's visibility (shadow), or "
             "normal, depth, object for debugging")


class HTTPProblem(Exception):
    """An error answer; ``part`` names the form part it concerns (``"image"``: the submission, not the scene)."""

    def __init__(self, status: int, detail: str, errors: list[dict[str, Any]] | None = None,
                 headers: dict[str, str] | None = None, part: str | None = None):
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


def scene_errors(exc: SceneError, text: bytes | str) -> list[dict[str, Any]]:
    """Every problem with its path, message and (where found) the line of the JSON text."""
    return located(exc.problems, text)


def _require_json(request: Request) -> None:
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json" and not kind.endswith("+json"):
        raise HTTPProblem(415, f"content type must be application/json, got {kind or 'none'}")


def _answering(work: Callable[[], T], body: bytes | str) -> T:
    """``work()``, with scene problems as 422 (with their lines) and limits as their own status."""
    try:
        return work()
    except SceneError as exc:
        raise HTTPProblem(422, "invalid scene", scene_errors(exc, body)) from None
    except LimitError as exc:
        raise HTTPProblem(exc.status, str(exc)) from None


def _prepare(body: bytes | str, overrides: dict[str, int | None], service: RenderService) -> Job:
    return _answering(lambda: prepare(body, overrides, service.settings), body)


def _validate(body: bytes, service: RenderService) -> None:
    _answering(lambda: validate_scene(parse_counted(body, service.settings)), body)


class _Flight:
    """One render in progress, shared by every request for the same scene: they wait on it without a thread."""

    def __init__(self) -> None:
        self.done = anyio.Event()
        self.result: bytes | None = None
        self.failure: Exception | None = None
        self.waiting = 0  # requests still interested; the render stops when none is


def _unavailable(exc: Exception, service: RenderService) -> HTTPProblem:
    """503 with Retry-After for a render that cannot be had now: the slots busy, past its time, no cluster."""
    settings = service.settings
    detail = (f"the pass answers this worker holds leave no room for this one now (max_answer_bytes = "
              f"{settings.max_answer_bytes}); try again shortly" if isinstance(exc, AnswersFull) else
              "the render ran out of memory beside this worker's other work; try again shortly"
              if isinstance(exc, OutOfMemory) else
              "every render slot is busy; try again shortly" if isinstance(exc, Busy) else
              f"the render ran past the limit render_timeout = {settings.render_timeout:g} s"
              if isinstance(exc, TooSlow) else "the render cluster cannot be reached; try again shortly")
    return HTTPProblem(503, detail, headers={"Retry-After": str(settings.retry_after)})


async def _png(request: Request, job: Job) -> bytes:
    """Render (or fetch) off the event loop; stop rendering once every client that wants it has gone."""
    service: RenderService = request.app.state.service
    cached = service.cache.get(job.key)
    if cached is not None:
        return cached
    flights: dict[str, _Flight] = request.app.state.flights
    flight = flights.get(job.key)
    leader = flight is None
    if flight is None:
        flight = flights[job.key] = _Flight()
    flight.waiting += 1
    gone = anyio.Event()
    waiting = anyio.CancelScope()  # a follower stops waiting when its client goes; the leader waits for its thread

    async def watch() -> None:
        while not gone.is_set() and not flight.done.is_set():
            if await request.is_disconnected():
                gone.set()
                flight.waiting -= 1
                waiting.cancel()
                return
            await anyio.sleep(DISCONNECT_POLL)

    async with anyio.create_task_group() as tasks:
        tasks.start_soon(watch)
        if leader:
            try:
                flight.result = await anyio.to_thread.run_sync(service.png, job, lambda: flight.waiting <= 0)
            except Exception as exc:  # shared with every waiter, re-raised below outside the task group
                flight.failure = exc
            finally:
                flights.pop(job.key, None)
                flight.done.set()
        else:
            with waiting:
                await flight.done.wait()
        tasks.cancel_scope.cancel()
    if not gone.is_set():
        flight.waiting -= 1
    if not gone.is_set() and isinstance(flight.failure, RenderCancelled):
        # the flight stopped when every client waiting on it had left, as this one joined it: render again
        return await _png(request, job)
    failure = RenderCancelled("client closed the request") if gone.is_set() else flight.failure
    result = flight.result
    try:
        if failure is not None:
            raise failure
    except (Busy, TooSlow, ClusterDown) as exc:
        raise _unavailable(exc, service) from None
    except RenderCancelled:
        raise HTTPProblem(499, "client closed the request") from None
    except ImageTooLarge as exc:  # only when the service's own limits are set above the renderer's
        raise HTTPProblem(422, str(exc)) from None
    except LimitError as exc:  # the render outgrew its budget
        raise HTTPProblem(exc.status, str(exc)) from None
    assert result is not None
    return result


@router.post("/render", openapi_extra=SCENE_BODY, responses={
    200: {"content": {"image/png": {}, "application/x-npy": {}},
          "description": "the image (or with pass, the pass as a PNG or a .npy array)"}, 304: {}, **ERRORS},
             response_class=Response, summary="Render a scene to a PNG")
async def render_scene(request: Request, width: Annotated[int | None, Query(ge=1)] = None,
                       height: Annotated[int | None, Query(ge=1)] = None,
                       samples: Annotated[int | None, Query(ge=1)] = None,
                       pass_: Annotated[PassName | None, Query(alias="pass", description=PASS_HELP)] = None,
                       light: Annotated[int | None, Query(ge=0, description="with pass: the index in lights of "
                                                          "the one light whose diffuse, specular or shadow is "
                                                          "shown (default: every light)")] = None,
                       format: Annotated[Literal["png", "npy"], Query(description="with pass: a PNG to look "
                                         "at, or the values as a NumPy .npy array")] = "png") -> Response:
    _require_json(request)
    if pass_ is None:  # (as the command line refuses --light or an .npy file without --pass; format=png, the
        # default, which the API page's "Try it out" sends with every render, asks for what a render gives)
        for option in ("format", "light"):
            if option in request.query_params and request.query_params.get(option) != "png":
                raise HTTPProblem(422, f"{option}: applies to a render pass only; add pass=NAME (one of "
                                       f"{', '.join(get_args(PassName))}) or leave {option} out")
    service: RenderService = request.app.state.service
    body = await request.body()
    job = await anyio.to_thread.run_sync(_prepare, body, {"width": width, "height": height, "samples": samples},
                                         service, limiter=service.parsing)
    if pass_ is not None:
        return await _pass(request, job, pass_, light, format)
    headers = {"ETag": job.etag, "Cache-Control": "no-cache"}
    if job.etag in [t.strip() for t in request.headers.get("if-none-match", "").split(",")]:
        return Response(status_code=304, headers=headers)
    started = time.perf_counter()
    headers["X-Cache"] = "hit" if job.key in service.cache else "miss"  # (the playground says "from cache")
    data = await _png(request, job)
    headers["X-Render-Seconds"] = f"{time.perf_counter() - started:.4f}"
    return Response(data, media_type="image/png", headers=headers)


async def _pass(request: Request, job: Job, name: str, light: int | None, fmt: Literal["png", "npy"]) -> Response:
    service: RenderService = request.app.state.service

    def work(gone: Callable[[], bool]) -> tuple[PassFile, int]:
        return _answering(lambda: service.pass_file(job, name, light, fmt, gone), "")

    try:
        made, held = await _watched(request, work, service.grading)
    except ValueError as exc:  # a light the scene does not have
        raise HTTPProblem(422, str(exc)) from None
    except (Busy, TooSlow, ClusterDown) as exc:
        raise _unavailable(exc, service) from None
    return Streamed(made, service.settings.send_timeout, lambda: service.answers.give(held))


class Gone(Exception):
    """The client left: nobody reads the answer."""


async def _watched(request: Request, work: Callable[[Callable[[], bool]], T], limiter: Any) -> T:
    """``work(gone)`` on a pool thread (of ``limiter``), where ``gone()`` turns true once the client has left,
    looked at every :data:`DISCONNECT_POLL` seconds: the work polls it and stops (a 499, which nobody reads)."""
    left = threading.Event()

    async def watch() -> None:
        while not await request.is_disconnected():
            await anyio.sleep(DISCONNECT_POLL)
        left.set()

    failure: BaseException | None = None
    async with anyio.create_task_group() as tasks:
        tasks.start_soon(watch)
        try:
            result = await anyio.to_thread.run_sync(work, left.is_set, limiter=limiter)
        except Exception as exc:  # re-raised below, outside the task group (which would wrap it in a group)
            failure = exc
        tasks.cancel_scope.cancel()
    if isinstance(failure, RenderCancelled) and left.is_set():
        raise HTTPProblem(499, "client closed the request") from None
    if failure is not None:
        raise failure
    return result


class Streamed(Response):
    """A large answer sent a chunk at a time (:meth:`service.passes.PassFile.chunks`), never joined: each chunk
    must be taken by the client within ``timeout`` seconds (``send_timeout``), else the connection is dropped;
    either way ``done()`` runs once it is over (the answer's memory is let go and its budget given back)."""

    def __init__(self, file: PassFile, timeout: float, done: Callable[[], None]):
        super().__init__(media_type=file.media)
        self.file: PassFile | None = file
        self.timeout, self.done = timeout, done

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        file = self.file
        assert file is not None
        self.file = None
        try:
            await send({"type": "http.response.start", "status": 200, "headers": [
                (b"content-type", file.media.encode()), (b"content-length", str(file.size).encode()),
                (b"cache-control", b"no-cache")]})
            for piece in file.chunks():
                with anyio.move_on_after(self.timeout) as waiting:
                    await send({"type": "http.response.body", "body": piece, "more_body": True})
                if waiting.cancelled_caught:
                    await _drop(scope)
                    return
                if await _left(receive):  # (a send to a closed connection returns at once: stop copying)
                    return
                await anyio.sleep(0)  # (a turn of the event loop between chunks, for the other requests)
            await send({"type": "http.response.body", "body": b"", "more_body": False})
        finally:
            del file
            self.done()


async def _left(receive: Any) -> bool:
    """Whether the client has gone, looked at without waiting (as :meth:`Request.is_disconnected` looks)."""
    with anyio.CancelScope() as look:
        look.cancel()
        message = await receive()
        return bool(message.get("type") == "http.disconnect")
    return False


async def _drop(scope: Any) -> None:
    """Close a connection whose client does not read, dropping what is queued for it (``phongray.abort``, set by
    :class:`service.server.Protocol`); where there is no such hook, by failing the answer."""
    abort = scope.get("phongray.abort")
    if abort is None:
        raise Gone("the client did not read the answer within send_timeout")
    abort()
    for _ in range(3):  # (the connection's loss is taken in first: the server then logs no unfinished answer)
        await anyio.sleep(0)


@router.post("/validate", openapi_extra=SCENE_BODY, summary="Check a scene; list every error with its place",
             response_model=ValidAnswer, responses={413: ERRORS[413], 415: ERRORS[415], 422: ERRORS[422]})
async def validate(request: Request) -> dict[str, bool]:
    _require_json(request)
    body = await request.body()
    service: RenderService = request.app.state.service
    await anyio.to_thread.run_sync(_validate, body, service, limiter=service.parsing)
    return {"valid": True}


@router.post("/grade", openapi_extra=GRADE_BODY, summary="Grade a submitted PNG against the reference render",
             response_model=None, responses={200: {"model": GradeAnswer, "content": {"image/png": {}}, "description":
                                                   "the grade, or with format=png the heat-map"}, **ERRORS})
async def grade(request: Request, format: Literal["json", "png"] = "json",
                heatmap: Annotated[Kind, Query(description="verdict: the pixels that decided the grade, brighter "
                                                           "and darker; raw: the plain difference")] = "verdict",
                legend: Annotated[bool, Query(description="a band beneath the heat-map naming its colours")] = True,
                ) -> Response:
    service: RenderService = request.app.state.service
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind not in ("multipart/form-data", "application/x-www-form-urlencoded"):
        raise HTTPProblem(415, f"content type must be multipart/form-data, got {kind or 'none'}")
    try:
        # a part may be as large as the body (the framework's default is 1 MiB): the limits of each part are
        # checked below, with 413 naming the part
        form = await request.form(max_files=4, max_fields=16, max_part_size=request.app.state.body_limit("/grade"))
    except Exception as exc:  # malformed multipart bodies
        raise HTTPProblem(422, f"invalid multipart form: {exc}") from None
    try:
        scene_text = await _field(form.get("scene"), "scene")
        image = await _field(form.get("image"), "image", text=False)
    finally:
        await form.close()
    tolerance = _number(form.get("tolerance"), "tolerance", grading.DEFAULT_TOLERANCE, 0, 255)
    max_fraction = _number(form.get("max_fraction"), "max_fraction", grading.DEFAULT_MAX_FRACTION, 0, 1)
    diagnose = _flag(form.get("diagnose"), "diagnose", True)
    settings = service.settings
    if len(scene_text) > settings.max_body_bytes:
        raise HTTPProblem(413, f"scene: {len(scene_text)} bytes exceed the limit max_body_bytes = "
                               f"{settings.max_body_bytes}")
    if len(image) > settings.max_image_bytes:
        raise HTTPProblem(413, f"image: {len(image)} bytes exceed the limit max_image_bytes = "
                               f"{settings.max_image_bytes}", part="image")
    job = await anyio.to_thread.run_sync(_prepare, scene_text, {}, service, limiter=service.parsing)
    size = (job.scene.image.width, job.scene.image.height)
    # the submission is checked (and decoded) before any rendering is spent on it; decoding and comparing
    # run on pool threads, a bounded number at once
    decoded = [await anyio.to_thread.run_sync(_read_image, image, size, limiter=service.grading)]
    png = await _png(request, job)
    drawn = heatmap if format == "png" else None
    explain = job if diagnose and format == "json" else None

    def work(gone: Callable[[], bool]) -> Response:
        return _compare(png, decoded, drawn, legend, tolerance, max_fraction, service, explain, gone)

    try:
        return await _watched(request, work, service.grading)
    except ClusterDown as exc:
        raise _unavailable(exc, service) from None


def _read_image(image: bytes, size: tuple[int, int]) -> Any:
    try:
        return pipeline.read_image(image, size)
    except grading.ImageError as exc:
        release()  # what a refused decode allocated goes back to the OS
        raise HTTPProblem(422, f"image: {exc}", part="image") from None


def _compare(png: bytes, decoded: list[Any], heatmap: Kind | None, legend: bool, tolerance: float,
             max_fraction: float, service: RenderService, explain: Job | None,
             gone: Callable[[], bool] = lambda: False) -> Response:
    """Grade the submission in ``decoded`` (taken out of it, so that nothing else holds its pixels), or draw its
    heat-map, diagnose a failing grade of ``explain``'s scene, and hand the memory of the images back to the OS
    before answering."""
    submitted = decoded.pop()
    try:
        reference = decode_png(png)
        graded = pipeline.compare(png, submitted, tolerance, max_fraction, heatmap, legend, reference=reference)
        if explain is not None:
            graded = service.explain(explain, graded, reference, submitted, gone)
        if graded.heatmap is not None:
            return Response(graded.heatmap, media_type="image/png")
        return JSONResponse(graded.as_dict())
    finally:
        del submitted
        release()


async def _field(value: Any, name: str, text: bool = True) -> Any:
    if value is None:
        raise HTTPProblem(422, f"{name}: required form field", part=name)
    if isinstance(value, UploadFile):
        value = await value.read()
    if text:  # a scene as a file part stays bytes (the JSON parser decodes it, and refuses what is not UTF-8)
        return value
    return value.encode("utf-8", "surrogateescape") if isinstance(value, str) else value


def _flag(value: Any, name: str, default: bool) -> bool:
    if value is None or value == "":
        return default
    text = value.lower() if isinstance(value, str) else value
    if text in ("true", "1", "yes", "on"):
        return True
    if text in ("false", "0", "no", "off"):
        return False
    raise HTTPProblem(422, f"{name}: must be true or false")


def _number(value: Any, name: str, default: float, low: float, high: float) -> float:
    if value is None or value == "":
        return default
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise HTTPProblem(422, f"{name}: must be a number") from None
    if not low <= number <= high:
        raise HTTPProblem(422, f"{name}: must be between {low:g} and {high:g}")
    return number


@router.get("/schema", summary="The scene JSON Schema (Draft 2020-12)")
def schema() -> dict[str, Any]:
    return json_schema()


@router.get("/healthz", summary="Liveness and counters")
async def healthz(request: Request) -> dict[str, Any]:  # on the loop: never queued behind pool threads
    return {"status": "ok", **request.app.state.service.status()}
