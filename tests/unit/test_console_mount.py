"""The console's files as the service serves them: the page, its CSP, the tile setting,
and the API docs from local assets (no network needed beyond the service)."""

from __future__ import annotations

import re
from pathlib import Path

import httpx

from gcs.service.api.app import create_app
from gcs.service.console import STATIC
from gcs.service.settings import Settings


def client(tmp_path: Path, **settings: object) -> httpx.AsyncClient:
    """The app without its lifespan (no storage, no pool): only static routes are used."""
    app = create_app(Settings(data_dir=tmp_path, allowed_hosts=["test"], **settings))  # type: ignore[arg-type]
    return httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://test")


async def test_the_console_is_served_at_the_root_offline_by_default(tmp_path: Path) -> None:
    c = client(tmp_path)
    answer = await c.get("/")
    assert answer.status_code == 200 and "text/html" in answer.headers["content-type"]
    assert '<meta name="tile-url" content="">' in answer.text
    csp = answer.headers["content-security-policy"]
    assert "default-src 'self'" in csp and "script-src 'self'" in csp
    for asset in re.findall(r'(?:src|href)="(/console/[^"]+)"', answer.text):
        assert (await c.get(asset)).status_code == 200, asset


async def test_a_tile_url_reaches_the_page_and_its_csp(tmp_path: Path) -> None:
    url = "https://{s}.tiles.example/{z}/{x}/{y}.png?key=<k>"
    answer = await client(tmp_path, console_tile_url=url).get("/")
    assert 'content="https://{s}.tiles.example/{z}/{x}/{y}.png?key=&lt;k&gt;"' in answer.text
    assert (
        "img-src 'self' data: https://*.tiles.example;" in answer.headers["content-security-policy"]
    )


async def test_api_docs_load_their_assets_from_the_service(tmp_path: Path) -> None:
    c = client(tmp_path)
    page = (await c.get("/docs")).text
    urls = re.findall(r'(?:src|href)="([^"]+)"', page)
    assert urls and all(u.startswith("/console/vendor/swagger-ui/") for u in urls), urls
    assert "cdn" not in page and "validatorUrl" in page
    for url in urls:
        assert (await c.get(url)).status_code == 200, url


async def test_the_console_is_not_part_of_the_api_schema(tmp_path: Path) -> None:
    paths = (await client(tmp_path).get("/openapi.json")).json()["paths"]
    assert "/" not in paths and not any(p.startswith("/console") for p in paths)


def test_every_vendored_library_says_its_version_and_licence() -> None:
    vendor = STATIC / "vendor"
    readme = (vendor / "README.md").read_text()
    for library in (p for p in vendor.iterdir() if p.is_dir()):
        assert f"`{library.name}/`" in readme
        assert (library / "LICENSE").exists(), library
    assert "1.9.4" in (vendor / "leaflet" / "leaflet.js").read_text()[:200]
