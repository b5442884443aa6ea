"""The viewer in a real browser during a sim-mode run: headless Chromium (Debian's ``chromium``) opens the page,
the test waits for the first cloud, takes a screenshot and checks the canvas and the status text.

Chromium is driven over the DevTools protocol on ``--remote-debugging-pipe`` (JSON messages ending in a NUL byte
on file descriptors 3 and 4; no port, no extra package). WebGL runs on SwiftShader (``--use-angle=swiftshader``).
The page frames the first cloud from the scanner's side with its bounding sphere filling about 80 % of the view
height, so the scene's pixels must lie around the canvas centre; before the first cloud the canvas is all
background.
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time

import cv2
import numpy as np
import pytest

from tests.launch_files.running import SIM_RIG, TWIN_RIG_ARG, LaunchRun

CHROMIUM = "/usr/bin/chromium"
BACKGROUND_BGR = np.array([24, 20, 16])  # #101418, the page's background
WIDTH, HEIGHT = 800, 600

pytestmark = pytest.mark.skipif(not os.path.exists(CHROMIUM),
                                reason=f"{CHROMIUM} is absent: install Debian's chromium (apt-get install -y chromium)")


class DevTools:
    """Chromium with the DevTools protocol on a pipe: ``call(method, **params)`` returns the result."""

    def __init__(self, url: str, profile_dir: str):
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def child_fds():  # the browser reads commands on fd 3 and writes answers on fd 4
            high_r, high_w = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(high_r, 3)
            os.dup2(high_w, 4)

        args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                f"--user-data-dir={profile_dir}", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                "--remote-debugging-pipe", f"--window-size={WIDTH},{HEIGHT}", "--hide-scrollbars", url]
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, preexec_fn=child_fds, pass_fds=(3, 4))
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer = b""
        self._next_id = 0
        self.session = None

    def call(self, method: str, timeout: float = 30.0, **params):
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params}
        if self.session and not method.startswith("Target."):
            message["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            while b"\0" not in self._buffer:
                chunk = os.read(self._from_browser, 1 << 20)
                if not chunk:
                    raise AssertionError(f"chromium closed the DevTools pipe: {self.stderr()}")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            answer = json.loads(raw)
            if answer.get("id") == self._next_id:
                if "error" in answer:
                    raise AssertionError(f"{method}: {answer['error']}")
                return answer["result"]
        raise AssertionError(f"{method}: no answer within {timeout} s")

    def attach_to_page(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            pages = [t for t in self.call("Target.getTargets")["targetInfos"] if t["type"] == "page"]
            if pages:
                self.session = self.call("Target.attachToTarget", targetId=pages[0]["targetId"],
                                         flatten=True)["sessionId"]
                return
            time.sleep(0.2)
        raise AssertionError("chromium opened no page")

    def evaluate(self, expression: str):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result["result"].get("value")

    def screenshot(self) -> np.ndarray:
        """The page as (H, W, 3) BGR, with the status panel hidden for the shot (it grows as statuses come)."""
        self.evaluate("document.getElementById('panel').style.visibility = 'hidden'")
        try:
            data = self.call("Page.captureScreenshot", format="png")["data"]
        finally:
            self.evaluate("document.getElementById('panel').style.visibility = 'visible'")
        image = cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_COLOR)  # (H, W, 3) BGR
        assert image is not None, "the screenshot is not a PNG"
        return image

    def stderr(self) -> str:
        return self.proc.stderr.read().decode(errors="replace")[-3000:] if self.proc.poll() is not None else ""

    def close(self) -> None:
        for fd in (self._to_browser, self._from_browser):
            try:
                os.close(fd)
            except OSError:
                pass
        self.proc.kill()
        self.proc.wait(timeout=10)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


_STATE_JS = """(() => { try { return JSON.stringify({clouds: viewerState.clouds, statuses: viewerState.statuses,
  live: document.getElementById('connection').textContent === '(live)',
  cloud: document.getElementById('cloud').textContent, scans: document.getElementById('scans').innerText});
} catch (e) { return JSON.stringify({clouds: -1, statuses: -1, live: false, error: String(e)}); } })()"""


def _page_state(browser: DevTools) -> dict:
    """The page's counters and texts; ``clouds == -1`` while the page has not loaded."""
    return json.loads(browser.evaluate(_STATE_JS) or '{"clouds": -1, "statuses": -1, "live": false}')


def _wait_state(browser: DevTools, predicate, timeout: float, run: LaunchRun | None, what: str) -> dict:
    deadline = time.monotonic() + timeout
    state = {}
    while time.monotonic() < deadline:
        state = _page_state(browser)
        if predicate(state):
            return state
        time.sleep(0.3)
    output = run.text(30) if run is not None else ""
    raise AssertionError(f"{what}: not within {timeout} s; page state {state}; launch output:\n{output}")


def _scene_pixels(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels that are not the background (the screenshot hides the status panel)."""
    return np.abs(image.astype(np.int32) - BACKGROUND_BGR).max(axis=-1) > 24


def test_browser_shows_the_sim_rig_cloud_and_the_scan_status(spawn_node, node_env, tmp_path):
    port = _free_port()
    viewer = spawn_node("dptpu.nodes.viewer", "--ros-args", "-p", f"port:={port}")
    assert viewer.wait_for_stderr(f"viewer at http://127.0.0.1:{port}/", timeout=30), viewer.stderr
    profile = tempfile.mkdtemp(prefix="chromium-", dir=tmp_path)
    browser = DevTools(f"http://127.0.0.1:{port}/", profile)
    run = None
    try:
        browser.attach_to_page()
        browser.call("Page.enable")
        browser.call("Emulation.setDeviceMetricsOverride", width=WIDTH, height=HEIGHT, deviceScaleFactor=1,
                     mobile=False)
        _wait_state(browser, lambda s: s["clouds"] == 0 and s["live"], 60, None, "the page connected")
        blank = browser.screenshot()
        assert _scene_pixels(blank).sum() < 0.001 * blank.shape[0] * blank.shape[1]  # nothing yet
        run = LaunchRun(SIM_RIG, "scans:=0", TWIN_RIG_ARG, "size:=160x120", "sequence:=16x4,1x4", "method:=mf",
                        "ply_dir:=", "frame_rate:=20.0", "scenes:=random:1", env=node_env, cwd=tmp_path)

        first = _wait_state(browser, lambda s: s["clouds"] >= 1, 90, run, "the first cloud")
        assert first["cloud"].startswith("cloud ") and "points of 160x120" in first["cloud"], first
        image = browser.screenshot()
        cv2.imwrite(str(tmp_path / "viewer.png"), image)
        assert image.shape[:2] == (HEIGHT, WIDTH)
        scene = _scene_pixels(image)
        count = int(scene.sum())
        assert count > 0.01 * WIDTH * HEIGHT, count  # the scene covers a real part of the canvas
        rows, cols = np.nonzero(scene)
        centre = np.array([HEIGHT / 2, WIDTH / 2])
        assert np.hypot(rows.mean() - centre[0], cols.mean() - centre[1]) < 0.15 * HEIGHT  # centred on the cloud
        radius = np.hypot(rows - centre[0], cols - centre[1])
        assert np.quantile(radius, 0.99) < 0.55 * HEIGHT  # inside the framed bounding sphere

        later = _wait_state(browser, lambda s: s["statuses"] > first["statuses"] and s["clouds"] > first["clouds"]
                            and s["scans"] != first["scans"], 60, run, "a status update")
        assert "scan " in later["scans"] and "done OK" in later["scans"], later
        assert later["cloud"] != first["cloud"] or later["clouds"] > first["clouds"]
    finally:
        browser.close()
        if run is not None:
            run.close()
        shutil.rmtree(profile, ignore_errors=True)
