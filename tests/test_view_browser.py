"""The web viewer, served as ``log --view`` serves it without a display, loads a drive's
recording in a real browser (Debian's headless chromium, driven by Playwright) without errors,
and a screenshot shows the rover's path. The screenshot stays in the test's temporary folder
(its path is printed) for CI to keep.

Skipped where chromium is not installed, except in CI (``CI=true``), where .ci/run installs it
and a skip would hide a broken view: there it fails."""

from __future__ import annotations

import os
import time
import urllib.parse
from pathlib import Path

import pytest

rr = pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from mecanum_mav.app.rerunview import _PATH_COLOUR  # noqa: E402
from mecanum_mav.app.view import serve_rrd, write_rrd  # noqa: E402
from mecanum_mav.config.params import Params  # noqa: E402
from mecanum_mav.io.tlog import read_tlog  # noqa: E402
from mecanum_mav.sim.sampledrive import sample_drive  # noqa: E402

CHROMIUM = Path(os.environ.get("MECANUM_CHROMIUM", "/usr/bin/chromium"))
"""Debian's chromium (apt-get install chromium; .ci/run installs it)."""
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
"""Headless, and no calls to hosts off this machine (the network is closed)."""
LOAD_TIMEOUT_S = 120.0
"""How long the viewer may take to show the recording (software rendering, 2 shared cores)."""
PATH_PIXELS = 150
"""Pixels of the estimated path's colour that show the path was drawn."""
_FETCH_FAILED = ("Failed to load resource", "Failed to fetch")


def _need(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"CI: {reason}")
    pytest.skip(reason)


def _path_pixels(png: bytes) -> int:
    """Pixels within a few levels of the estimated path's colour."""
    import io

    import numpy as np
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    near = np.abs(image - np.array(_PATH_COLOUR)).max(axis=2) <= 30
    return int(near.sum())


def _loopback(url: str) -> bool:
    host = urllib.parse.urlsplit(url).hostname or ""
    return host in ("127.0.0.1", "localhost", "::1") or url.startswith(("data:", "blob:"))


@pytest.mark.slow
def test_the_served_web_viewer_loads_a_drives_recording_and_draws_its_path(tmp_path):
    if not CHROMIUM.exists():
        _need(f"no chromium at {CHROMIUM} (apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _need("playwright is not installed (the test extra)")
    tlog = tmp_path / "drive.tlog"
    with tlog.open("wb") as f:
        sample_drive(f)
    rrd = tmp_path / "drive.rrd"
    write_rrd(read_tlog(tlog).entries, Params(), rrd)
    errors: list[str] = []
    off_machine: list[str] = []
    failed_here: list[str] = []
    shot = tmp_path / "view.png"
    viewer = serve_rrd(rrd, 0, native=False)
    try:
        assert viewer.url is not None
        with sync_playwright() as p:
            context = p.chromium.launch_persistent_context(
                str(tmp_path / "profile"), executable_path=str(CHROMIUM), headless=True,
                args=FLAGS, viewport={"width": 1600, "height": 1000})

            def route(r):
                if _loopback(r.request.url):
                    r.continue_()
                else:
                    off_machine.append(r.request.url)
                    r.abort()

            context.route("**/*", route)
            page = context.new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.on("requestfailed", lambda r: failed_here.append(r.url)
                    if _loopback(r.url) else None)
            page.goto(viewer.url)
            deadline = time.monotonic() + LOAD_TIMEOUT_S
            drawn = 0
            while time.monotonic() < deadline:
                png = page.screenshot()
                drawn = _path_pixels(png)
                if drawn >= PATH_PIXELS:
                    break
                page.wait_for_timeout(1000)
            page.wait_for_timeout(2000)  # the rest of the first frames
            page.screenshot(path=str(shot))
            context.close()
    finally:
        viewer.close()
    print(f"screenshot: {shot}")
    assert drawn >= PATH_PIXELS, f"the path was not drawn in {LOAD_TIMEOUT_S:g} s ({shot})"
    assert failed_here == []
    # The viewer asks hosts off this machine for extras (blocked here); those fetches fail
    # and say so. Anything else said at error level is an error of the view.
    unexplained = [e for e in errors
                   if not (off_machine and any(text in e for text in _FETCH_FAILED))]
    assert unexplained == [], f"{unexplained} (blocked: {off_machine})"
