"""The route of a grade: a submitted image against its scene's reference render, with its heat-map or the
diagnosis of a failing image."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import anyio
from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse
from starlette.datastructures import UploadFile

from service.http.models import GradeAnswer
from service.http.problems import ERRORS, HTTPProblem, prepared, require_plain, unavailable
from service.http.routers.render import EXAMPLE_TEXT
from service.http.waiting import rendered, watched, whole
from service.images import grading
from service.images.heatmap import Kind
from service.work import pipeline
from service.work.jobs import Busy, ClusterDown, Job, RenderService, TooSlow
from tracer import decode_png
from tracer.memory import release

router = APIRouter()

GRADE_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["scene", "image"],
                    "properties": {
                        "scene": {
                            "type": "string",
                            "description": "the scene, as JSON text or a JSON file",
                            "example": EXAMPLE_TEXT,
                        },
                        "image": {"type": "string", "format": "binary", "description": "the submitted PNG or PPM"},
                        "tolerance": {"type": "number", "minimum": 0, "maximum": 255, "default": 2},
                        "max_fraction": {"type": "number", "minimum": 0, "maximum": 1, "default": 0.001},
                        "diagnose": {
                            "type": "boolean",
                            "default": True,
                            "description": "name the likely mistake of a failing image (renders the scene "
                            "once per classic mistake, in a render slot)",
                        },
                    },
                }
            }
        },
    }
}


@router.post(
    "/grade",
    openapi_extra=GRADE_BODY,
    summary="Grade a submitted PNG or PPM against the reference render",
    response_model=None,
    responses={
        200: {
            "model": GradeAnswer,
            "content": {"image/png": {}},
            "description": "the grade, or with format=png the heat-map",
        },
        **ERRORS,
    },
)
async def grade(
    request: Request,
    format: Literal["json", "png"] = "json",
    heatmap: Annotated[
        Kind,
        Query(description="verdict: the pixels that decided the grade, brighter and darker; raw: the plain difference"),
    ] = "verdict",
    legend: Annotated[bool, Query(description="a band beneath the heat-map naming its colours")] = True,
) -> Response:
    service: RenderService = request.app.state.service
    require_plain(request)
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
        _once(form)
        scene_text = await _field(form.get("scene"), "scene")
        image = await _field(form.get("image"), "image", text=False)
    finally:
        await form.close()
    tolerance = _number(form.get("tolerance"), "tolerance", grading.DEFAULT_TOLERANCE, 0, 255)
    max_fraction = _number(form.get("max_fraction"), "max_fraction", grading.DEFAULT_MAX_FRACTION, 0, 1)
    diagnose = _flag(form.get("diagnose"), "diagnose", True)
    settings = service.settings
    if len(scene_text) > settings.max_body_bytes:
        raise HTTPProblem(
            413, f"scene: {len(scene_text)} bytes exceed the limit max_body_bytes = {settings.max_body_bytes}"
        )
    if len(image) > settings.max_image_bytes:
        raise HTTPProblem(
            413,
            f"image: {len(image)} bytes exceed the limit max_image_bytes = {settings.max_image_bytes}",
            part="image",
        )
    job = await anyio.to_thread.run_sync(prepared, scene_text, {}, service, limiter=service.parsing)
    size = (job.scene.image.width, job.scene.image.height)
    # the submission is checked (and decoded) before any rendering is spent on it; decoding and comparing
    # run on pool threads, a bounded number at once
    decoded = [await anyio.to_thread.run_sync(_read_image, image, size, limiter=service.grading)]
    png = await rendered(request, job)
    asked = Comparison(
        tolerance,
        max_fraction,
        heatmap if format == "png" else None,
        legend,
        job if diagnose and format == "json" else None,
    )

    def work(gone: Callable[[], bool]) -> Response | bytes:
        return _compare(png, decoded, asked, service, gone)

    try:
        answer = await watched(request, work, service.grading)
    except (Busy, TooSlow, ClusterDown) as exc:  # (the verdict could not be decided now: never a FAIL)
        raise unavailable(exc, service) from None
    if isinstance(answer, bytes):  # the heat-map, served as every image is
        return whole(service, answer, "image/png", f"heat-map: {size[0]}×{size[1]} pixels as png")
    return answer


def _read_image(image: bytes, size: tuple[int, int]) -> Any:
    try:
        return pipeline.read_image(image, size)
    except grading.ImageError as exc:
        release()  # what a refused decode allocated goes back to the OS
        raise HTTPProblem(422, f"image: {exc}", part="image") from None


@dataclass(frozen=True)
class Comparison:
    """What a grade request asks of its submission: the thresholds it is held to, the heat-map to draw instead
    of a grade (``None``: the grade itself) and whether it has a legend, and the job whose scene a failing grade
    is diagnosed against (``None``: no diagnosis)."""

    tolerance: float
    max_fraction: float
    heatmap: Kind | None
    legend: bool
    explain: Job | None


def _compare(
    png: bytes, decoded: list[Any], asked: Comparison, service: RenderService, gone: Callable[[], bool] = lambda: False
) -> Response | bytes:
    """Grade the submission in ``decoded`` (taken out of it, so that nothing else holds its pixels) as ``asked``,
    or draw its heat-map (its PNG's bytes), diagnose a failing grade of ``asked.explain``'s scene, and hand the
    memory of the images back to the OS before answering."""
    submitted = decoded.pop()
    try:
        reference = decode_png(png)
        graded = pipeline.compare(
            png, submitted, asked.tolerance, asked.max_fraction, asked.heatmap, asked.legend, reference=reference
        )
        if asked.explain is not None:
            graded = service.explain(asked.explain, graded, reference, submitted, gone)
        if graded.heatmap is not None:
            return graded.heatmap
        return JSONResponse(graded.as_dict())
    finally:
        del submitted
        release()


#: the form's fields, each of which a grade reads once
FIELDS = ("scene", "image", "tolerance", "max_fraction", "diagnose")


def _once(form: Any) -> None:
    """A field sent twice is refused, naming it: which of the two a grade took would be a guess."""
    for name in FIELDS:
        if (times := len(form.getlist(name))) > 1:
            said = f"{name}: given {times} times in the form; send it once"
            raise HTTPProblem(422, said, part=name if name in ("scene", "image") else None)


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
