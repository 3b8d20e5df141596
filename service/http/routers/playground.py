"""The pages a person opens: the playground (every example scene, the heat-map's legend) and the API's docs
(Swagger UI and ReDoc, from the assets fastapi-offline ships, so that they work with no internet access)."""

from __future__ import annotations

import html
import json
import os
from pathlib import Path

import fastapi_offline
from fastapi import APIRouter, Response
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse

from service.images.heatmap import LEGEND

#: the playground's page and the example scene, shipped as package data of service
STATIC = Path(__file__).parents[2] / "static"
EXAMPLE = STATIC / "example.json"
DOCS_ASSETS = Path(fastapi_offline.__file__).parent / "static"
#: the docs pages may load nothing from elsewhere: the browser does not even try
SAME_ORIGIN = (
    "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; worker-src 'self' blob:; connect-src 'self'"
)


def examples() -> dict[str, str]:
    """The playground's examples: every scene of the project's examples/ folder ($PHONGRAY_EXAMPLES, the source
    tree's, or ./examples as in the Docker image), else the one scene the package ships."""
    for folder in (
        os.environ.get("PHONGRAY_EXAMPLES"),
        Path(__file__).parents[3] / "examples",
        Path.cwd() / "examples",
    ):
        if folder and Path(folder).is_dir():
            found = {p.stem: p.read_text() for p in sorted(Path(folder).glob("*.json"))}
            if found:
                return found
    return {"example": EXAMPLE.read_text()}


def playground_page() -> str:
    """The playground's HTML, with the examples and the legend filled in (once, as the app is made)."""
    scenes = examples()
    return (
        (STATIC / "playground.html")
        .read_text()
        .replace("__EXAMPLES__", json.dumps(scenes).replace("</", "<\\/"))
        .replace("__LEGEND__", json.dumps(LEGEND))
        .replace("__EXAMPLE__", html.escape(next(iter(scenes.values())), quote=False))
    )


def playground_router() -> APIRouter:
    """The pages' routes (none in the API's schema); Swagger UI's and ReDoc's assets are mounted by the app at
    ``/docs-assets`` (:data:`DOCS_ASSETS`)."""
    router = APIRouter(include_in_schema=False)
    page = playground_page()

    @router.get("/")
    def playground() -> HTMLResponse:
        return HTMLResponse(page, headers={"Content-Security-Policy": SAME_ORIGIN})

    @router.get("/docs")
    def docs() -> HTMLResponse:
        page = get_swagger_ui_html(
            openapi_url="/openapi.json",
            title="phongray API",
            swagger_js_url="/docs-assets/swagger-ui-bundle.js",
            swagger_css_url="/docs-assets/swagger-ui.css",
            swagger_favicon_url="/favicon.ico",
            swagger_ui_parameters={"tryItOutEnabled": True, "persistAuthorization": True},
        )
        page.headers["Content-Security-Policy"] = SAME_ORIGIN
        return page

    @router.get("/redoc")
    def redoc() -> HTMLResponse:
        page = get_redoc_html(
            openapi_url="/openapi.json",
            title="phongray API",
            redoc_js_url="/docs-assets/redoc.standalone.js",
            redoc_favicon_url="/favicon.ico",
            with_google_fonts=False,
        )
        page.headers["Content-Security-Policy"] = SAME_ORIGIN  # (ReDoc's sidebar logo would come from its CDN)
        return page

    @router.get("/favicon.ico")
    def favicon() -> Response:
        return Response((STATIC / "favicon.svg").read_bytes(), media_type="image/svg+xml")

    return router
