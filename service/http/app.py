"""Builds the FastAPI application; nothing else happens here."""

from __future__ import annotations

import html
import json
import os
from pathlib import Path
from typing import Any

import fastapi_offline
from fastapi import FastAPI, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles

from schemas import Scene
from service.heatmap import LEGEND
from service.http.jobs import RenderService
from service.http.middleware import ApiKey, BodyLimit, Framing
from service.http.routes import HTTPProblem, SafeJSONResponse, problem_response, router
from service.settings import Settings

#: the playground's page and the example scene, shipped as package data of service
STATIC = Path(__file__).parent.parent / "static"
EXAMPLE = STATIC / "example.json"
DOCS_ASSETS = Path(fastapi_offline.__file__).parent / "static"
#: the docs pages may load nothing from elsewhere: the browser does not even try
SAME_ORIGIN = ("default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
               "img-src 'self' data: blob:; worker-src 'self' blob:; connect-src 'self'")


def examples() -> dict[str, str]:
    """The playground's examples: every scene of the project's examples/ folder ($PHONGRAY_EXAMPLES, the source
    tree's, or ./examples as in the Docker image), else the one scene the package ships."""
    for folder in (os.environ.get("PHONGRAY_EXAMPLES"), Path(__file__).parents[2] / "examples",
                   Path.cwd() / "examples"):
        if folder and Path(folder).is_dir():
            found = {p.stem: p.read_text() for p in sorted(Path(folder).glob("*.json"))}
            if found:
                return found
    return {"example": EXAMPLE.read_text()}


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

    scenes = examples()
    page = (STATIC / "playground.html").read_text().replace(
        "__EXAMPLES__", json.dumps(scenes).replace("</", "<\\/")).replace(
        "__LEGEND__", json.dumps(LEGEND)).replace(
        "__EXAMPLE__", html.escape(next(iter(scenes.values())), quote=False))

    @app.get("/", include_in_schema=False)
    def playground() -> HTMLResponse:
        return HTMLResponse(page, headers={"Content-Security-Policy": SAME_ORIGIN})

    # Swagger UI and ReDoc from the assets the fastapi-offline package ships (a maintained PyPI package: no
    # npm build of ours, no CDN), so that the docs work with no internet access
    app.mount("/docs-assets", StaticFiles(directory=DOCS_ASSETS), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        page = get_swagger_ui_html(openapi_url="/openapi.json", title="phongray API",
                                   swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                                   swagger_css_url="/docs-assets/swagger-ui.css", swagger_favicon_url="/favicon.ico",
                                   swagger_ui_parameters={"tryItOutEnabled": True, "persistAuthorization": True})
        page.headers["Content-Security-Policy"] = SAME_ORIGIN
        return page

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        page = get_redoc_html(openapi_url="/openapi.json", title="phongray API",
                              redoc_js_url="/docs-assets/redoc.standalone.js", redoc_favicon_url="/favicon.ico",
                              with_google_fonts=False)
        page.headers["Content-Security-Policy"] = SAME_ORIGIN  # (ReDoc's sidebar logo would come from its CDN)
        return page

    @app.get("/favicon.ico", include_in_schema=False)
    def favicon() -> Response:
        return Response((STATIC / "favicon.svg").read_bytes(), media_type="image/svg+xml")

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

    def body_limit(path: str) -> int:
        extra = settings.max_image_bytes if path == "/grade" else 0
        return settings.max_body_bytes + extra

    app.state.body_limit = body_limit  # (also the most a form part may be: service.routes)
    app.add_middleware(BodyLimit, limit=body_limit, grace=settings.body_timeout, min_rate=settings.body_min_rate,
                       budget=settings.max_buffered_bytes, wait=settings.buffer_wait, retry_after=settings.retry_after)
    if settings.api_key:
        app.add_middleware(ApiKey, key=settings.api_key)
    app.add_middleware(Framing)  # (the outermost: before the key is asked for)
    return app
