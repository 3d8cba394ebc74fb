"""The operator console: a map page at `/`, its static files under `/console/`, and the
Swagger UI of `/docs` served from the package instead of a CDN (the console must work
with no network but the service's own).

The page uses only the public API; this module serves files and nothing else.
"""

from __future__ import annotations

import html
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from starlette.routing import Route

from gcs.service.settings import Settings

STATIC = Path(__file__).parent / "static"
ASSETS = "/console"
SWAGGER = f"{ASSETS}/vendor/swagger-ui"

# Everything the page may fetch comes from this service; map tiles, when configured, are
# the one exception, so their origin is added to img-src.
_CSP = (
    "default-src 'self'; img-src 'self' data: {tiles}; connect-src 'self'; "
    "style-src 'self' 'unsafe-inline'; script-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'"
)


def mount_console(app: FastAPI, settings: Settings) -> None:
    """Serve the console at `/` and the API docs' assets locally; announce the URL."""
    page = _page(settings.console_tile_url)
    headers = {"Content-Security-Policy": _CSP.format(tiles=_origin(settings.console_tile_url))}

    async def console(_: Request) -> HTMLResponse:
        return HTMLResponse(page, headers={**headers, "Cache-Control": "no-cache"})

    app.add_route("/", console, include_in_schema=False)
    app.mount(ASSETS, StaticFiles(directory=STATIC), name="console")
    _local_swagger_ui(app)
    _announce_after_start(app, settings)


def _page(tile_url: str) -> str:
    """index.html with the tile URL in a meta tag (the page reads it; empty = offline)."""
    text = (STATIC / "index.html").read_text(encoding="utf-8")
    return text.replace("{{TILE_URL}}", html.escape(tile_url, quote=True))


def _origin(url: str) -> str:
    """The scheme and host of a tile URL template, for the page's img-src."""
    if "://" not in url:
        return ""
    scheme, rest = url.split("://", 1)
    host = rest.split("/", 1)[0]
    # A {s} subdomain placeholder cannot be named exactly in a CSP: allow the domain's
    # subdomains instead.
    host = host.replace("{s}.", "*.") if host.startswith("{s}.") else host
    return f"{scheme}://{host}"


def _local_swagger_ui(app: FastAPI) -> None:
    """Replace FastAPI's /docs route by the same page loading the vendored Swagger UI."""
    if not (app.docs_url and app.openapi_url):
        return
    openapi_url, redirect = app.openapi_url, app.swagger_ui_oauth2_redirect_url
    parameters: dict[str, Any] = {**(app.swagger_ui_parameters or {}), "validatorUrl": None}

    async def docs(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "").rstrip("/")
        return get_swagger_ui_html(
            openapi_url=root + openapi_url,
            title=f"{app.title} - Swagger UI",
            swagger_js_url=f"{root}{SWAGGER}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{SWAGGER}/swagger-ui.css",
            swagger_favicon_url=f"{root}{SWAGGER}/favicon-32x32.png",
            oauth2_redirect_url=root + redirect if redirect else None,
            init_oauth=app.swagger_ui_init_oauth,
            swagger_ui_parameters=parameters,
        )

    routes = app.router.routes
    for i, route in enumerate(routes):
        if isinstance(route, Route) and route.path == app.docs_url:
            routes[i] = Route(app.docs_url, docs, include_in_schema=False)


def _announce_after_start(app: FastAPI, settings: Settings) -> None:
    """Print the console's URL beside the docs' one, once the service has started."""
    inner = app.router.lifespan_context

    @asynccontextmanager
    async def lifespan(application: Any) -> AsyncIterator[Any]:
        async with inner(application) as state:
            print(f"mvo-gcs: console at http://{settings.host}:{settings.port}/", flush=True)
            yield state

    app.router.lifespan_context = lifespan
