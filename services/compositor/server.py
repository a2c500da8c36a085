"""The compositor's gRPC service: a thin servicer over FrameGatherer, the host observer, serve()."""

from __future__ import annotations

import json
import logging
import threading
import time
from pathlib import Path

import grpc

from ig.v1 import compositor_pb2, compositor_pb2_grpc, host_pb2, host_pb2_grpc
from services.grpc_util import RPC_DEADLINE_S, add_health, bind, make_channel, make_server, set_not_serving

from .gather import FrameGatherer, InvalidSubmission
from .stitch import FrameWriter

log = logging.getLogger("ig.compositor")
SERVICE = "ig.v1.CompositorService"


class Compositor:
    """Gatherer + writer + the run's state, shared by the servicer and the host observer."""

    def __init__(self, channels, out_dir: Path, *, exr_every: int = 30) -> None:
        self.out_dir = Path(out_dir)
        self.writer = FrameWriter(self.out_dir / "frames", exr_every=exr_every)
        self.gatherer = FrameGatherer(channels, self.writer.put)
        self.finished = threading.Event()
        self.host_status: dict = {}

    def report(self) -> dict:
        doc = self.gatherer.report()
        doc["frames_written"] = self.writer.written
        doc["write_errors"] = self.writer.errors
        doc["frames_dir"] = str(self.out_dir / "frames")
        doc["host"] = self.host_status
        return doc

    def finish(self, *, grace_s: float) -> dict:
        """End of run: wait up to grace_s for frames still open, then decide and report."""
        deadline = time.monotonic() + grace_s
        while self.gatherer.report()["frames_pending"] and time.monotonic() < deadline:
            time.sleep(0.05)
        self.gatherer.finalize_all()
        self.writer.close()
        doc = self.report()
        self.out_dir.mkdir(parents=True, exist_ok=True)
        (self.out_dir / "report.json").write_text(json.dumps(doc, indent=2) + "\n")
        self.finished.set()
        return doc


class CompositorServicer(compositor_pb2_grpc.CompositorServiceServicer):
    def __init__(self, compositor: Compositor) -> None:
        self.compositor = compositor

    def SubmitChannelImage(self, request, context):
        if self.compositor.finished.is_set():
            context.abort(grpc.StatusCode.FAILED_PRECONDITION, "the run is over; report written")
        try:
            self.compositor.gatherer.submit(request)
        except InvalidSubmission as exc:
            log.warning("submission refused: %s", exc)
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        return compositor_pb2.SubmitChannelImageResponse()

    def GetCompositorReport(self, request, context):
        return compositor_pb2.GetCompositorReportResponse(
            report_json=json.dumps(self.compositor.report()), finished=self.compositor.finished.is_set())


def observe_host(compositor: Compositor, host_address: str, stop: threading.Event) -> bool:
    """Follow the host's frame stream as an observer until its run ends; True if it did end.

    Retries while the host is not up yet. The host's final status is kept for the report.
    """
    with make_channel(host_address) as channel:
        stub = host_pb2_grpc.HostServiceStub(channel)
        seen = False
        while not stop.is_set():
            try:
                stream = stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="compositor"),
                                              wait_for_ready=True, timeout=None)
                for response in stream:
                    seen = True
                    compositor.gatherer.on_published(response.frame)
                    if stop.is_set():
                        stream.cancel()
                        return False
                if seen:
                    break
            except grpc.RpcError as exc:
                if exc.code() == grpc.StatusCode.CANCELLED:
                    return False
                log.warning("host stream: %s %s; retrying", exc.code().name, exc.details())
            stop.wait(1.0)
        if not seen:
            return False
        try:
            s = stub.GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=RPC_DEADLINE_S)
            compositor.host_status = {
                "frames_published": s.frames_published, "eyepoints_rejected": s.eyepoints_rejected,
                "ack_timeouts": dict(s.ack_timeouts), "ack_failures": dict(s.ack_failures),
                "subscriptions_rejected": s.subscriptions_rejected, "queue_drops": dict(s.queue_drops),
                "last_error": s.last_error}
        except grpc.RpcError as exc:
            log.warning("host status unavailable: %s", exc.code().name)
        return True


def serve(compositor: Compositor, address: str, host_address: str, stop: threading.Event, *,
          once: bool = False, grace_s: float = 5.0) -> dict:
    """Serve the compositor on address; returns the final report.

    With once, the compositor finishes when the host's run ends; otherwise on stop (SIGTERM).
    """
    server = make_server()
    compositor_pb2_grpc.add_CompositorServiceServicer_to_server(CompositorServicer(compositor), server)
    health = add_health(server, [SERVICE])
    bind(server, address)
    server.start()
    log.info("compositor listening on %s, writing to %s", address, compositor.out_dir)
    observer_done = threading.Event()

    def follow() -> None:
        if observe_host(compositor, host_address, stop):
            observer_done.set()

    threading.Thread(target=follow, name="host-observer", daemon=True).start()
    while not stop.is_set() and not (once and observer_done.is_set()):
        stop.wait(0.2)
    doc = compositor.finish(grace_s=grace_s)
    # Keep answering briefly so clients can fetch the final report.
    if once:
        stop.wait(1.0)
    set_not_serving(health, [SERVICE])
    server.stop(grace=1.0).wait()
    log.info("compositor done: %d complete, incomplete %s", doc["frames_complete"], doc["frames_incomplete"])
    return doc
