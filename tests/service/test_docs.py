"""``/docs``, ``/redoc`` and ``/viewer`` name no outside address: every page and every script
and stylesheet they load, as served, scanned for ``http(s)://`` addresses (the browser test,
tests/service/test_browser.py, checks that no request leaves and the console stays clean)."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from typing import Any
from urllib.parse import urljoin, urlsplit

import pytest

from service import docs

PAGES = ("/docs", "/redoc", "/viewer/")
ADDRESS = re.compile(r"https?://[^\s\"'`<>()\\]*")
#: The service's own address under the test client.
OWN = "testserver"
#: Addresses in the vendors' bundles (Swagger UI, ReDoc) that no page ever requests or shows,
#: by host, with why: XML and JSON-Schema identifiers compared as strings, links inside error
#: messages and code comments, a linkifier's patterns, the specification's own fields (none of
#: which this service's schema sets), and Swagger UI's validator (switched off by
#: ``validatorUrl: null``, asserted below).
NOT_ADDRESSES = {
    "identifiers": {"www.w3.org", "json-schema.org", "spec.openapis.org",
                    "raw.githubusercontent.com"},
    "messages and comments": {"reactjs.org", "redux.js.org", "github.com", "git.io", "fb.me",
                              "marked.js.org", "stackoverflow.com", "datatracker.ietf.org",
                              "www.rfc-editor.org", "redocly.com", "vladimirgorej.com",
                              "swagger.io"},
    "linkifier patterns and samples": {"twitter.com", "www.facebook.com", "instagram.com",
                                       "www.tiktok.com", "soundcloud.com", "example.com",
                                       "xn--9n2bp8q.com", "실례.com"},
    "templates filled from the schema when it sets them": {"spdx.org", "api.${i}", "api.${n}",
                                                           "base${string", ""},
    "switched off": {"validator.swagger.io"},
}
VENDOR = "/static-offline-docs/"


class Loads(HTMLParser):
    """The scripts and stylesheets a page loads."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "script" and a.get("src"):
            self.urls.append(str(a["src"]))
        if tag == "link" and a.get("href") and "stylesheet" in (a.get("rel") or ""):
            self.urls.append(str(a["href"]))


def served(client: Any) -> dict[str, str]:
    """Every page and asset as served: ``{path: text}``."""
    out: dict[str, str] = {}
    for page in PAGES:
        r = client.get(page)
        assert r.status_code == 200, page
        out[page] = r.text
        parser = Loads()
        parser.feed(r.text)
        for url in parser.urls:
            path = urlsplit(urljoin(f"http://{OWN}{page}", url)).path
            asset = client.get(path)
            assert asset.status_code == 200, path
            out[path] = asset.text
    return out


def outside(text: str) -> set[str]:
    return {a for a in ADDRESS.findall(text) if urlsplit(a).hostname != OWN}


@pytest.fixture(scope="module")
def assets(client: Any) -> dict[str, str]:
    return served(client)


def test_the_pages_and_the_viewer_name_no_outside_address(assets: dict[str, str]) -> None:
    ours = {path: outside(text) for path, text in assets.items() if not path.startswith(VENDOR)}
    assert set(ours) >= {*PAGES, "/viewer/viewer.js", "/viewer/viewer.css"}
    assert ours == {path: set() for path in ours}


def test_the_vendor_bundles_name_no_address_they_would_request(
        assets: dict[str, str]) -> None:
    vendor = {path for path in assets if path.startswith(VENDOR)}
    assert vendor >= {f"{VENDOR}swagger-ui-bundle.js", f"{VENDOR}swagger-ui.css",
                      f"{VENDOR}redoc.standalone.js"}
    allowed = set().union(*NOT_ADDRESSES.values())
    found = {a for path in vendor for a in outside(assets[path])}
    assert {a for a in found if (urlsplit(a).hostname or "") not in allowed} == set()
    redoc = assets[f"{VENDOR}redoc.standalone.js"]
    assert "cdn.redoc.ly" not in redoc and 'href:"https://redocly.com/redoc/"' not in redoc
    assert '"validatorUrl": null' in assets["/docs"]


def test_redocs_logo_is_drawn_inline() -> None:
    bundle = docs.redoc_bundle().decode()
    assert bundle.count('src:"data:image/svg+xml,') == 1
    for old, _ in docs.REDOC_PATCHES:
        assert old not in bundle
