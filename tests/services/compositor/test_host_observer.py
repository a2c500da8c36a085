"""The compositor following the host's stream: the host's final counters come with the stream's
end however the host stopped (issue 33), and an ended run is asked again only after a pause."""

import threading
import time

import grpc
import pytest

from host_sim.publisher import FramePublisher
from host_sim.server import HostServicer
from ig.v1 import host_pb2_grpc
from services.compositor.server import Compositor, observe_host
from services.rig.frame import Eyepoint
from services.rig.grpc_util import make_server


class _GoneStatus(HostServicer):
    """A host that no longer answers GetHostStatus, as one stopped by SIGTERM a moment ago."""

    def GetHostStatus(self, request, context):
        context.abort(grpc.StatusCode.UNAVAILABLE, "the host is stopping")


@pytest.fixture
def gone_host():
    """(publisher, its stop event, address) of a host on an in-process server whose GetHostStatus
    is UNAVAILABLE; the publisher runs on a thread, waiting for one observer and no channel."""
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0, 10, 0, 0, 0), channels=[], rate_hz=200.0,
                         duration_s=3600.0, observers=1, start_timeout_s=60.0)
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(_GoneStatus(pub), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    yield pub, stop, f"127.0.0.1:{port}"
    stop.set()
    runner.join()
    server.stop(0).wait()


def _observe(comp, address):
    """observe_host with once on a thread: (thread, its stop event)."""
    stop = threading.Event()
    thread = threading.Thread(target=observe_host, args=(comp, address, stop), kwargs={"once": True, "grace_s": 0.0})
    thread.start()
    return thread, stop


def test_a_stopped_hosts_counters_reach_the_report_without_asking(gone_host, tmp_path):
    pub, host_stop, address = gone_host
    comp = Compositor(("a", "b"), tmp_path, record_every=0, exr_every=0)
    thread, stop = _observe(comp, address)
    try:
        deadline = time.monotonic() + 30
        while pub.snapshot().frames_published < 5 and time.monotonic() < deadline:
            time.sleep(0.01)
        host_stop.set()  # SIGTERM mid-run
        thread.join(30)
        assert not thread.is_alive()
    finally:
        stop.set()
    doc = comp.finish(grace_s=0.0)
    host = doc["host"]
    assert host, doc
    assert host["run_id"] == doc["run_id"] == pub.status.run_id
    assert host["frames_published"] == doc["frames_published"] == pub.snapshot().frames_published
    assert host["run_end"] == "stopped" and host["eyepoint_source"] == "bundled"


def test_a_run_that_ends_by_itself_says_so(tmp_path):
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0, 10, 0, 0, 0), channels=[], rate_hz=100.0,
                         duration_s=0.05, observers=1, start_timeout_s=60.0)
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(_GoneStatus(pub), server)
    address = f"127.0.0.1:{server.add_insecure_port('127.0.0.1:0')}"
    server.start()
    comp = Compositor(("a", "b"), tmp_path, record_every=0, exr_every=0)
    stop = threading.Event()
    runner = threading.Thread(target=pub.run, args=(stop,))
    runner.start()
    try:
        assert observe_host(comp, address, stop, once=True, grace_s=0.0)
        runner.join()
    finally:
        stop.set()
        server.stop(0).wait()
    host = comp.finish(grace_s=0.0)["host"]
    assert host["run_end"] == "completed" and host["frames_published"] == pub.tick_count == 6


class _CountedStop(threading.Event):
    """A stop event that records every pause the thread that made it asks of it, and sets itself
    after `pauses` of them (the stream's canceller, on a thread of its own, only polls it)."""

    def __init__(self, pauses):
        super().__init__()
        self.pauses = pauses
        self.asked = []
        self._owner = threading.current_thread()

    def wait(self, timeout=None):
        if threading.current_thread() is not self._owner:
            return super().wait(timeout)
        self.asked.append(timeout)
        if len(self.asked) >= self.pauses:
            self.set()
        return self.is_set()


def test_an_ended_run_is_asked_again_only_after_a_pause(tmp_path):
    from services.rig.resubscribe import RUN_ENDED_FIRST_PAUSE_S, RUN_ENDED_MAX_PAUSE_S

    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0, 10, 0, 0, 0), channels=[], duration_s=0.0,
                         start_timeout_s=0.0)
    pub.run(threading.Event())
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(pub), server)
    address = f"127.0.0.1:{server.add_insecure_port('127.0.0.1:0')}"
    server.start()
    comp = Compositor(("a", "b"), tmp_path, record_every=0, exr_every=0)
    stop = _CountedStop(3)
    try:
        assert not observe_host(comp, address, stop)
    finally:
        server.stop(0).wait()
        comp.finish(grace_s=0.0)
    assert stop.asked == [RUN_ENDED_FIRST_PAUSE_S, RUN_ENDED_MAX_PAUSE_S, RUN_ENDED_MAX_PAUSE_S]
    assert pub.snapshot().requests_refused == {"run_ended": 3}
