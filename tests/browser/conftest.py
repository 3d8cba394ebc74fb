"""The browser tests' fixtures: a real `mvo-gcs serve`, Chromium on its console, and where
screenshots go (MVO_GCS_SCREENSHOTS, docs/console/ to refresh the committed ones, else
the test's temporary directory)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.browser.chromium import CHROMIUM, CHROMIUM_FLAGS, VIEWPORT, Browser
from tests.service_process import ServiceProcess


@pytest.fixture
def shots(tmp_path: Path) -> Path:
    directory = Path(os.environ.get("MVO_GCS_SCREENSHOTS") or tmp_path / "shots")
    directory.mkdir(parents=True, exist_ok=True)
    return directory


@pytest.fixture
def service(tmp_path: Path) -> Iterator[ServiceProcess]:
    proc = ServiceProcess(tmp_path / "data")
    proc.start()
    yield proc
    proc.stop()


@pytest.fixture
def browser(service: ServiceProcess) -> Iterator[Browser]:
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(
            executable_path=CHROMIUM,
            args=CHROMIUM_FLAGS,
        )
        # Playwright's waits evaluate strings, which the console's CSP forbids the page.
        context = chromium.new_context(viewport=VIEWPORT, bypass_csp=True)
        page = context.new_page()
        page.set_default_timeout(60_000)
        b = Browser(page, service.url)

        def console(message: Any) -> None:
            if message.type == "error":
                b.errors.append(message.text)

        page.on("console", console)
        page.on("pageerror", lambda e: b.errors.append(f"uncaught: {e}"))
        ws_url = service.url.replace("http://", "ws://")

        def outside(request: Any) -> None:
            if not request.url.startswith((service.url, ws_url, "data:")):
                b.foreign.append(request.url)

        page.on("request", outside)
        try:
            yield b
        finally:
            context.close()
            chromium.close()
