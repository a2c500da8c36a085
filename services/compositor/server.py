"""The compositor's gRPC service: a thin servicer over FrameGatherer, the host observer, serve()."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import threading
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import grpc
from google.protobuf import json_format

from ig.v1 import compositor_pb2, compositor_pb2_grpc, frame_pb2, host_pb2, host_pb2_grpc
from services.rig.grpc_util import (
    MAX_MESSAGE_BYTES,
    RPC_DEADLINE_S,
    STREAM_DEADLINE_S,
    Security,
    add_health,
    add_service,
    bind,
    make_channel,
    make_server,
    set_not_serving,
)
from services.rig.metrics import serve_metrics
from services.rig.resubscribe import RunEndedBackoff, run_ended
from services.rig.rigfile import WireSpec
from services.rig.shared_images import SharedImageReader, shared_memory_supported

from .blend import BlendPlan
from .gather import (
    OTHER_RUN,
    SHARED_UNAVAILABLE,
    UNPUBLISHED,
    CompleteFrame,
    FrameGatherer,
    InvalidSubmission,
)
from .liveview.endpoint import LiveView, ViewSpec
from .metrics import CompositorMetrics, CountKey, run_counts
from .stitch import FrameRecorder, RecorderCounts, compose
from .timing import HOPS, TimingStats
from .watch import Watchers, summary

log = logging.getLogger("ig.compositor")
SERVICE = "ig.v1.CompositorService"

#: How often serve() finalises frames that have been open too long, seconds.
_EXPIRE_EVERY_S = 0.5

#: How often a watcher's stream wakes up to notice a cancelled client, seconds.
_POLL_S = 0.5


#: Longest a submission waits for the compositor's own copy of its frame from the host (an
#: image can overtake it by milliseconds; a new run's first image, by the host's first frame).
SUBMIT_WAIT_S = 1.0

#: Ended runs listed in the report (the newest).
RUNS_LISTED = 100

_RUN_NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}")


@dataclass
class _Run:
    """One run of the host as the compositor sees it: its gatherer, timing and recorder, and
    the directory its files go to (runs/<run_id>/ under the output directory)."""

    run_id: str
    gatherer: FrameGatherer
    timing: TimingStats
    recorder: FrameRecorder | None = None
    directory: Path | None = None
    stitch_errors: int = 0
    stitched: Counter[str] = field(default_factory=Counter)  # composites by format
    host_status: dict = field(default_factory=dict)
    ended: bool = False
    # Claimed by the first of the callers that may end a run at once (the host's stream
    # ending, SIGTERM's stop, a new run's first frame); the others wait for it to be done.
    ending: bool = False
    end_done: threading.Event = field(default_factory=threading.Event)


class Compositor:
    """Gatherer, composite, timing, recorder and watchers: the rig's state, shared by the
    servicer and the host observer.

    A complete frame is stitched at once, on the thread that delivered its last image (a copy of
    the pixels, under a millisecond at the default rig size): that is the composite, time-stamped
    as a display output would show it. Everything after it (the timing figures, the recording,
    the watchers) takes no more than a queue append on that thread.

    Runs: the host names every run (its run id). Each run gets its own gatherer and its own
    directory, OUT/runs/<run_id>/ (frames/ and report.json; OUT/latest links to the newest), so
    two runs are never merged and a run never overwrites another's files. A run ends when the
    host closes its stream (end_run) or when the first frame of another run arrives (the host
    restarted): its open frames are then finalised and its report written.

    Args:
        channels: rig channel names in display order.
        out_dir: where runs/ and latest go.
        record_every: write a PNG of every N-th frame (0: never).
        exr_every: write an EXR every N frames (0: never).
        record_per_s: when > 0, PNGs by simulation time instead, this many a simulated second
            (FrameRecorder).
        pending_timeout_s: a frame open this long is finalised as incomplete, seconds.
        sizes: each channel's (width, height) from the rig file (None: any size).
        max_pending_frames: frames held open at once (FrameGatherer).
        max_pending_bytes: pixels the open frames may hold.
        plan: edge blending of the stitch (None: channels side by side).
        seams: the seam check of the rig (BlendPlan.report()), for the report.
        wire: the rig's wire format (what a frame whose channels sent different formats is
            stitched in) and whether images may come through the workers' shared memory.
    """

    def __init__(self, channels: Sequence[str], out_dir: Path, *, record_every: int = 1, exr_every: int = 30,
                 pending_timeout_s: float = 30.0, sizes: Mapping[str, tuple[int, int]] | None = None,
                 max_pending_frames: int = 16, max_pending_bytes: int = 512 * 2**20,
                 plan: BlendPlan | None = None, seams: dict | None = None, wire: WireSpec | None = None,
                 record_per_s: float = 0.0) -> None:
        self.out_dir = Path(out_dir)
        self.channels = tuple(channels)
        self.record_every = record_every
        self.record_per_s = record_per_s
        self.exr_every = exr_every
        self.plan = plan
        self.seams = seams or {}
        self.wire = wire or WireSpec()
        # One reader for every run: a worker's segment outlives the host's runs.
        self.shared = SharedImageReader() if self.wire.shared_memory and shared_memory_supported() else None
        self._pending_timeout_s = pending_timeout_s
        self._sizes = sizes
        self._max_pending = (max_pending_frames, max_pending_bytes)
        self.watchers = Watchers(channels)
        self.finished = threading.Event()
        self._lock = threading.RLock()
        self._ended: list[dict] = []
        self._enders: list[threading.Thread] = []
        # The counts of the runs over and gone (no longer current), summed; the runs whose counts
        # may still change are live (counts()).
        self._folded: Counter[CountKey] = Counter()
        self._live: list[_Run] = []
        self._run = self._new_run("")
        #: Its Prometheus metrics (docs/metrics.md): counts() and current() read at scrape time,
        #: every composite's latency observed in _on_complete.
        self.metrics = CompositorMetrics(self.counts, self.current, tuple(key for key, _ in HOPS))

    # --- runs ---------------------------------------------------------------------------------
    @property
    def gatherer(self) -> FrameGatherer:
        """The current run's gatherer."""
        with self._lock:
            return self._run.gatherer

    @property
    def run_directory(self) -> Path | None:
        """Where the current run's files go (None before its first frame)."""
        with self._lock:
            return self._run.directory

    def _new_run(self, run_id: str) -> _Run:
        """A run's state; its directory is opened now if the run is named."""
        gatherer = FrameGatherer(self.channels, lambda f: None, run_id=run_id,
                                 pending_timeout_s=self._pending_timeout_s, sizes=self._sizes,
                                 max_pending_frames=self._max_pending[0], max_pending_bytes=self._max_pending[1],
                                 shared=self.shared)
        run = _Run(run_id, gatherer, TimingStats())
        run.gatherer.on_complete = lambda frame: self._on_complete(run, frame)
        if run_id:
            self._open_directory(run)
        with self._lock:
            self._live.append(run)
        return run

    def _open_directory(self, run: _Run, name: str = "") -> None:
        """Give the run its directory (runs/<name or run id>) and recorder; point OUT/latest at it."""
        # The run id names a directory: anything but a plain name (a path, ".", "..") is hashed.
        name = name or (run.run_id if _RUN_NAME.fullmatch(run.run_id) and run.run_id.strip(".") else
                        "run-" + hashlib.sha1(run.run_id.encode()).hexdigest()[:12])
        directory = self.out_dir / "runs" / name
        k = 2
        while directory.exists():  # the same run seen again (the compositor restarted): never overwrite
            directory = self.out_dir / "runs" / f"{name}.{k}"
            k += 1
        directory.mkdir(parents=True)
        run.directory = directory
        run.recorder = FrameRecorder(directory / "frames", record_every=self.record_every, exr_every=self.exr_every,
                                     record_per_s=self.record_per_s)
        latest = self.out_dir / "latest"
        tmp = self.out_dir / f".latest.{os.getpid()}"
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(directory.relative_to(self.out_dir))
        tmp.replace(latest)  # atomic: a reader sees the old run or the new one
        log.info("run %s: writing to %s", run.run_id, directory)

    def on_published(self, frame: frame_pb2.Frame) -> None:
        """The host published a frame (the observer stream): a frame of a new run ends the
        current run first."""
        with self._lock:
            run = self._run
            if run.directory is None and not run.ended:
                # The first run: images may already wait in the gatherer; it adopts the id.
                run.run_id = frame.run_id
                self._open_directory(run)
            elif frame.run_id != run.run_id or run.ended:
                log.info("run %s follows run %s", frame.run_id, run.run_id)
                self._run = self._new_run(frame.run_id)
                self._fold(run)
                if not run.ended:
                    # The host restarted without ending its stream: finalise on a thread, so
                    # the new run's first frames are not held up by the old recorder.
                    ender = threading.Thread(target=self._end, args=(run, 0.0), daemon=True)
                    self._enders = [t for t in self._enders if t.is_alive()] + [ender]
                    ender.start()
                run = self._run
        run.gatherer.on_published(frame)

    def submit(self, request: compositor_pb2.SubmitChannelImageRequest) -> None:
        """A channel delivered an image: to the current run's gatherer, after waiting up to
        SUBMIT_WAIT_S for the compositor's copy of its frame.

        Raises:
            InvalidSubmission: as FrameGatherer.submit.
        """
        deadline = time.monotonic() + SUBMIT_WAIT_S
        while self.gatherer.accepts(request.run_id, request.frame_number) is False and time.monotonic() < deadline:
            time.sleep(0.005)
        self.gatherer.submit(request)

    def end_run(self, run_id: str, *, host_status: dict | None = None, grace_s: float = 0.0) -> None:
        """The host's run run_id is over: wait up to grace_s for its open frames, decide them,
        write its report."""
        with self._lock:
            run = self._run
        if run.run_id == run_id and not run.ended:
            if host_status is not None:
                run.host_status = host_status
            self._end(run, grace_s)

    def _end(self, run: _Run, grace_s: float) -> dict:
        with self._lock:
            first = not run.ending
            run.ending = True
        if not first:
            # Another thread is ending it (writing report.json through the same temporary
            # name: two writers raced there when SIGTERM came as the host's stream ended).
            run.end_done.wait()
            return self._report(run)
        try:
            return self._end_once(run, grace_s)
        finally:
            run.end_done.set()

    def _end_once(self, run: _Run, grace_s: float) -> dict:
        deadline = time.monotonic() + grace_s
        while run.gatherer.pending and time.monotonic() < deadline:
            time.sleep(0.05)
        run.gatherer.finalize_all()
        if run.recorder is not None:
            run.recorder.close()
        with self._lock:
            run.ended = True
            self._fold(run)
        doc = self._report(run)
        if run.directory is not None:
            _write_json(run.directory / "report.json", doc)
        with self._lock:
            self._ended.append({"run_id": run.run_id, "directory": str(run.directory or ""),
                                "frames_published": doc["frames_published"],
                                "frames_complete": doc["frames_complete"],
                                "frames_incomplete": doc["frames_incomplete"]})
            del self._ended[:-RUNS_LISTED]
        log.info("run %s over: %d complete, incomplete %s; %s", run.run_id, doc["frames_complete"],
                 doc["frames_incomplete"], wire_summary(doc["wire"]))
        return doc

    def _fold(self, run: _Run) -> None:
        """Add a run's counts to the totals once it is over and no longer current: nothing
        reaches it then (lock held)."""
        if run.ended and run is not self._run and run in self._live:
            self._live.remove(run)
            self._folded.update(_run_counts(run))

    def counts(self) -> Counter[CountKey]:
        """Every run's counts (metrics.COUNTERS), summed over the compositor's life: the runs
        folded and the live ones; they only grow."""
        with self._lock:
            total = Counter(self._folded)
            for run in self._live:
                total.update(_run_counts(run))
            return total

    def current(self) -> dict:
        """The current run's id, open frames and the bytes they hold."""
        with self._lock:
            run = self._run
        gathered = run.gatherer.counters()
        return {"run_id": run.run_id, "frames_pending": gathered["frames_pending"],
                "pending_bytes": gathered["pending_bytes"]}

    def refuse(self, cause: str, message: str) -> None:
        """Count a request refused before it reached the gatherer (add_service: malformed bytes,
        overlong text) with the submissions refused."""
        self.gatherer.count_refused(cause, message)

    # --- frames -------------------------------------------------------------------------------
    def _on_complete(self, run: _Run, frame: CompleteFrame) -> None:
        try:
            composite = compose(frame, self.plan, prefer=self.wire.format)
        except ValueError as exc:
            with self._lock:
                run.stitch_errors += 1
            log.error("frame %d not stitched: %s", frame.frame_number, exc)
            return
        with self._lock:
            run.stitched["srgb8" if composite.rgb.dtype.itemsize == 1 else "half"] += 1
        figures = run.timing.add(composite)
        self.metrics.observe(figures.latency, figures.hops, figures.interval)
        if run.recorder is not None:
            run.recorder.offer(composite)
        self.watchers.publish(composite)

    # --- report -------------------------------------------------------------------------------
    def _report(self, run: _Run) -> dict:
        doc = run.gatherer.report()
        doc.update(run.timing.report())
        counts = run.recorder.snapshot() if run.recorder is not None else RecorderCounts()
        with self._lock:
            doc["stitch_errors"] = run.stitch_errors
            # The format a frame of mixed formats is stitched in, and what the composites were.
            doc["wire"].update(format=self.wire.format, shared_memory=self.shared is not None,
                               composites=dict(run.stitched))
            doc["run_over"] = run.ended
            doc["runs_before"] = list(self._ended)
        doc["record_every"] = self.record_every
        doc["record_per_s"] = self.record_per_s
        doc["exr_every"] = self.exr_every
        doc["frames_written"] = counts.written
        doc["frames_not_recorded"] = counts.not_recorded
        doc["write_errors"] = counts.errors
        doc["run_dir"] = str(run.directory or "")
        doc["frames_dir"] = str(run.directory / "frames") if run.directory is not None else ""
        doc["seams"] = self.seams
        doc["host"] = run.host_status
        doc["finished"] = self.finished.is_set()
        return doc

    def report(self) -> dict:
        """The current run's report document (report.json): gatherer counters, timing, recorder
        counters, host counters, the runs before it (docs/frame-lock.md, docs/latency.md)."""
        with self._lock:
            run = self._run
        return self._report(run)

    def finish(self, *, grace_s: float) -> dict:
        """Stop: end the current run (waiting up to grace_s for its open frames), close the
        watchers; returns the last run's report."""
        with self._lock:
            run = self._run
            if run.directory is None:
                # Stopped before the host published anything: the report still says so.
                self._open_directory(run, time.strftime("no-frames-%Y%m%dT%H%M%SZ", time.gmtime()))
        # Runs before this one end first, so that runs_before lists them in the order they ran.
        for ender in self._enders:
            ender.join()
        # Through _end even when the run is marked ended: another thread may still be writing
        # its report.json, and _end waits for it (writing it here at the same time lost one
        # writer's temporary file).
        self._end(run, grace_s)
        self.watchers.close()
        self.finished.set()
        if self.shared is not None:
            self.shared.close()
        doc = self._report(run)
        if run.directory is not None:
            _write_json(run.directory / "report.json", doc)
        return doc


def _run_counts(run: _Run) -> Counter[CountKey]:
    """A run's counts for the metrics: its gatherer's, stitcher's and recorder's."""
    recorded = run.recorder.snapshot() if run.recorder is not None else RecorderCounts()
    return run_counts(run.gatherer.counters(), stitch_errors=run.stitch_errors, composites=run.stitched,
                      written=recorded.written, not_recorded=recorded.not_recorded, write_errors=recorded.errors)


def wire_summary(wire: dict) -> str:
    """One line of what fed the compositor: images by format and by way, summed over the
    channels ("wire: 300 srgb8 (300 in shared memory), 0 half")."""
    total = Counter[str]()
    for counts in wire["channels"].values():
        total.update({k: v for k, v in counts.items() if k != "bytes_per_image"})
    return (f"wire: {total['srgb8']} srgb8, {total['half']} half images ({total['shared_memory']} in shared memory, "
            f"{total['inline']} inline)")


def _write_json(path: Path, doc: dict) -> None:
    """Write doc to path through a temporary name, so a reader never sees half a report."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # A temporary name of this writer's own: two writers of one report never share it.
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    tmp.replace(path)


class CompositorServicer(compositor_pb2_grpc.CompositorServiceServicer):
    """Thin servicer: submissions go to the gatherer, the report comes from the compositor."""

    def __init__(self, compositor: Compositor) -> None:
        self.compositor = compositor

    def SubmitChannelImage(self, request, context):
        if self.compositor.finished.is_set():
            context.abort(grpc.StatusCode.FAILED_PRECONDITION, "the compositor has stopped; report written")
        try:
            self.compositor.submit(request)
        except InvalidSubmission as exc:
            log.warning("submission refused (%s from %s): %s", exc.cause, context.peer(), exc)
            code = _STATUS.get(exc.cause, grpc.StatusCode.INVALID_ARGUMENT)
            context.abort(code, str(exc))
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


#: Status of a refused submission by cause; INVALID_ARGUMENT for the others.
#: SHARED_UNAVAILABLE tells the worker to send inline (compositor.proto, SubmitChannelImageRequest.shared).
_STATUS = {OTHER_RUN: grpc.StatusCode.FAILED_PRECONDITION, UNPUBLISHED: grpc.StatusCode.OUT_OF_RANGE,
           SHARED_UNAVAILABLE: grpc.StatusCode.FAILED_PRECONDITION}


def observe_host(compositor: Compositor, host_address: str, stop: threading.Event, *, once: bool = False,
                 grace_s: float = 5.0, security: Security | None = None) -> bool:
    """Follow the host's frame stream as an observer, run after run; True once a run has ended
    (with once, after the first).

    Subscribes again while the host is not up yet or the stream breaks. The host closing the
    stream normally means its run is over: the host's final counters go into the run's report,
    the run is ended (Compositor.end_run) and, without once, the next run is waited for. The
    counters come with the stream's last message (RunEnd), however the host stopped; a stream
    that ends without one (a host before issue 33) has them asked of GetHostStatus, which a host
    stopped by SIGTERM may no longer answer.
    """
    backoff = RunEndedBackoff()
    with make_channel(host_address, security) as channel:
        stub = host_pb2_grpc.HostServiceStub(channel)
        ended_any = False
        while not stop.is_set():
            stream = stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="compositor"),
                                          wait_for_ready=True, timeout=STREAM_DEADLINE_S)
            # SIGTERM must not wait for the next frame: cancel the stream when stop is set.
            done = threading.Event()
            threading.Thread(target=_cancel_on_stop, args=(stream, stop, done), daemon=True).start()
            run_id = ""
            status: dict | None = None
            try:
                for response in stream:
                    if response.HasField("run_end"):
                        status = host_status_doc(response.run_end.host_status)
                        status["run_end"] = _END_REASONS.get(response.run_end.reason, "")
                        continue
                    if run_id and response.frame.run_id != run_id:
                        # The host started a new run in the same stream (a CIGI host restarted):
                        # the run that ends gets the host's counters as they stand, as at the
                        # end of a stream.
                        compositor.end_run(run_id, host_status=_host_status(stub))
                    compositor.on_published(response.frame)
                    run_id = response.frame.run_id
                    backoff.reset()
            except grpc.RpcError as exc:
                if stop.is_set():
                    return ended_any
                if run_ended(exc):
                    # The host's run ended before we subscribed: it lingers, then exits.
                    log.info("host: %s; subscribing again after a pause", exc.details())
                    if once:
                        return True
                    stop.wait(backoff.pause())
                    continue
                log.warning("host stream: %s %s; subscribing again", exc.code().name, exc.details())
                stop.wait(1.0)
                continue
            finally:
                done.set()
            if status is None:
                status = _host_status(stub)
            run_id = run_id or (status or {}).get("run_id", "")
            compositor.end_run(run_id, host_status=status, grace_s=grace_s)
            ended_any = True
            if once:
                return True
            # The host lingers a moment after its run, refusing new streams: ask again after a
            # pause, longer after each refusal (services/rig/resubscribe.py), never in a tight loop.
            stop.wait(backoff.pause())
    return ended_any


#: RunEnd.reason as the report says it (report["host"]["run_end"]).
_END_REASONS = {host_pb2.RUN_END_REASON_COMPLETED: "completed", host_pb2.RUN_END_REASON_STOPPED: "stopped"}


def _host_status(stub: host_pb2_grpc.HostServiceStub) -> dict | None:
    """The host's counters for the report, asked of GetHostStatus; None if it does not answer."""
    try:
        s = stub.GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=RPC_DEADLINE_S)
    except grpc.RpcError as exc:
        log.warning("host status unavailable: %s", exc.code().name)
        return None
    return host_status_doc(s)


def host_status_doc(s: host_pb2.GetHostStatusResponse) -> dict:
    """The host's counters as the report holds them (report["host"], docs/frame-lock.md)."""
    return {
        "run_id": s.run_id, "frames_published": s.frames_published,
        "eyepoints_rejected": s.eyepoints_rejected, "ack_timeouts": dict(s.ack_timeouts),
        "ack_failures": dict(s.ack_failures), "channel_absent": dict(s.channel_absent),
        "late_acks": dict(s.late_acks), "requests_refused": dict(s.requests_refused),
        "subscriptions_rejected": s.subscriptions_rejected, "queue_drops": dict(s.queue_drops),
        "last_error": s.last_error,
        # Where the eyepoints came from and what the control inputs or the replayed log
        # refused, by cause (docs/host-inputs.md, docs/replay-formats.md).
        "eyepoint_source": s.eyepoint_source,
        "inputs": [json_format.MessageToDict(i, preserving_proto_field_name=True) for i in s.inputs],
        "replay": json_format.MessageToDict(s.replay, preserving_proto_field_name=True)
        if s.HasField("replay") else None,
        "flight_model": json_format.MessageToDict(s.flight_model, preserving_proto_field_name=True)
        if s.HasField("flight_model") else None,
        # The external CIGI host: messages and packets used, refused and unused, queries,
        # staleness and restarts (docs/cigi.md).
        "cigi": json_format.MessageToDict(s.cigi, preserving_proto_field_name=True,
                                          always_print_fields_with_no_presence=True)
        if s.HasField("cigi") else None,
        "runs": s.runs}


def _cancel_on_stop(stream: grpc.Future, stop: threading.Event, done: threading.Event) -> None:
    """Cancel stream as soon as stop is set; return when done is set first."""
    while not done.is_set():
        if stop.wait(0.2):
            stream.cancel()
            return


def serve(compositor: Compositor, address: str, host_address: str, stop: threading.Event, *,
          once: bool = False, grace_s: float = 5.0, security: Security | None = None,
          max_receive_bytes: int = MAX_MESSAGE_BYTES, metrics_address: str | None = None,
          view: ViewSpec | None = None) -> dict:
    """Serve the compositor on address and follow the host at host_address; returns the last
    run's report.

    With once, the compositor finishes when the host's run ends; otherwise it follows run after
    run until stop is set (SIGTERM). Either way it finalises open frames, writes the run's
    report.json, reports NOT_SERVING and stops the server. max_receive_bytes: the largest
    message taken (the largest channel image of the rig and its fields); metrics_address:
    host:port of its Prometheus metrics (docs/metrics.md), None for none; view: where its live
    view listens (docs/live-view.md), None for none.

    Raises:
        OSError: address, metrics_address or the view's address cannot be bound, or plaintext
            off the loopback is not allowed.
    """
    metrics = serve_metrics(compositor.metrics.registry, metrics_address)
    live = None
    try:
        if view is not None:
            live = LiveView(compositor.report, compositor.channels, compositor.watchers, view.address,
                            certificate=view.certificate, allow_plaintext=view.allow_plaintext)
            compositor.metrics.add_view(live.frames.counts)
        server = make_server(max_receive_bytes=max_receive_bytes)
        add_service(server, CompositorServicer(compositor),
                    compositor_pb2.DESCRIPTOR.services_by_name["CompositorService"], refused=compositor.refuse)
        health = add_health(server, [SERVICE], refused=compositor.refuse)
        bind(server, address, security)
        return _run(compositor, server, health, address, host_address, stop, once=once, grace_s=grace_s,
                    security=security)
    finally:
        if live is not None:
            live.close()
        if metrics is not None:
            metrics.close()


def _run(compositor: Compositor, server: grpc.Server, health, address: str, host_address: str,
         stop: threading.Event, *, once: bool, grace_s: float, security: Security | None) -> dict:
    """serve()'s life of the server: start, follow the host, finish, stop; the last run's report."""
    server.start()
    log.info("compositor listening on %s, writing to %s; wire %s, shared memory %s", address, compositor.out_dir,
             compositor.wire.format, "taken" if compositor.shared is not None else "refused (images inline)")
    observer_done = threading.Event()

    def follow() -> None:
        if observe_host(compositor, host_address, stop, once=once, grace_s=grace_s, security=security):
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
    log.info("compositor done: %d complete, incomplete %s, %s, report in %s", doc["frames_complete"],
             doc["frames_incomplete"], wire_summary(doc["wire"]), doc["run_dir"] or compositor.out_dir)
    return doc
