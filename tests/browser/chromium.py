"""Debian's Chromium under Playwright for the console's browser tests: the page, what it
logged as errors and any request it made outside the service."""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
NEEDS_CHROMIUM = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not Path(CHROMIUM).exists(),
        reason="Chromium is not installed (apt-get install chromium; .ci/run does it)",
    ),
]
# Playwright adds --headless and a fresh --user-data-dir of its own (it refuses ours).
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
VIEWPORT = {"width": 1280, "height": 800}


@dataclass
class Browser:
    page: Any
    service_url: str
    errors: list[str] = field(default_factory=list)
    foreign: list[str] = field(default_factory=list)

    def js(self, expression: str, arg: Any = None) -> Any:
        return self.page.evaluate(expression, arg)

    def wait_js(self, expression: str, timeout_s: float, arg: Any = None) -> Any:
        return self.page.wait_for_function(expression, arg=arg, timeout=timeout_s * 1000)

    def shot(self, directory: Path, name: str) -> Path:
        path = directory / name
        self.page.screenshot(path=str(path))
        return path
