"""The live view in a real browser: headless Chromium opens the compositor's page while a small
rig (two 160 x 120 channels, the host at 5 Hz for 2 s) flies; the panorama moves between two
screenshots, and once the run is over the page's numbers are report.json's.

Needs Debian's chromium and chromium-driver (.ci/run installs them as root) and selenium (the
test extra); skips, saying which is missing, without them. The last screenshot is kept as
tmp_path/live-view.png (docs/images/live-view.png is one of them).
"""

from __future__ import annotations

import json
import signal
import time
import urllib.request
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from services.demo import free_port, local_rig
from services.rig.image_io import read_image
from services.rig.rigfile import default_rig_path, load_rig, rig_toml

from .conftest import kill_all, start, wait_all

pytestmark = pytest.mark.integration

CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
RATE, DURATION = 5.0, 2.0
FRAMES = int(round(RATE * DURATION)) + 1


def webdriver():
    """selenium's webdriver; skips the test (before any process starts) without it or Chromium."""
    if not CHROMIUM.exists() or not CHROMEDRIVER.exists():
        pytest.skip(f"{CHROMIUM} or {CHROMEDRIVER} missing: apt-get install chromium chromium-driver")
    return pytest.importorskip("selenium.webdriver", reason="selenium is not installed (the test extra)")


def open_browser(webdriver):
    """Headless Chromium, 1200 x 1000: the whole page, for the screenshot."""
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,1000", "--hide-scrollbars"):
        options.add_argument(arg)
    return webdriver.Chrome(options=options, service=webdriver.ChromeService(executable_path=str(CHROMEDRIVER)))


def status(url):
    with urllib.request.urlopen(url + "status.json", timeout=5) as response:
        return json.loads(response.read())


def wait_for(predicate, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


def panorama(driver, path):
    """A screenshot of the page saved at path, and the panorama's pixels cut out of it."""
    driver.save_screenshot(str(path))
    pixels, _ = read_image(path)
    ratio = driver.execute_script("return window.devicePixelRatio")
    box = driver.execute_script("const r = document.getElementById('panorama').getBoundingClientRect();"
                                "return [r.left, r.top, r.width, r.height];")
    x, y, w, h = (int(round(v * ratio)) for v in box)
    assert w > 100 and h > 20, f"the panorama is {w} x {h} px on the page"
    return pixels[y:y + h, x:x + w, :3]


def test_the_page_shows_the_flight_and_ends_on_the_reports_numbers(tmp_path):
    driver = webdriver()
    # Two channels: a panorama with a seam, one worker fewer to start than the default rig's three.
    base = load_rig(default_rig_path()).with_size(160, 120)
    rig = local_rig(replace(base, channels=base.channels[:2]))
    port = free_port()
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    url = f"http://127.0.0.1:{port}/"
    out = tmp_path / "out"
    procs, logs = {}, {}
    browser = None

    def launch(name, argv):
        logs[name] = open(tmp_path / f"{name}.log", "w")  # noqa: SIM115  (closed by kill_all)
        procs[name] = start(argv, logs[name])

    try:
        launch("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--record-every", "0",
                              "--exr-every", "0", "--view-port", str(port)])
        for ch in rig.channel_names:
            launch(ch, ["worker", "--rig", str(rig_path), "--channel", ch])
        launch("host", ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", str(DURATION),
                        "--sync-timeout", "20"])
        # Chromium starts while the rig does.
        browser = open_browser(driver)
        wait_for(lambda: _answers(url), 30.0, "the live view to answer")
        browser.get(url)
        # The first picture as soon as there is one, the second 0.6 s of flight later (the host
        # is frame-locked: a loaded machine slows the flight down, it skips nothing).
        wait_for(lambda: status(url)["shown"] is not None, 60.0, "the first composite")
        time.sleep(0.3)  # the browser's stream
        first = panorama(browser, tmp_path / "first.png")
        later = min(status(url)["shown"]["frame_number"] + 3, FRAMES - 1)
        wait_for(lambda: status(url)["shown"]["frame_number"] >= later, 30.0, f"frame {later}")
        time.sleep(0.3)
        second = panorama(browser, tmp_path / "second.png")
        # The compositor writes the report as the run ends (the host lingers a moment after).
        report_path = out / "latest" / "report.json"
        wait_for(report_path.exists, 60.0, "report.json")
        report = json.loads(report_path.read_text())
        # The page polls once a second: it shows the run's end within two.
        wait_for(lambda: browser.find_element("id", "run-state").text == "run over", 10.0, "the page's run over")
        page = {key: browser.find_element("id", key).text for key in (
            "run-id", "frames-published", "frames-complete", "incomplete-missing_channel",
            "incomplete-eyepoint_mismatch", "latency-p50", "latency-p99", "latency-count", "view-dropped")}
        channels = {ch: browser.find_element("id", f"channel-{ch}").text.split() for ch in rig.channel_names}
        last = panorama(browser, tmp_path / "live-view.png")
        for name in ["compositor", *rig.channel_names]:
            procs[name].send_signal(signal.SIGTERM)  # they follow run after run: stopped here
        codes = wait_all(procs, timeout_s=60.0)
    finally:
        if browser is not None:
            browser.quit()
        kill_all(procs, logs)
    assert all(code == 0 for code in codes.values()), codes
    # The panorama moved: the aircraft rolled down the runway between the two pictures.
    assert first.shape == second.shape and last.shape == first.shape
    assert np.abs(first - second).mean() > 0.002, "the panorama did not change between the screenshots"
    assert first.std() > 0.05, "the panorama is blank"
    latency = report["control_to_composite_latency"]
    assert report["frames_complete"] == FRAMES
    assert page == {
        "run-id": report["run_id"], "frames-published": str(report["frames_published"]),
        "frames-complete": str(report["frames_complete"]),
        "incomplete-missing_channel": str(report["frames_incomplete"]["missing_channel"]),
        "incomplete-eyepoint_mismatch": str(report["frames_incomplete"]["eyepoint_mismatch"]),
        "latency-p50": f"{latency['p50_ms']:.1f}", "latency-p99": f"{latency['p99_ms']:.1f}",
        "latency-count": str(latency["count"]), "view-dropped": "0"}
    for ch, cells in channels.items():
        # channel, state (rendering until a few seconds after its last image), images, missing,
        # late, render p50
        assert cells[0] == ch and cells[1] in ("rendering", "idle"), cells
        assert cells[2:] == [str(report["wire"]["channels"][ch]["srgb8"]), str(report["missing_by_channel"][ch]),
                             str(report["late_by_channel"][ch]), f"{report['render_time'][ch]['p50_ms']:.1f}"], cells


def _answers(url):
    try:
        return bool(status(url))
    except OSError:
        return False
