"""Builds the FastAPI application; nothing else happens here."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles

from schemas import Scene
from service.http.middleware import ApiKey, BodyLimit, Framing
from service.http.problems import HTTPProblem, SafeJSONResponse, problem_response
from service.http.routers import grade, render, status
from service.http.routers.playground import DOCS_ASSETS, playground_router
from service.settings import Settings
from service.work.jobs import RenderService


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    app = FastAPI(
        title="phongray",
        version="0.1.0",
        docs_url=None,
        redoc_url=None,
        description="A reference Phong/Whitted ray tracer: render, validate and grade scenes.",
    )
    app.state.service = RenderService(settings)
    app.state.flights = {}  # scene key → the render in progress that requests for it wait on (service.http.waiting)
    app.include_router(render.router)
    app.include_router(grade.router)
    app.include_router(status.router)
    app.include_router(playground_router())
    # Swagger UI and ReDoc from the assets the fastapi-offline package ships (a maintained PyPI package: no
    # npm build of ours, no CDN), so that the docs work with no internet access
    app.mount("/docs-assets", StaticFiles(directory=DOCS_ASSETS), name="docs-assets")
    _answer_errors(app)
    _document(app)
    _guard(app, settings)
    return app


def _answer_errors(app: FastAPI) -> None:
    """Error answers as JSON: an :class:`HTTPProblem` as itself, FastAPI's own checks of a request's query as 422
    with every problem."""

    @app.exception_handler(HTTPProblem)
    async def on_problem(request: Request, exc: HTTPProblem) -> JSONResponse:
        return problem_response(exc)

    @app.exception_handler(RequestValidationError)
    async def on_invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = [
            {"path": ".".join(str(p) for p in err["loc"]), "message": err["msg"], "line": None} for err in exc.errors()
        ]
        return SafeJSONResponse({"detail": "invalid request", "errors": errors}, status_code=422)


def _document(app: FastAPI) -> None:
    """The OpenAPI schema, with the scene's JSON Schema among its components and the API key as its security."""
    original_openapi = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = original_openapi()
            scene_schema = Scene.model_json_schema(ref_template="#/components/schemas/{model}")
            defs = scene_schema.pop("$defs", {})
            components = schema.setdefault("components", {})
            components.setdefault("schemas", {}).update({**defs, "Scene": scene_schema})
            # Swagger UI's "Authorize": the key of a service that has one (PHONGRAY_API_KEY)
            needed = "needed when the service sets PHONGRAY_API_KEY"
            components["securitySchemes"] = {"apiKey": {"type": "http", "scheme": "bearer", "description": needed}}
            schema["security"] = [{"apiKey": []}, {}]
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def _guard(app: FastAPI, settings: Settings) -> None:
    """The middleware: a body's size and pace, the API key when there is one, the framing of every request."""

    def body_limit(path: str) -> int:
        extra = settings.max_image_bytes if path == "/grade" else 0
        return settings.max_body_bytes + extra

    app.state.body_limit = body_limit  # (also the most a form part may be: service.http.routers.grade)
    app.add_middleware(
        BodyLimit,
        limit=body_limit,
        grace=settings.body_timeout,
        min_rate=settings.body_min_rate,
        budget=settings.max_buffered_bytes,
        wait=settings.buffer_wait,
        retry_after=settings.retry_after,
    )
    if settings.api_key:
        app.add_middleware(ApiKey, key=settings.api_key)
    app.add_middleware(Framing)  # (the outermost: before the key is asked for)
