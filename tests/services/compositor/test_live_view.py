"""The live view's HTTP side without a browser: a Compositor in this process, its view on port 0,
asked over HTTP(S) as a browser would; a stalled client; the options and their errors."""

from __future__ import annotations

import http.client
import json
import socket
import ssl
import threading
import time
import urllib.request

import numpy as np
import pytest
from prometheus_client import generate_latest

from ig.v1 import compositor_pb2, frame_pb2
from services.cli import main
from services.compositor.gather import CompleteFrame
from services.compositor.liveview.endpoint import MAX_STREAMS, LiveView, view_address
from services.compositor.liveview.frames import downscale
from services.compositor.liveview.status import IDLE, LATE, MISSING, RENDERING, ChannelStates, latency_series
from services.compositor.server import Compositor
from services.compositor.timing import Composite
from services.rig.grpc_util import PlaintextRefused
from services.rig.image_io import read_image

SEAMS = {"ok": True, "stitched_width": 6, "seams": [{"left": "a", "right": "b", "overlap_min_deg": 0.0, "ok": True}]}


@pytest.fixture
def view(tmp_path):
    """A two-channel compositor (2 x 3 px channels) and its live view on a free port."""
    comp = Compositor(("a", "b"), tmp_path, record_every=0, exr_every=0, seams=SEAMS)
    live = LiveView(comp.report, comp.channels, comp.watchers, "127.0.0.1:0", max_rate_hz=200.0)
    comp.metrics.add_view(live.frames.counts)
    yield comp, live
    live.close()


def submit_frame(comp, n, now):
    """Frame n published and both channels' images of it submitted: one composite."""
    eye = frame_pb2.Eyepoint(x=float(n))
    comp.on_published(frame_pb2.Frame(frame_number=n, run_id="r", eyepoint=eye, control_sample_time_unix_s=now))
    for ch, level in (("a", 40), ("b", 200)):
        comp.submit(compositor_pb2.SubmitChannelImageRequest(
            frame_number=n, channel_name=ch, width=3, height=2, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_SRGB8,
            pixels=bytes([level]) * 18, eyepoint=eye, run_id="r", control_sample_time_unix_s=now))


def get(url, path, context=None):
    with urllib.request.urlopen(url + path, timeout=5, context=context) as response:
        return response.status, response.headers["Content-Type"], response.read()


def wait_until(predicate, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def noise_composite(n, rng, width=480, height=240):
    """A composite of noise (a JPEG of it is large: a stalled client's buffers fill at once)."""
    frame = CompleteFrame(n, n / 60, (0.0,) * 6, time.time(), (), run_id="r")
    return Composite(frame, rng.integers(0, 256, (height, width, 3), dtype=np.uint8), time.time())


def test_the_view_listens_on_127_0_0_1_unless_told_and_is_off_without_a_port(view):
    assert view_address(8080, None) == "127.0.0.1:8080"
    assert view_address(8080, "::1") == "[::1]:8080"
    assert view_address(0, "0.0.0.0") is None and view_address(None, None) is None
    _, live = view
    assert live._server.server_address[0] == "127.0.0.1" and live.url == f"http://127.0.0.1:{live.port}/"


def test_page_status_and_frame_over_http(view, tmp_path):
    comp, live = view
    now = time.time()
    for n in range(3):
        submit_frame(comp, n, now - 0.05)
    wait_until(lambda: live.frames.latest is not None and live.frames.latest.frame_number == 2)
    status, kind, page = get(live.url, "")
    assert status == 200 and kind.startswith("text/html") and b'src="stream.mjpg"' in page
    # Self-contained: nothing fetched from anywhere else.
    assert b"http://" not in page.replace(b"http://www.w3.org/2000/svg", b"") and b"https://" not in page
    status, kind, body = get(live.url, "status.json")
    doc = json.loads(body)
    assert kind == "application/json" and doc["run_id"] == "r"
    assert (doc["frames_published"], doc["frames_complete"], doc["frames_incomplete"]) == \
        (3, 3, {"missing_channel": 0, "eyepoint_mismatch": 0})
    assert [(c["name"], c["state"], c["images"]) for c in doc["channels"]] == [("a", RENDERING, 3), ("b", RENDERING, 3)]
    assert doc["latency"]["count"] == 3 and 40 < doc["latency"]["p50_ms"] < 10_000
    assert doc["latency_series"] and doc["latency_series"][-1][3] == 3
    assert doc["seams"] == SEAMS
    assert doc["shown"]["frame_number"] == 2 and (doc["shown"]["width"], doc["shown"]["height"]) == (6, 2)
    # The page's numbers are the report's.
    assert doc["frames_complete"] == comp.report()["frames_complete"]
    status, kind, jpeg = get(live.url, "frame.jpg")
    assert kind == "image/jpeg" and jpeg[:2] == b"\xff\xd8"
    (tmp_path / "frame.jpg").write_bytes(jpeg)
    pixels, _ = read_image(tmp_path / "frame.jpg")
    assert pixels.shape == (2, 6, 3)
    assert pixels[:, :3].mean() < 0.3 < 0.6 < pixels[:, 3:].mean()  # channel a dark, b light
    with pytest.raises(urllib.error.HTTPError) as err:
        get(live.url, "report.json")
    err.value.close()
    assert err.value.code == 404


def test_the_stream_sends_each_new_frame_as_a_jpeg_part(view):
    comp, live = view
    submit_frame(comp, 0, time.time())
    wait_until(lambda: live.frames.latest is not None)
    conn = http.client.HTTPConnection("127.0.0.1", live.port, timeout=5)
    conn.request("GET", "/stream.mjpg")
    response = conn.getresponse()
    assert response.status == 200
    assert response.headers["Content-Type"] == "multipart/x-mixed-replace; boundary=igframe"
    parts = []
    for n in (1, 2):
        parts.append(_read_part(response))  # the newest frame waits for a new stream at once
        submit_frame(comp, n, time.time())
    parts.append(_read_part(response))
    response.close()
    conn.close()
    assert all(p[:2] == b"\xff\xd8" for p in parts)
    assert live.frames.counts()["frames_encoded"] == 3


def _read_part(response):
    assert response.fp.readline() == b"--igframe\r\n"
    headers = {}
    while (line := response.fp.readline()) != b"\r\n":
        key, _, value = line.decode().partition(":")
        headers[key.lower()] = value.strip()
    assert headers["content-type"] == "image/jpeg"
    body = response.fp.read(int(headers["content-length"]))
    assert response.fp.read(2) == b"\r\n"
    return body


def test_a_stalled_browser_drops_frames_counted_and_holds_nobody_up(view):
    comp, live = view
    rng = np.random.default_rng(1)
    # A browser that asks for the stream and never reads it, with the smallest buffer it may have.
    stalled = socket.socket()
    stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stalled.connect(("127.0.0.1", live.port))
    stalled.sendall(b"GET /stream.mjpg HTTP/1.1\r\nHost: x\r\n\r\n")
    wait_until(lambda: live.frames.counts()["clients"] == 1)
    # A browser that keeps up, beside it.
    received = []
    conn = http.client.HTTPConnection("127.0.0.1", live.port, timeout=5)
    conn.request("GET", "/stream.mjpg")
    response = conn.getresponse()
    reader = threading.Thread(target=lambda: [received.append(_read_part(response)) for _ in range(20)], daemon=True)
    reader.start()
    wait_until(lambda: live.frames.counts()["clients"] == 2)
    try:
        for n in range(20):
            t0 = time.monotonic()
            comp.watchers.publish(noise_composite(n, rng))
            # The gathering thread's hand-over: an append, whatever the browsers do.
            assert time.monotonic() - t0 < 0.5
            wait_until(lambda n=n: live.frames.counts()["frames_encoded"] == n + 1)
        wait_until(lambda: len(received) == 20)
        counts = live.frames.counts()
        assert counts["frames_encoded"] == 20 and counts["composites_skipped"] == 0
        # The stalled browser's kernel buffers took a few frames, then every later one was dropped.
        assert counts["frames_dropped"] >= 15, counts
        doc = json.loads(get(live.url, "status.json")[2])
        assert doc["view"]["frames_dropped"] == counts["frames_dropped"] and doc["view"]["clients"] == 2
        metrics = generate_latest(comp.metrics.registry).decode()
        assert f"ig_compositor_view_frames_dropped_total {float(counts['frames_dropped'])}" in metrics
        assert "ig_compositor_view_clients 2.0" in metrics
    finally:
        stalled.close()
        response.close()
        conn.close()
    # Its stream ends at its next write: the drops stay counted.
    wait_until(lambda: live.frames.counts()["clients"] == 0, timeout_s=15.0)
    assert live.frames.counts()["frames_dropped"] >= 15


def test_streams_beyond_the_limit_are_refused(view):
    _, live = view
    socks = []
    try:
        for _ in range(MAX_STREAMS):
            s = socket.create_connection(("127.0.0.1", live.port))
            s.sendall(b"GET /stream.mjpg HTTP/1.0\r\n\r\n")
            socks.append(s)
        wait_until(lambda: live.frames.counts()["clients"] == MAX_STREAMS)
        with pytest.raises(urllib.error.HTTPError) as err:
            get(live.url, "stream.mjpg")
        err.value.close()
        assert err.value.code == 503
    finally:
        for s in socks:
            s.close()


def test_https_with_the_rigs_certificate(tmp_path):
    from services.rig.certs import write_certs
    from services.rig.rigfile import default_rig_path, load_rig

    certs = tmp_path / "certs"
    write_certs(load_rig(default_rig_path()), certs)
    comp = Compositor(("a",), tmp_path / "out", record_every=0, exr_every=0)
    with LiveView(comp.report, comp.channels, comp.watchers, "127.0.0.1:0",
                  certificate=(str(certs / "compositor.pem"), str(certs / "compositor-key.pem"))) as live:
        assert live.url.startswith("https://")
        trusting = ssl.create_default_context(cafile=str(certs / "ca.pem"))
        status, _, body = get(live.url, "status.json", context=trusting)
        assert status == 200 and json.loads(body)["channels"][0]["name"] == "a"
        # A browser that does not trust the rig's CA is refused in the handshake, and the view serves on.
        with pytest.raises(urllib.error.URLError, match="CERTIFICATE_VERIFY_FAILED"):
            get(live.url, "status.json", context=ssl.create_default_context())
        with pytest.raises((http.client.RemoteDisconnected, ConnectionError)):
            get(live.url.replace("https", "http"), "status.json")
        assert get(live.url, "", context=trusting)[0] == 200


def test_plaintext_off_the_loopback_and_a_port_in_use_are_refused(tmp_path):
    comp = Compositor(("a",), tmp_path, record_every=0, exr_every=0)
    with pytest.raises(PlaintextRefused, match=r"view: 0.0.0.0:0: plaintext is refused off the loopback"):
        LiveView(comp.report, comp.channels, comp.watchers, "0.0.0.0:0")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(OSError, match=f"view: cannot listen on 127.0.0.1:{port}"):
            LiveView(comp.report, comp.channels, comp.watchers, f"127.0.0.1:{port}")


@pytest.mark.parametrize("argv,message", [
    (["compositor", "--view-port", "70000"], "argument --view-port: '70000' is not a port"),
    (["compositor", "--view-port", "web"], "argument --view-port: 'web' is not a port"),
    (["compositor", "--view-bind", "not an address"], "argument --view-bind: 'not an address' is not an IP"),
    (["demo", "--view-port", "-1"], "argument --view-port: '-1' is not a port"),
])
def test_bad_view_options_exit_2_naming_the_option_and_value(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_a_bad_view_port_in_the_rig_file_exits_2_naming_the_key(tmp_path, capsys):
    from services.rig.rigfile import default_rig_path

    rig = tmp_path / "rig.toml"
    rig.write_text(default_rig_path().read_text().replace('address = "127.0.0.1:50151"',
                                                          'address = "127.0.0.1:50151"\nview_port = "8080"'))
    assert main(["compositor", "--rig", str(rig)]) == 2
    assert "compositor.view_port: '8080' is not a port in [1, 65535], or 0 for none" in capsys.readouterr().err


def test_downscale_averages_blocks_to_the_width_asked():
    rgb = np.zeros((8, 20, 3), np.uint8)
    rgb[:, 10:] = 255
    small = downscale(rgb, 8)  # f = 3: 6 whole blocks across, 2 down; the last 2 columns and rows left out
    assert small.shape == (2, 6, 3) and small.dtype == np.uint8
    assert small[0, :3].tolist() == [[0] * 3] * 3 and small[0, 3, 0] == 170 and small[0, 4, 0] == 255
    assert downscale(rgb, 20) is rgb
    half = np.full((4, 8, 3), 0.5, np.float16)
    assert downscale(half, 4).shape == (2, 4, 3) and downscale(half, 4)[0, 0, 0] == 188  # sRGB of 0.5


def test_channel_states_follow_what_changed_lately():
    now = [0.0]
    states = ChannelStates(("a", "b"), clock=lambda: now[0])

    def report(images_a, missing_b=0, late_a=0):
        return {"wire": {"channels": {"a": {"srgb8": images_a, "half": 0}, "b": {"srgb8": 0, "half": 0}}},
                "missing_by_channel": {"a": 0, "b": missing_b}, "late_by_channel": {"a": late_a, "b": 0}}

    assert states.update(report(0)) == {"a": IDLE, "b": IDLE}
    now[0] = 1.0
    assert states.update(report(5, missing_b=2)) == {"a": RENDERING, "b": MISSING}
    now[0] = 2.0
    assert states.update(report(6, missing_b=2, late_a=1)) == {"a": LATE, "b": MISSING}
    now[0] = 10.0
    assert states.update(report(6, missing_b=2, late_a=1)) == {"a": IDLE, "b": IDLE}


def test_latency_series_is_p50_and_p99_second_by_second():
    samples = [(100.2, 0.010), (100.4, 0.030), (101.5, 0.050), (30.0, 1.0)]
    series = latency_series(samples, 102.0)
    assert series == [[-1.5, 20.0, 29.8, 2], [-0.5, 50.0, 50.0, 1]]  # the sample 72 s old is left out
    assert latency_series([], 102.0) == []


def test_the_view_of_the_command_line_and_the_rig_file(tmp_path):
    from dataclasses import replace

    from services.cli import build_parser
    from services.compositor.cli import view_of
    from services.rig.rigfile import TlsSpec, default_rig_path, load_rig

    rig = load_rig(default_rig_path())
    args = build_parser("compositor").parse_args(["compositor"])
    assert view_of(args, rig) is None  # off unless asked
    spec = view_of(args, replace(rig, compositor_view_port=8080))
    assert (spec.address, spec.certificate, spec.allow_plaintext) == ("127.0.0.1:8080", None, False)
    args = build_parser("compositor").parse_args(["compositor", "--view-port", "9090", "--view-bind", "::1"])
    tls = TlsSpec(ca="ca.pem", cert="compositor.pem", key="compositor-key.pem")
    spec = view_of(args, replace(rig, compositor_view_port=8080, tls=tls))
    assert (spec.address, spec.certificate) == ("[::1]:9090", ("compositor.pem", "compositor-key.pem"))
    args = build_parser("compositor").parse_args(["compositor", "--view-port", "0"])
    assert view_of(args, replace(rig, compositor_view_port=8080)) is None
