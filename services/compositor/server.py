"""The compositor's gRPC service: a thin servicer over FrameGatherer, the host observer, serve()."""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import grpc
from google.protobuf import json_format

from ig.v1 import compositor_pb2, compositor_pb2_grpc, host_pb2, host_pb2_grpc
from services.rig.grpc_util import (
    RPC_DEADLINE_S,
    STREAM_DEADLINE_S,
    add_health,
    bind,
    make_channel,
    make_server,
    set_not_serving,
)

from .gather import CompleteFrame, FrameGatherer, InvalidSubmission
from .stitch import FrameRecorder, compose
from .timing import TimingStats
from .watch import Watchers, summary

log = logging.getLogger("ig.compositor")
SERVICE = "ig.v1.CompositorService"

#: How often serve() finalises frames that have been open too long, seconds.
_EXPIRE_EVERY_S = 0.5

#: How often a watcher's stream wakes up to notice a cancelled client, seconds.
_POLL_S = 0.5


class Compositor:
    """Gatherer, composite, timing, recorder and watchers: the run's state, shared by the
    servicer and the host observer.

    A complete frame is stitched at once, on the thread that delivered its last image (a copy of
    the pixels, under a millisecond at the default rig size): that is the composite, time-stamped
    as a display output would show it. Everything after it (the timing figures, the recording,
    the watchers) takes no more than a queue append on that thread.

    Args:
        channels: rig channel names in display order.
        out_dir: where frames/ and report.json go.
        record_every: write a PNG of every N-th frame (0: never).
        exr_every: write an EXR every N frames (0: never).
        pending_timeout_s: a frame open this long is finalised as incomplete, seconds.
    """

    def __init__(self, channels: Sequence[str], out_dir: Path, *, record_every: int = 1, exr_every: int = 30,
                 pending_timeout_s: float = 30.0) -> None:
        self.out_dir = Path(out_dir)
        self.recorder = FrameRecorder(self.out_dir / "frames", record_every=record_every, exr_every=exr_every)
        self.timing = TimingStats()
        self.watchers = Watchers(channels)
        self.gatherer = FrameGatherer(channels, self._on_complete, pending_timeout_s=pending_timeout_s)
        self.finished = threading.Event()
        self.stitch_errors = 0
        self._lock = threading.Lock()
        #: The host's final counters (GetHostStatus after its run), for the report.
        self.host_status: dict = {}

    def _on_complete(self, frame: CompleteFrame) -> None:
        try:
            composite = compose(frame)
        except ValueError as exc:
            with self._lock:
                self.stitch_errors += 1
            log.error("frame %d not stitched: %s", frame.frame_number, exc)
            return
        self.timing.add(composite)
        self.recorder.offer(composite)
        self.watchers.publish(composite)

    def report(self) -> dict:
        """The report document (report.json): gatherer counters, timing, recorder counters, host
        counters (docs/frame-lock.md, docs/latency.md)."""
        doc = self.gatherer.report()
        doc.update(self.timing.report())
        counts = self.recorder.snapshot()
        with self._lock:
            doc["stitch_errors"] = self.stitch_errors
        doc["record_every"] = self.recorder.record_every
        doc["exr_every"] = self.recorder.exr_every
        doc["frames_written"] = counts.written
        doc["frames_not_recorded"] = counts.not_recorded
        doc["write_errors"] = counts.errors
        doc["frames_dir"] = str(self.out_dir / "frames")
        doc["host"] = self.host_status
        doc["finished"] = self.finished.is_set()
        return doc

    def finish(self, *, grace_s: float) -> dict:
        """End of run: wait up to grace_s seconds for open frames, decide them, write report.json."""
        deadline = time.monotonic() + grace_s
        while self.gatherer.pending and time.monotonic() < deadline:
            time.sleep(0.05)
        self.gatherer.finalize_all()
        self.recorder.close()
        self.watchers.close()
        self.finished.set()
        doc = self.report()
        self.out_dir.mkdir(parents=True, exist_ok=True)
        # Written to a temporary name and renamed, so a reader never sees half a report.
        tmp = self.out_dir / "report.json.tmp"
        tmp.write_text(json.dumps(doc, indent=2) + "\n")
        tmp.replace(self.out_dir / "report.json")
        return doc


class CompositorServicer(compositor_pb2_grpc.CompositorServiceServicer):
    """Thin servicer: submissions go to the gatherer, the report comes from the compositor."""

    def __init__(self, compositor: Compositor) -> None:
        self.compositor = compositor

    def SubmitChannelImage(self, request, context):
        if self.compositor.finished.is_set():
            context.abort(grpc.StatusCode.FAILED_PRECONDITION, "the run is over; report written")
        try:
            self.compositor.gatherer.submit(request)
        except InvalidSubmission as exc:
            log.warning("submission refused (%s from %s): %s", exc.cause, context.peer(), exc)
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        return compositor_pb2.SubmitChannelImageResponse()

    def GetCompositorReport(self, request, context):
        doc = self.compositor.report()
        return compositor_pb2.GetCompositorReportResponse(
            report_json=json.dumps(doc), finished=doc["finished"], frames_published=doc["frames_published"],
            frames_complete=doc["frames_complete"], frames_incomplete=sum(doc["frames_incomplete"].values()),
            frames_written=doc["frames_written"], frames_not_recorded=doc["frames_not_recorded"])

    def WatchComposites(self, request, context):
        try:
            watch = self.compositor.watchers.add(request.watcher or context.peer(), request.profile_channels)
        except ValueError as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        log.info("watcher %s joined (row profiles of %s)", watch.name, list(watch.profile_channels) or "no channel")
        try:
            while context.is_active():
                composite = watch.get(_POLL_S)
                if composite is not None:
                    yield summary(composite, watch)
                elif watch.closed:
                    return
        finally:
            self.compositor.watchers.remove(watch)


def observe_host(compositor: Compositor, host_address: str, stop: threading.Event) -> bool:
    """Follow the host's frame stream as an observer until its run ends; True if it did end.

    Subscribes again while the host is not up yet or the stream breaks. The host closing the
    stream normally means its run is over; the host's final counters are then kept for the report.
    """
    with make_channel(host_address) as channel:
        stub = host_pb2_grpc.HostServiceStub(channel)
        ended = False
        while not stop.is_set() and not ended:
            stream = stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="compositor"),
                                          wait_for_ready=True, timeout=STREAM_DEADLINE_S)
            # SIGTERM must not wait for the next frame: cancel the stream when stop is set.
            done = threading.Event()
            threading.Thread(target=_cancel_on_stop, args=(stream, stop, done), daemon=True).start()
            try:
                for response in stream:
                    compositor.gatherer.on_published(response.frame)
                ended = True
            except grpc.RpcError as exc:
                if stop.is_set():
                    return False
                log.warning("host stream: %s %s; subscribing again", exc.code().name, exc.details())
                stop.wait(1.0)
            finally:
                done.set()
        if not ended:
            return False
        try:
            s = stub.GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=RPC_DEADLINE_S)
            compositor.host_status = {
                "run_id": s.run_id, "frames_published": s.frames_published,
                "eyepoints_rejected": s.eyepoints_rejected, "ack_timeouts": dict(s.ack_timeouts),
                "ack_failures": dict(s.ack_failures), "channel_absent": dict(s.channel_absent),
                "subscriptions_rejected": s.subscriptions_rejected, "queue_drops": dict(s.queue_drops),
                "last_error": s.last_error,
                # Where the eyepoints came from and what the control inputs or the replayed log
                # refused, by cause (docs/host-inputs.md, docs/replay-formats.md).
                "eyepoint_source": s.eyepoint_source,
                "inputs": [json_format.MessageToDict(i, preserving_proto_field_name=True) for i in s.inputs],
                "replay": json_format.MessageToDict(s.replay, preserving_proto_field_name=True)
                if s.HasField("replay") else None,
                "flight_model": json_format.MessageToDict(s.flight_model, preserving_proto_field_name=True)
                if s.HasField("flight_model") else None}
        except grpc.RpcError as exc:
            log.warning("host status unavailable: %s", exc.code().name)
        return True


def _cancel_on_stop(stream: grpc.Future, stop: threading.Event, done: threading.Event) -> None:
    """Cancel stream as soon as stop is set; return when done is set first."""
    while not done.is_set():
        if stop.wait(0.2):
            stream.cancel()
            return


def serve(compositor: Compositor, address: str, host_address: str, stop: threading.Event, *,
          once: bool = False, grace_s: float = 5.0) -> dict:
    """Serve the compositor on address and follow the host at host_address; returns the final report.

    With once, the compositor finishes when the host's run ends; otherwise when stop is set
    (SIGTERM). Either way it finalises open frames, writes report.json, reports NOT_SERVING and
    stops the server.

    Raises:
        OSError: address cannot be bound.
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
        compositor.gatherer.expire()
        stop.wait(_EXPIRE_EVERY_S)
    doc = compositor.finish(grace_s=0.0 if stop.is_set() else grace_s)
    # Keep answering briefly so clients (ig demo) can fetch the final report.
    if once and not stop.is_set():
        stop.wait(1.0)
    set_not_serving(health, [SERVICE])
    server.stop(grace=1.0).wait()
    log.info("compositor done: %d complete, incomplete %s, report in %s", doc["frames_complete"],
             doc["frames_incomplete"], compositor.out_dir / "report.json")
    return doc
