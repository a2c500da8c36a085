"""The compositor's runs: one directory per run under OUT/runs/, OUT/latest the newest, a run
never overwriting another's files, and submissions just ahead of (or far beyond) the frames the
host has published."""

import hashlib
import json
import threading
import time
import types

import grpc
import numpy as np
import pytest

from ig.v1 import compositor_pb2, compositor_pb2_grpc, frame_pb2
from services.compositor import server as server_module
from services.compositor.gather import LOOKAHEAD_FRAMES, UNPUBLISHED, InvalidSubmission
from services.compositor.server import Compositor, CompositorServicer
from services.rig.grpc_util import add_service, bind, make_channel, make_server

CHANNELS = ("a", "b")


def eye(n):
    return frame_pb2.Eyepoint(x=10.0 + n, y=2.0, z=3.0, heading_deg=5.0)


def frame(run_id, n):
    return frame_pb2.Frame(frame_number=n, sim_time_s=n / 60, eyepoint=eye(n), run_id=run_id,
                           control_sample_time_unix_s=100.0 + n, channels=list(CHANNELS))


def image(run_id, n, channel, value):
    px = np.full((2, 3, 3), value, "<f2")
    return compositor_pb2.SubmitChannelImageRequest(
        frame_number=n, channel_name=channel, width=3, height=2, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
        pixels=px.tobytes(), eyepoint=eye(n), run_id=run_id, render_time_s=0.01)


def complete(comp, run_id, n, value=0.5):
    """The host publishes frame n of run_id and both channels deliver it."""
    comp.on_published(frame(run_id, n))
    for c in CHANNELS:
        comp.submit(image(run_id, n, c, value))


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def wait_for(path, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.01)


@pytest.fixture
def comp(tmp_path):
    c = Compositor(CHANNELS, tmp_path, record_every=1, exr_every=0, seams={"seams": [], "ok": True})
    yield c
    if not c.finished.is_set():
        c.finish(grace_s=0.0)


def test_a_run_goes_to_its_own_directory_and_latest_points_at_it(comp, tmp_path):
    complete(comp, "alpha", 0)
    assert comp.run_directory == tmp_path / "runs" / "alpha"
    assert (tmp_path / "latest").is_symlink()
    assert (tmp_path / "latest").resolve() == (tmp_path / "runs" / "alpha").resolve()
    doc = comp.finish(grace_s=0.0)
    assert (tmp_path / "runs" / "alpha" / "frames" / "frame_000000.png").is_file()
    on_disk = json.loads((tmp_path / "runs" / "alpha" / "report.json").read_text())
    assert on_disk["run_id"] == "alpha" and on_disk["frames_complete"] == 1 and on_disk["finished"]
    assert doc["run_dir"] == str(tmp_path / "runs" / "alpha")
    assert doc["frames_dir"] == str(tmp_path / "runs" / "alpha" / "frames")
    assert doc["seams"] == {"seams": [], "ok": True}
    assert doc["runs_before"] == [{"run_id": "alpha", "directory": str(tmp_path / "runs" / "alpha"),
                                   "frames_published": 1, "frames_complete": 1,
                                   "frames_incomplete": {"missing_channel": 0, "eyepoint_mismatch": 0}}]


def test_a_second_run_finalises_the_first_and_never_overwrites_its_files(comp, tmp_path):
    complete(comp, "first", 0, value=0.25)
    comp.on_published(frame("first", 1))
    comp.submit(image("first", 1, "a", 0.25))  # frame 1 stays open: b never delivers it
    first_png = tmp_path / "runs" / "first" / "frames" / "frame_000000.png"
    wait_for(first_png)
    before = digest(first_png)

    # The host restarted without ending its stream: frame numbers start at 0 again.
    complete(comp, "second", 0, value=0.75)
    assert comp.run_directory == tmp_path / "runs" / "second"
    assert (tmp_path / "latest").resolve() == (tmp_path / "runs" / "second").resolve()
    doc = comp.finish(grace_s=0.0)  # joins the thread that ends the first run

    first = json.loads((tmp_path / "runs" / "first" / "report.json").read_text())
    assert first["run_id"] == "first" and first["run_over"]
    assert first["frames_published"] == 2 and first["frames_complete"] == 1
    assert first["frames_incomplete"]["missing_channel"] == 1  # the open frame was decided
    assert first["frames_pending"] == 0
    assert first["missing_by_channel"] == {"a": 0, "b": 1}
    assert digest(first_png) == before  # frame 0 of the second run went elsewhere
    second_png = tmp_path / "runs" / "second" / "frames" / "frame_000000.png"
    assert second_png.is_file() and digest(second_png) != before
    assert doc["run_id"] == "second" and doc["frames_complete"] == 1 and doc["frames_published"] == 1
    assert doc["run_dir"] == str(tmp_path / "runs" / "second")
    assert [r["run_id"] for r in doc["runs_before"]] == ["first", "second"]
    assert doc["runs_before"][0]["frames_incomplete"]["missing_channel"] == 1


def test_the_same_run_id_seen_again_goes_to_a_numbered_directory(tmp_path):
    first = Compositor(CHANNELS, tmp_path, exr_every=0)
    complete(first, "run7", 0, value=0.25)
    first.finish(grace_s=0.0)
    png = tmp_path / "runs" / "run7" / "frames" / "frame_000000.png"
    before = digest(png)

    again = Compositor(CHANNELS, tmp_path, exr_every=0)  # the compositor restarted
    complete(again, "run7", 0, value=0.75)
    doc = again.finish(grace_s=0.0)
    assert doc["run_dir"] == str(tmp_path / "runs" / "run7.2")
    assert (tmp_path / "runs" / "run7.2" / "frames" / "frame_000000.png").is_file()
    assert (tmp_path / "latest").resolve() == (tmp_path / "runs" / "run7.2").resolve()
    assert digest(png) == before
    assert json.loads((tmp_path / "runs" / "run7" / "report.json").read_text())["frames_complete"] == 1


@pytest.mark.parametrize("run_id", ["../x", "a/b", "/etc", "x" * 65, "run id", "", ".", ".."])
def test_a_run_id_that_is_not_a_plain_name_is_hashed(tmp_path, run_id):
    out = tmp_path / "out"
    comp = Compositor(CHANNELS, out, exr_every=0)
    complete(comp, run_id, 0)
    doc = comp.finish(grace_s=0.0)
    expected = out / "runs" / ("run-" + hashlib.sha1(run_id.encode()).hexdigest()[:12])
    directory = comp.run_directory
    assert directory == expected
    assert directory.parent == out / "runs" and directory.is_dir()
    assert (directory / "report.json").is_file() and doc["run_dir"] == str(directory)
    # Nothing was written outside OUT.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in out.iterdir()) == ["latest", "runs"]


def test_end_run_writes_the_report_and_the_next_frame_starts_a_new_run(comp, tmp_path):
    complete(comp, "one", 0)
    comp.end_run("one", host_status={"ack_timeouts": {"a": 3}})
    one = json.loads((tmp_path / "runs" / "one" / "report.json").read_text())
    assert one["run_over"] and one["host"] == {"ack_timeouts": {"a": 3}} and one["frames_complete"] == 1
    assert not one["finished"]

    complete(comp, "two", 0)
    assert comp.run_directory == tmp_path / "runs" / "two"
    report = comp.report()
    assert report["run_id"] == "two" and not report["run_over"]
    assert [r["run_id"] for r in report["runs_before"]] == ["one"]
    assert report["frames_complete"] == 1 and report["host"] == {}


def test_a_run_ended_from_two_threads_at_once_is_ended_once(comp, tmp_path, monkeypatch):
    # SIGTERM's stop and the host's stream ending both end the run: the two wrote report.json
    # through one temporary name, and the second writer's rename found it gone (a traceback
    # in the README's CIGI walkthrough). The first caller ends it; the other waits for it.
    complete(comp, "one", 0)
    ends = []
    real_end, real_write = Compositor._end_once, server_module._write_json

    def counted_end(self, run, grace_s):
        ends.append(run.run_id)
        return real_end(self, run, grace_s)

    def slow_write(path, doc):
        time.sleep(0.2)  # the other callers arrive while the first writes
        real_write(path, doc)

    monkeypatch.setattr(Compositor, "_end_once", counted_end)
    monkeypatch.setattr(server_module, "_write_json", slow_write)
    errors = []

    def end():
        try:
            comp.end_run("one")
        except Exception as exc:  # the test reports whatever a thread raised
            errors.append(exc)

    threads = [threading.Thread(target=end) for _ in range(2)]
    for t in threads:
        t.start()
    comp.finish(grace_s=0.0)  # SIGTERM's path, at the same time
    for t in threads:
        t.join()
    assert not errors
    assert ends == ["one"]
    assert json.loads((tmp_path / "runs" / "one" / "report.json").read_text())["frames_complete"] == 1


def test_end_run_of_another_run_changes_nothing(comp, tmp_path):
    complete(comp, "one", 0)
    comp.end_run("other")
    assert not (tmp_path / "runs" / "one" / "report.json").exists()
    assert not comp.report()["run_over"]


def test_finish_before_any_frame_still_writes_a_report(comp, tmp_path):
    doc = comp.finish(grace_s=0.0)
    runs = list((tmp_path / "runs").iterdir())
    assert len(runs) == 1 and runs[0].name.startswith("no-frames-")
    report = json.loads((runs[0] / "report.json").read_text())
    assert report["frames_published"] == 0 and report["finished"] and report["run_dir"] == str(runs[0])
    assert doc["run_dir"] == str(runs[0])
    assert (tmp_path / "latest").resolve() == runs[0].resolve()


def test_an_image_just_ahead_of_the_published_frames_waits_for_the_hosts_copy(comp):
    complete(comp, "r", 0)
    ahead = 1 + LOOKAHEAD_FRAMES  # not taken until frame 1 has been published

    def publish_later():
        time.sleep(0.05)
        for n in range(1, ahead + 1):
            comp.on_published(frame("r", n))

    publisher = threading.Thread(target=publish_later)
    publisher.start()
    comp.submit(image("r", ahead, "a", 0.5))  # accepted: no InvalidSubmission
    publisher.join()
    comp.submit(image("r", ahead, "b", 0.5))
    report = comp.report()
    assert report["rejected_submissions"] == {}
    assert report["frames_complete"] == 2  # frame `ahead` is complete; 1..ahead-1 missed both channels
    assert report["frames_incomplete"]["missing_channel"] == ahead - 1


class _RecordingTime:
    """server.time with a sleep that counts its calls instead of sleeping."""

    def __init__(self):
        self.sleeps = 0
        self.now = 0.0

    def monotonic(self):
        return self.now

    def sleep(self, s):
        self.sleeps += 1
        self.now += s


def test_an_image_far_ahead_is_refused_at_once(comp, monkeypatch):
    complete(comp, "r", 0)
    clock = _RecordingTime()
    monkeypatch.setattr(server_module, "time", types.SimpleNamespace(monotonic=clock.monotonic, sleep=clock.sleep,
                                                                     strftime=time.strftime, gmtime=time.gmtime))
    far = 4 * LOOKAHEAD_FRAMES + 1
    with pytest.raises(InvalidSubmission) as err:
        comp.submit(image("r", far, "a", 0.5))
    assert err.value.cause == UNPUBLISHED and clock.sleeps == 0
    assert f"frame_number: {far} has not been published (the last is 0)" in str(err.value)
    # Just ahead: waited for (in vain, here) before it is refused.
    with pytest.raises(InvalidSubmission) as err:
        comp.submit(image("r", LOOKAHEAD_FRAMES + 1, "a", 0.5))
    assert err.value.cause == UNPUBLISHED and clock.sleeps > 0
    assert comp.report()["rejected_submissions"] == {UNPUBLISHED: 2}


def test_far_ahead_is_out_of_range_over_grpc(comp):
    complete(comp, "r", 0)
    server = make_server(max_receive_bytes=2**20)
    add_service(server, CompositorServicer(comp), compositor_pb2.DESCRIPTOR.services_by_name["CompositorService"],
                refused=comp.refuse)
    port = bind(server, "127.0.0.1:0")
    server.start()
    try:
        with make_channel(f"127.0.0.1:{port}") as ch:
            stub = compositor_pb2_grpc.CompositorServiceStub(ch)
            with pytest.raises(grpc.RpcError) as err:
                stub.SubmitChannelImage(image("r", 1000, "a", 0.5), timeout=5)
            assert err.value.code() == grpc.StatusCode.OUT_OF_RANGE
            assert "frame_number: 1000 has not been published" in err.value.details()
    finally:
        server.stop(0).wait()
    assert comp.report()["rejected_submissions"] == {UNPUBLISHED: 1}
