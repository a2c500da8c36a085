"""The real rig: host, three workers and the compositor as processes over gRPC on localhost.

One short run is shared by the tests of this module. While it runs, the fixture checks every
process's health and throws bad input at the running rig: a NaN eyepoint and an unknown channel
submitted to the compositor, an unknown channel subscribing to the host, a worker started on a
malformed scene. The run must still finish with every frame complete.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import grpc
import numpy as np
import pytest

from ig.v1 import (
    compositor_pb2,
    compositor_pb2_grpc,
    frame_pb2,
    host_pb2,
    host_pb2_grpc,
    worker_pb2,
    worker_pb2_grpc,
)
from services.demo import local_rig
from services.rig.colour import decode_srgb8, linear_to_srgb8
from services.rig.grpc_util import check_health, make_channel
from services.rig.image_io import read_image
from services.rig.options import RenderOptions
from services.rig.rigfile import default_rig_path, load_rig, rig_toml

from .conftest import ROOT, kill_all, start, wait_all

pytestmark = pytest.mark.integration

W, H = 160, 120
RATE, DURATION = 20.0, 1.5
EXPECTED = int(round(RATE * DURATION)) + 1


def wait_serving(address, proc, timeout_s=180.0):
    """The health status of a process once it is SERVING (a worker answers NOT_SERVING while its
    kernels compile); its last status after timeout_s, or EXITED if it died first."""
    deadline = time.monotonic() + timeout_s
    status = "UNREACHABLE"
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return f"EXITED {proc.returncode}"
        try:
            status = check_health(address, timeout_s=1.0)
            if status == "SERVING":
                return status
        except grpc.RpcError:
            pass
        time.sleep(0.1)
    return status


@pytest.fixture(scope="module")
def rig_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rig")
    rig = local_rig(load_rig(default_rig_path()).with_size(W, H))
    rig_path = tmp / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    out = tmp / "out"
    logs = {}
    procs = {}

    def launch(name, argv):
        logs[name] = open(tmp / f"{name}.log", "w")  # noqa: SIM115  (closed when the run ends)
        procs[name] = start(argv, logs[name])

    result = {"tmp": tmp, "out": out, "rig": rig}
    try:
        launch("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--exr-every", "10", "--once"])
        for ch in rig.channels:
            launch(f"worker-{ch.name}", ["worker", "--rig", str(rig_path), "--channel", ch.name, "--samples", "4",
                                         "--once"])
        launch("host", ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", str(DURATION),
                        "--sync-timeout", "20"])
        # Health of every process while the run is on.
        result["health"] = {name: wait_serving(addr, procs[proc]) for name, addr, proc in
                            [("host", rig.host_address, "host"),
                             ("compositor", rig.compositor_address, "compositor")]
                            + [(ch.name, ch.address, f"worker-{ch.name}") for ch in rig.channels]}
        result["status"] = {ch.name: worker_status(ch.address) for ch in rig.channels}
        result["bad"] = throw_bad_input(rig, tmp, rig_path)
        result["exit"] = wait_all(procs)
    finally:
        kill_all(procs, logs)
    result["logs"] = {name: (tmp / f"{name}.log").read_text() for name in logs}
    report = out / "latest" / "report.json"
    result["report"] = json.loads(report.read_text()) if report.exists() else {}
    return result


def worker_status(address):
    with make_channel(address) as ch:
        return worker_pb2_grpc.ChannelWorkerServiceStub(ch).GetWorkerStatus(worker_pb2.GetWorkerStatusRequest(),
                                                                            timeout=5)


def throw_bad_input(rig, tmp, rig_path):
    bad = {}
    nan_eye = frame_pb2.Eyepoint(x=float("nan"), y=0.0, z=10.0)
    px = np.zeros((H, W, 3), "<f2").tobytes()
    with make_channel(rig.compositor_address) as ch:
        stub = compositor_pb2_grpc.CompositorServiceStub(ch)
        for key, name, eye in (("nan_eyepoint", "centre", nan_eye),
                               ("unknown_channel", "bogus", frame_pb2.Eyepoint(z=10.0))):
            req = compositor_pb2.SubmitChannelImageRequest(
                frame_number=10**9, channel_name=name, width=W, height=H,
                pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16, pixels=px, eyepoint=eye)
            try:
                stub.SubmitChannelImage(req, timeout=5)
                bad[key] = ("OK", "")
            except grpc.RpcError as exc:
                bad[key] = (exc.code().name, exc.details())
    with make_channel(rig.host_address) as ch:
        stub = host_pb2_grpc.HostServiceStub(ch)
        try:
            for _ in stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="rogue", channel_name="middle"),
                                          timeout=5):
                break
            bad["subscribe"] = ("OK", "")
        except grpc.RpcError as exc:
            bad["subscribe"] = (exc.code().name, exc.details())
    malformed = tmp / "malformed.json"
    malformed.write_text('{"format": "ig-scene/1", "sky": {"colour": "#zzzzzz"}, "earth": {"colour": "#000000"},'
                         ' "models": {}, "instances": []}')
    proc = subprocess.run([sys.executable, "-m", "services.cli", "worker", "--rig", str(rig_path), "--channel",
                           "centre", "--scene", str(malformed)], capture_output=True, text=True, cwd=ROOT,
                          timeout=120)
    bad["malformed_scene"] = (proc.returncode, proc.stderr)
    return bad


def test_every_process_reports_serving(rig_run):
    assert rig_run["health"] == dict.fromkeys(("host", "compositor", "left", "centre", "right"), "SERVING")


def test_every_frame_is_complete_and_stitched_from_the_same_frame(rig_run):
    report = rig_run["report"]
    assert report["frames_published"] == EXPECTED
    assert report["frames_complete"] == EXPECTED
    assert report["frames_incomplete"] == {"missing_channel": 0, "eyepoint_mismatch": 0}
    assert report["late_images"] == 0
    assert report["frames_skipped"] == {"left": 0, "centre": 0, "right": 0}
    assert report["host"]["ack_timeouts"] == {"left": 0, "centre": 0, "right": 0}
    assert report["host"]["eyepoint_source"] == "bundled" and report["host"]["inputs"] == []
    pngs = sorted((rig_run["out"] / "latest" / "frames").glob("frame_*.png"))
    assert len(pngs) == EXPECTED
    for png in pngs:
        pixels, attrs = read_image(png)
        assert pixels.shape == (H, 3 * W, 3)
        assert attrs["channels"] == "left,centre,right"
        assert int(attrs["frame_number"]) == int(png.stem.split("_")[1])
    exrs = sorted((rig_run["out"] / "latest" / "frames").glob("frame_*.exr"))
    assert [p.stem for p in exrs] == [f"frame_{n:06d}" for n in range(0, EXPECTED, 10)]
    for p in ("p50_ms", "p95_ms", "p99_ms"):
        assert report["control_to_composite_latency"][p] > 0
        assert all(report["render_time"][c][p] > 0 for c in ("left", "centre", "right"))


def test_workers_serve_their_status(rig_run):
    for name, status in rig_run["status"].items():
        assert status.channel_name == name
        assert status.frames_refused == 0 and status.submit_failures == 0


def test_each_third_of_a_stitched_frame_is_its_channel_at_the_published_eyepoint(rig_run):
    # Render every channel here, at the eyepoint the host publishes for the frame (the bundled
    # flight at frame_number / rate: no eyepoint is refused on this flight), and compare with
    # the stitched EXR: the right channel, in the right place, from the same frame.
    from channel_worker.pipeline.render import render_frame
    from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
    from host_sim.flight import bundled_flight

    database = load_scene(bundled_scene_path())
    flight = bundled_flight()
    for n in (10, EXPECTED - 1 - (EXPECTED - 1) % 10):
        pixels, attrs = read_image(rig_run["out"] / "latest" / "frames" / f"frame_{n:06d}.exr")
        eyepoint = flight.eyepoint_at(n / RATE)
        x, y, z, h, p, r = (float(v) for v in attrs["eyepoint"].split())
        assert (x, y, z, h, p, r) == (*eyepoint.position, eyepoint.heading_deg, eyepoint.pitch_deg,
                                      eyepoint.roll_deg)  # bitwise: the host's eyepoint
        # The rig's default wire: sRGB bytes (in shared memory, all on this machine), which the
        # PNG holds bit for bit and the EXR as their linear values (quantised to 8-bit levels).
        png, _ = read_image(rig_run["out"] / "latest" / "frames" / f"frame_{n:06d}.png")
        for i, ch in enumerate(rig_run["rig"].channels):
            rendered = render_frame(database, ch.spec, eyepoint, RenderOptions(samples=4)).rgb
            expected = linear_to_srgb8(rendered)
            np.testing.assert_array_equal(np.round(png[:, i * W:(i + 1) * W] * 255).astype(np.uint8), expected,
                                          err_msg=f"frame {n} channel {ch.name}")
            np.testing.assert_array_equal(pixels[:, i * W:(i + 1) * W],
                                          decode_srgb8(expected).astype(np.float16).astype(np.float32))
    assert rig_run["report"]["wire"]["composites"] == {"srgb8": EXPECTED}


def test_every_process_exits_cleanly(rig_run):
    assert rig_run["exit"] == {"compositor": 0, "worker-left": 0, "worker-centre": 0, "worker-right": 0, "host": 0}, \
        rig_run["logs"]


def test_bad_input_gets_named_errors_and_the_rig_keeps_running(rig_run):
    bad = rig_run["bad"]
    assert bad["nan_eyepoint"][0] == "INVALID_ARGUMENT" and "eyepoint.x: nan is not finite" in bad["nan_eyepoint"][1]
    assert bad["unknown_channel"][0] == "INVALID_ARGUMENT" and "channel_name: 'bogus'" in bad["unknown_channel"][1]
    assert bad["subscribe"][0] == "INVALID_ARGUMENT" and "channel_name: 'middle'" in bad["subscribe"][1]
    code, err = bad["malformed_scene"]
    assert code == 2 and "malformed.json: sky.colour" in err and "#zzzzzz" in err
    report = rig_run["report"]
    assert report["rejected_submissions"] == {"non_finite_eyepoint": 1, "unknown_channel": 1}
    assert report["host"]["subscriptions_rejected"] == 1
    assert report["frames_complete"] == EXPECTED  # nothing else was lost


def test_sigterm_stops_every_service_cleanly(tmp_path):
    """Host (still waiting for its channels), compositor and a worker all stop on SIGTERM.

    The host's start timeout is an hour: only SIGTERM can end it, and it must not wait it out.
    """
    rig = local_rig(load_rig(default_rig_path()).with_size(32, 24))
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    out = tmp_path / "out"
    procs, logs = {}, {}
    try:
        for name, argv in [("host", ["host", "--start-timeout", "3600"]),
                           ("compositor", ["compositor", "--out", str(out)]),
                           ("worker-left", ["worker", "--channel", "left", "--samples", "1"])]:
            logs[name] = open(tmp_path / f"{name}.log", "w")  # noqa: SIM115  (closed when the run ends)
            procs[name] = start([*argv, "--rig", str(rig_path)], logs[name])
        addresses = {"host": rig.host_address, "compositor": rig.compositor_address,
                     "worker-left": rig.channels[0].address}
        assert {n: wait_serving(addresses[n], procs[n]) for n in procs} == dict.fromkeys(procs, "SERVING")
        for proc in procs.values():
            proc.send_signal(signal.SIGTERM)
        codes = {n: p.wait(timeout=120) for n, p in procs.items()}
    finally:
        kill_all(procs, logs)
    assert codes == {"host": 0, "compositor": 0, "worker-left": 0}, \
        {n: (tmp_path / f"{n}.log").read_text() for n in procs}
    report = json.loads((out / "latest" / "report.json").read_text())
    assert report["frames_published"] == 0 and report["finished"]
