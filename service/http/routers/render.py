"""The routes of a scene: render it (or one pass of it), or validate it."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal, get_args

import anyio
from fastapi import APIRouter, Query, Request, Response

from schemas import validate_scene
from service.http.models import ValidAnswer
from service.http.problems import ERRORS, HTTPProblem, answering, prepared, require_json, unavailable
from service.http.waiting import rendered, streamed, watched, whole
from service.render.passes import PassFile
from service.work.jobs import Busy, ClusterDown, Job, RenderService, TooSlow, parse_counted

router = APIRouter()

#: the request example: a real scene of examples/ (the one the package ships), so that "Try it out" renders
EXAMPLE_TEXT = (Path(__file__).parents[2] / "static" / "example.json").read_text()

SCENE_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/Scene"}, "example": json.loads(EXAMPLE_TEXT)}
        },
    }
}


PassName = Literal[
    "background", "ambient", "diffuse", "specular", "reflection", "refraction", "shadow", "normal", "depth", "object"
]

PASS_HELP = (
    "render one pass instead of the image: an additive term (background, ambient, diffuse, specular, "
    "reflection, refraction; they sum to the image's linear value), a light's visibility (shadow), or "
    "normal, depth, object for debugging"
)


def _validate(body: bytes, service: RenderService) -> None:
    answering(lambda: validate_scene(parse_counted(body, service.settings)), body)


@router.post(
    "/render",
    openapi_extra=SCENE_BODY,
    responses={
        200: {
            "content": {"image/png": {}, "application/x-npy": {}},
            "description": "the image (or with pass, the pass as a PNG or a .npy array)",
        },
        304: {},
        **ERRORS,
    },
    response_class=Response,
    summary="Render a scene to a PNG",
)
async def render_scene(
    request: Request,
    width: Annotated[int | None, Query(ge=1)] = None,
    height: Annotated[int | None, Query(ge=1)] = None,
    samples: Annotated[int | None, Query(ge=1)] = None,
    pass_: Annotated[PassName | None, Query(alias="pass", description=PASS_HELP)] = None,
    light: Annotated[
        int | None,
        Query(
            ge=0,
            description="with pass: the index in lights of "
            "the one light whose diffuse, specular or shadow is "
            "shown (default: every light)",
        ),
    ] = None,
    format: Annotated[
        Literal["png", "npy"], Query(description="with pass: a PNG to look at, or the values as a NumPy .npy array")
    ] = "png",
) -> Response:
    require_json(request)
    if pass_ is None:  # (as the command line refuses --light or an .npy file without --pass; format=png, the
        # default, which the API page's "Try it out" sends with every render, asks for what a render gives)
        for option in ("format", "light"):
            if option in request.query_params and request.query_params.get(option) != "png":
                raise HTTPProblem(
                    422,
                    f"{option}: applies to a render pass only; add pass=NAME (one of "
                    f"{', '.join(get_args(PassName))}) or leave {option} out",
                )
    service: RenderService = request.app.state.service
    body = await request.body()
    job = await anyio.to_thread.run_sync(
        prepared, body, {"width": width, "height": height, "samples": samples}, service, limiter=service.parsing
    )
    if pass_ is not None:
        return await _pass(request, job, PassRequest(pass_, light, format))
    if _none_match(request.headers.get("if-none-match", ""), job.etag):
        return Response(status_code=304, headers={"ETag": job.etag, "Cache-Control": "no-cache"})
    started = time.perf_counter()
    headers = {"ETag": job.etag}  # (Cache-Control: no-cache is every streamed answer's own)
    headers["X-Cache"] = "hit" if job.key in service.cache else "miss"  # (the playground says "from cache")
    data = await rendered(request, job)
    headers["X-Render-Seconds"] = f"{time.perf_counter() - started:.4f}"
    what = f"render: {job.scene.image.width}×{job.scene.image.height} pixels as png"
    return whole(service, data, "image/png", what, headers)  # (served as a pass is: priced, streamed)


@dataclass(frozen=True)
class PassRequest:
    """A render's ``pass`` query: the pass, the one light it shows (``None``: every light) and its format."""

    name: str
    light: int | None
    format: Literal["png", "npy"]


async def _pass(request: Request, job: Job, asked: PassRequest) -> Response:
    service: RenderService = request.app.state.service

    def work(gone: Callable[[], bool]) -> tuple[PassFile, int]:
        return answering(lambda: service.pass_file(job, asked.name, asked.light, asked.format, gone), "")

    try:
        made, held = await watched(request, work, service.grading)
    except ValueError as exc:  # a light the scene does not have
        raise HTTPProblem(422, str(exc)) from None
    except (Busy, TooSlow, ClusterDown) as exc:
        raise unavailable(exc, service) from None
    return streamed(service, made, held)


@router.post(
    "/validate",
    openapi_extra=SCENE_BODY,
    summary="Check a scene; list every error with its place",
    response_model=ValidAnswer,
    responses={413: ERRORS[413], 415: ERRORS[415], 422: ERRORS[422]},
)
async def validate(request: Request) -> dict[str, bool]:
    require_json(request)
    body = await request.body()
    service: RenderService = request.app.state.service
    await anyio.to_thread.run_sync(_validate, body, service, limiter=service.parsing)
    return {"valid": True}


def _none_match(header: str, etag: str) -> bool:
    """Whether ``If-None-Match`` matches the render's ETag, as RFC 9110 §13.1.2 compares: ``*``, or any of its
    tags weakly (``W/"…"`` matches ``"…"``)."""
    tags = [t.strip() for t in header.split(",")]
    return "*" in tags or any(t.removeprefix("W/") == etag.removeprefix("W/") for t in tags)
