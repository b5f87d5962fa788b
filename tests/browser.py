"""A real Chromium for the studio's browser tests: Debian's package driven by Playwright.

Playwright's own browser download cannot reach its host here, so the tests launch the
system's ``chromium`` (``make browser`` installs it) through ``executable_path``. WebGL runs
on SwiftShader (no GPU). A missing browser fails the test (conftest), never skips it.
"""

from __future__ import annotations

import shutil
from contextlib import contextmanager

#: where Debian's package puts it; ``RIGMAP_CHROMIUM`` names another
CHROMIUM_NAMES = ("chromium", "chromium-browser")
#: software WebGL on a machine without a GPU
CHROMIUM_ARGS = ["--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
VIEWPORT = {"width": 1000, "height": 700}


def chromium_path() -> str | None:
    import os

    named = os.environ.get("RIGMAP_CHROMIUM")
    if named:
        return named
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)


@contextmanager
def chromium_page(url: str | None = None, *, viewport=VIEWPORT):
    """A fresh Chromium page (optionally at ``url``), closed afterwards."""
    from playwright.sync_api import sync_playwright

    path = chromium_path()
    if path is None:
        raise RuntimeError("Chromium is missing: make browser (apt-get install chromium)")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=path, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport=viewport)
            if url is not None:
                page.goto(url)
            yield page
        finally:
            browser.close()


def keep_screenshot(png: bytes, name: str) -> None:
    """Keep a test's screenshot as a picture of the docs when ``RIGMAP_SCREENSHOTS`` names a
    folder (``RIGMAP_SCREENSHOTS=docs/studio make test`` refreshes ``docs/studio/``); a
    plain test run writes nothing outside its temporary folders."""
    import os
    from pathlib import Path

    folder = os.environ.get("RIGMAP_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        (Path(folder) / name).write_bytes(png)
