"""``/docs`` (Swagger UI) and ``/redoc`` that work offline: their assets are served by the
service itself, from the copies the ``fastapi-offline`` package ships (no CDN).

Both pages carry a Content-Security-Policy that lets them load only from the service, and name
no outside address: ReDoc's bundle hard-codes its vendor's logo from a CDN and a link to the
vendor's site in its sidebar, so the service serves a copy of the bundle with the logo drawn
from :data:`LOGO` (a ``data:`` URI) and the link's address dropped (:func:`redoc_bundle`);
Swagger UI's online validator badge is switched off.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from urllib.parse import quote

import fastapi_offline
from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles

ASSETS = Path(fastapi_offline.__file__).parent / "static"
ASSETS_URL = "/static-offline-docs"
CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data: blob:; font-src 'self' data:; worker-src 'self' blob:; "
       "connect-src 'self'")


#: ReDoc's sidebar logo, served inline: a small linkage (two pins, three bars).
LOGO = ('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 16 16" fill="none" '
        'stroke="#32329f" stroke-width="1.5"><path d="M2 14 5 4l7 2 2 8"/>'
        '<circle cx="2" cy="14" r="1.5"/><circle cx="14" cy="14" r="1.5"/></svg>')
#: What the service's copy of ReDoc's bundle replaces: the CDN logo and the vendor link.
REDOC_PATCHES = (
    ('src:"https://cdn.redoc.ly/redoc/logo-mini.svg"',
     f'src:"data:image/svg+xml,{quote(LOGO, safe="=:/")}"'),
    ('{target:"_blank",rel:"noopener noreferrer",href:"https://redocly.com/redoc/"}', '{}'),
)
REDOC_JS = "redoc.standalone.js"


@cache
def redoc_bundle() -> bytes:
    """ReDoc's bundle with :data:`REDOC_PATCHES` applied (each must apply once: a new
    ``fastapi-offline`` whose bundle differs fails here, at the first request, not silently)."""
    text = (ASSETS / REDOC_JS).read_text(encoding="utf-8")
    for old, new in REDOC_PATCHES:
        if text.count(old) != 1:
            raise RuntimeError(f"ReDoc's bundle has {text.count(old)} copies of {old[:40]!r}")
        text = text.replace(old, new)
    return text.encode("utf-8")


def install(app: FastAPI) -> None:
    """Serve the assets and the two pages (create ``app`` with ``docs_url=None`` and
    ``redoc_url=None``)."""
    # declared before the mount, so that this path is served from here
    @app.get(f"{ASSETS_URL}/{REDOC_JS}", include_in_schema=False)
    async def redoc_js() -> Response:
        return Response(redoc_bundle(), media_type="text/javascript",
                        headers={"cache-control": "public, max-age=3600"})

    app.mount(ASSETS_URL, StaticFiles(directory=ASSETS), name="docs-assets")
    openapi_url = app.openapi_url or "/openapi.json"

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        page = get_swagger_ui_html(
            openapi_url=f"{root}{openapi_url}",
            title=f"{app.title} - Swagger UI",
            swagger_js_url=f"{root}{ASSETS_URL}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{ASSETS_URL}/swagger-ui.css",
            swagger_favicon_url=f"{root}{ASSETS_URL}/favicon.png",
            swagger_ui_parameters={"validatorUrl": None},  # no badge from the validator's site
        )
        page.headers["content-security-policy"] = CSP
        return page

    @app.get("/redoc", include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        page = get_redoc_html(
            openapi_url=f"{root}{openapi_url}",
            title=f"{app.title} - ReDoc",
            redoc_js_url=f"{root}{ASSETS_URL}/redoc.standalone.js",
            redoc_favicon_url=f"{root}{ASSETS_URL}/favicon.png",
            with_google_fonts=False,
        )
        page.headers["content-security-policy"] = CSP
        return page
