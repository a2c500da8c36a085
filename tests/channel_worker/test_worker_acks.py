"""What the worker tells the host: each acknowledgement names the frame's run and carries an
error short enough for the host to take; requests its own server refused are counted."""

import grpc

from channel_worker.worker import ChannelWorker
from ig.v1 import frame_pb2
from services.rig.frame import ChannelSpec
from services.rig.grpc_util import MAX_TEXT_CHARS
from services.rig.options import RenderOptions


class FakeRpcError(grpc.RpcError):
    def __init__(self, code, details):
        self._code, self._details = code, details

    def code(self):
        return self._code

    def details(self):
        return self._details


class RecordingStub:
    """Host and compositor stubs that keep every request; the compositor may fail."""

    def __init__(self, submit_error=None):
        self.acks = []
        self.submits = []
        self.submit_error = submit_error

    def SubmitChannelImage(self, request, timeout):
        self.submits.append(request)
        if self.submit_error is not None:
            raise self.submit_error

    def AckFrame(self, request, timeout):
        self.acks.append(request)


def worker(make_scene, box_model_factory, stub):
    db = make_scene({"b": box_model_factory(1, 1, 1)}, [{"model": "b", "position": [0, 0, 0]}])
    w = ChannelWorker(db, ChannelSpec.symmetric("centre", 16, 12, 60.0), host_address="127.0.0.1:1",
                      compositor_address="127.0.0.1:1", options=RenderOptions(samples=1))
    w.host_stub = w.compositor_stub = stub
    return w


def frame(n, run_id, x=0.0):
    return frame_pb2.Frame(frame_number=n, eyepoint=frame_pb2.Eyepoint(x=x, y=-900.0, z=3.0), run_id=run_id)


def test_acknowledgements_carry_the_frames_run(make_scene, box_model_factory):
    stub = RecordingStub()
    w = worker(make_scene, box_model_factory, stub)
    w._handle(frame(0, "run-a"))
    w._handle(frame(0, "run-b", x=float("nan")))  # refused by the renderer: acknowledged as failed
    assert [(a.frame_number, a.run_id, a.ok, a.channel_name) for a in stub.acks] == [
        (0, "run-a", True, "centre"), (0, "run-b", False, "centre")]
    assert stub.acks[0].error == "" and "eyepoint.position[0]: nan is not finite" in stub.acks[1].error
    assert stub.submits[0].run_id == "run-a"


def test_a_huge_compositor_error_is_clipped_below_the_hosts_limit(make_scene, box_model_factory):
    stub = RecordingStub(submit_error=FakeRpcError(grpc.StatusCode.INVALID_ARGUMENT, "D" * 10_000_000))
    w = worker(make_scene, box_model_factory, stub)
    w._handle(frame(4, "run-a"))
    (ack,) = stub.acks
    assert not ack.ok and ack.run_id == "run-a" and ack.frame_number == 4
    assert ack.error.startswith("submit to compositor failed: INVALID_ARGUMENT DDD")
    assert len(ack.error) <= MAX_TEXT_CHARS  # the host refuses longer text
    assert "more characters)" in ack.error
    assert w.counters.submit_failures == 1 and len(w.counters.last_error) <= MAX_TEXT_CHARS + 80


def test_refuse_counts_and_clips(make_scene, box_model_factory):
    w = worker(make_scene, box_model_factory, RecordingStub())
    w.refuse("malformed", "malformed ig.v1.GetWorkerStatusRequest: " + "x" * 10_000_000)
    w.refuse("text_too_long", "short")
    assert w.counters.malformed_requests == 2
    assert w.counters.last_error == "text_too_long: short"
    w.refuse("malformed", "y" * 10_000_000)
    assert w.counters.last_error.startswith("malformed: yyy") and len(w.counters.last_error) <= MAX_TEXT_CHARS + 80
