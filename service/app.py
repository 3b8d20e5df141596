"""Builds the FastAPI application; nothing else happens here."""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse

from schemas import Scene

from .jobs import RenderService
from .middleware import ApiKey, BodyLimit
from .routes import HTTPProblem, SafeJSONResponse, problem_response, router
from .settings import Settings

STATIC = Path(__file__).parent / "static"
EXAMPLE = Path(__file__).parent / "static" / "example.json"


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    app = FastAPI(title="phongray", version="0.1.0", docs_url=None, redoc_url=None,
                  description="A reference Phong/Whitted ray tracer: render, validate and grade scenes.")
    app.state.service = RenderService(settings)
    app.state.flights = {}  # scene key → the render in progress that requests for it wait on (service.routes)
    app.include_router(router)

    @app.exception_handler(HTTPProblem)
    async def on_problem(request: Request, exc: HTTPProblem) -> JSONResponse:
        return problem_response(exc)

    @app.exception_handler(RequestValidationError)
    async def on_invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = [{"path": ".".join(str(p) for p in err["loc"]), "message": err["msg"], "line": None}
                  for err in exc.errors()]
        return SafeJSONResponse({"detail": "invalid request", "errors": errors}, status_code=422)

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def playground() -> str:
        page = (STATIC / "playground.html").read_text()
        return page.replace("__EXAMPLE__", EXAMPLE.read_text().replace("</", "<\\/"))

    @app.get("/docs", response_class=HTMLResponse, include_in_schema=False)
    def docs() -> str:
        return (STATIC / "docs.html").read_text()

    original_openapi = app.openapi

    def openapi() -> dict:  # type: ignore[type-arg]
        if app.openapi_schema is None:
            schema = original_openapi()
            scene_schema = Scene.model_json_schema(ref_template="#/components/schemas/{model}")
            defs = scene_schema.pop("$defs", {})
            schema.setdefault("components", {}).setdefault("schemas", {}).update({**defs, "Scene": scene_schema})
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]

    def body_limit(path: str) -> int:
        extra = settings.max_image_bytes if path == "/grade" else 0
        return settings.max_body_bytes + extra

    app.add_middleware(BodyLimit, limit=body_limit, grace=settings.body_timeout, min_rate=settings.body_min_rate)
    if settings.api_key:
        app.add_middleware(ApiKey, key=settings.api_key)
    return app
