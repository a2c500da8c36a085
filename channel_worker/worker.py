"""A channel worker: subscribe to the host, render the newest frame, submit it, acknowledge it.

A receiver thread drains the host's stream into a one-frame slot, so the render loop always
takes the newest frame: a worker never renders an old frame late. Frames that were replaced in
the slot before they were rendered are counted as skipped (none in synchronous mode, where the
host waits for every channel; see docs/frame-lock.md).

The worker also runs a small gRPC server at its rig address: the standard health service and
ChannelWorkerService.GetWorkerStatus (its counters).
"""

from __future__ import annotations

import enum
import logging
import threading
import time
from dataclasses import asdict, dataclass

import grpc
import numpy as np

from ig.v1 import (
    compositor_pb2,
    frame_pb2,
    host_pb2,
    host_pb2_grpc,
    worker_pb2,
    worker_pb2_grpc,
)
from services.rig.environment import apply_view, environment_from_proto
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.grpc_util import (
    MAX_TEXT_CHARS,
    RPC_DEADLINE_S,
    STREAM_DEADLINE_S,
    Security,
    add_health,
    add_service,
    bind,
    clip,
    make_channel,
    make_server,
    set_not_serving,
    set_serving,
)
from services.rig.memory import keep_freed_memory
from services.rig.metrics import serve_metrics
from services.rig.options import RenderOptions
from services.rig.report import FrameReport
from services.rig.resubscribe import RunEndedBackoff, run_ended
from services.rig.rigfile import WireSpec
from services.rig.wire import eyepoint_from_proto, options_to_proto, report_to_proto

from .metrics import WorkerMetrics
from .pipeline.kernel_cache import serialise_cache_writes
from .pipeline.render import render_frame
from .pipeline.scene.database import Database
from .pipeline.scene.environment import WARM_UP_ENVIRONMENT, EnvironmentCache
from .query.service import add_query_service, warm_queries
from .submit import ImageSender, SubmitStub, warm_encoders

log = logging.getLogger("ig.worker")
SERVICE = "ig.v1.ChannelWorkerService"

#: Pause before subscribing again after a stream broke (the host gone, a deadline), seconds.
_RESUBSCRIBE_S = 1.0
#: Every how many frames the worker logs its frame report at INFO (5 s at 60 Hz).
REPORT_EVERY = 300


@dataclass
class WorkerCounters:
    """What the worker has done since it started (mirrors GetWorkerStatusResponse)."""

    frames_handled: int = 0
    frames_rendered: int = 0
    frames_skipped: int = 0
    frames_refused: int = 0
    submit_failures: int = 0
    ack_failures: int = 0
    translucent_dropped: int = 0
    terrain_voxels_last_frame: int = 0
    terrain_voxels_total: int = 0
    terrain_eye_clamped: int = 0
    last_frame_number: int = 0
    run_id: str = ""
    last_error: str = ""
    runs: int = 0
    malformed_requests: int = 0
    resubscriptions: int = 0


class StreamEnd(enum.Enum):
    """How one subscription to the host ended."""

    RUN_OVER = "run over"  # the host closed the stream: its run has ended
    RUN_OVER_REFUSED = "run over, refused"  # the host's run had ended before we subscribed
    REFUSED = "refused"  # the host refused the channel name: the rig files disagree
    LOST = "lost"  # the host is gone, the deadline passed, or the channel is still taken
    STOPPED = "stopped"  # this worker is shutting down


class LatestFrame:
    """A one-frame mailbox: put replaces what is there; take waits for something new."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._frame: frame_pb2.Frame | None = None
        self._received = 0.0
        self._ended = False

    def put(self, frame: frame_pb2.Frame) -> None:
        """Replace what is there; the frame's arrival is stamped now (wall clock, UNIX seconds)."""
        received = time.time()
        with self._cond:
            self._frame = frame
            self._received = received
            self._cond.notify_all()

    def end(self) -> None:
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def take(self, timeout_s: float) -> frame_pb2.Frame | None:
        """The newest frame not taken yet; None if none came within timeout_s seconds."""
        taken = self.take_stamped(timeout_s)
        return taken[0] if taken else None

    def take_stamped(self, timeout_s: float) -> tuple[frame_pb2.Frame, float] | None:
        """As take, with the frame's arrival time (UNIX seconds)."""
        with self._cond:
            self._cond.wait_for(lambda: self._frame is not None or self._ended, timeout=timeout_s)
            frame, self._frame = self._frame, None
            return (frame, self._received) if frame is not None else None

    @property
    def ended(self) -> bool:
        """True once the stream has ended and its last frame was taken."""
        with self._cond:
            return self._ended and self._frame is None


class ChannelWorker:
    """Renders one channel of the rig for as long as the host publishes.

    Args:
        database: the loaded scene.
        channel: this channel's view.
        host_address: host:port of HostService.
        compositor_address: host:port of CompositorService.
        options: the render options (with_range is turned off: the compositor takes colour
            only).
        once: stop when the host's run ends instead of subscribing again for the next run.
        security: mutual TLS or plaintext to host and compositor (grpc_util.make_channel).
        cigi: the rig follows a CIGI host: the warm-up renders under a host's weather too
            (environment.WARM_UP_ENVIRONMENT) and prepares the query kernels; otherwise the
            first weather or query, if any, loads their kernels then.
        wire: the images' format to the compositor, and whether shared memory may carry them
            (the rig file's [compositor] wire and shared_memory; submit.ImageSender).
    """

    def __init__(self, database: Database, channel: ChannelSpec, *, host_address: str,
                 compositor_address: str, options: RenderOptions | None = None,
                 once: bool = False, security: Security | None = None, cigi: bool = False,
                 wire: WireSpec | None = None) -> None:
        self.database = database
        self.cigi = cigi
        self.channel = channel
        self.options = (options or RenderOptions()).replace(with_range=False)
        #: Stage times and counters of the last frame rendered.
        self.last_report = FrameReport()
        #: True once a warm-up frame has rendered (kernels compiled or loaded from the cache).
        self.ready = False
        # One colour array for every frame (and the sender's one wire buffer or ring): the image
        # is encoded and sent to the compositor before the next frame is rendered, and reusing
        # them spares faulting in fresh pages each frame.
        self._rgb = np.empty((channel.height, channel.width, 3), np.float32)
        self.sender = ImageSender(channel, compositor_address=compositor_address, wire=wire)
        self.once = once
        self.counters = WorkerCounters()
        #: Why the host refused this worker (its channel is not in the host's rig), else "".
        self.refused = ""
        self._lock = threading.Lock()
        self._subscribed = False
        self._stream: grpc.Future | None = None
        self._host = make_channel(host_address, security)
        self._compositor = make_channel(compositor_address, security)
        self.host_stub = host_pb2_grpc.HostServiceStub(self._host)
        self.compositor_stub = SubmitStub(self._compositor)
        self._last_taken = -1
        self._eye_below_said = False  # the eye-below-terrain warning, said once a run
        # Pauses before subscribing again after a run ended; reset by the receiver on a frame
        # (it is joined before run() takes the next pause).
        self._backoff = RunEndedBackoff()
        # The host's environment as this worker's database, built once per environment.
        self._environments = EnvironmentCache()
        #: Its Prometheus metrics: the counters above, read at scrape time, and every frame's
        #: stage times (docs/metrics.md).
        self.metrics = WorkerMetrics(channel.name, self.status)

    def warm_up(self) -> None:
        """Compile the numba kernels before the first real frame (several seconds the first time).

        Done before subscribing, so the first frames of the run are not held up by the compiler.
        Cache saves are locked: workers of one machine started on a cold cache without
        `ig compile` may compile the same kernels at once.
        """
        serialise_cache_writes()
        keep_freed_memory()
        tiny = ChannelSpec("warm-up", 8, 6, self.channel.left_deg, self.channel.right_deg,
                           self.channel.bottom_deg, self.channel.top_deg)
        render_frame(self.database, tiny, Eyepoint.of(0, 0, 10, 0, 0, 0), self.options)
        warm_encoders()  # compiles (or loads) the encoders too
        if self.cigi:
            # The host's first weather and first queries must not wait for a compiler.
            render_frame(self._environments.get(self.database, WARM_UP_ENVIRONMENT), tiny,
                         Eyepoint.of(0, 0, 10, 0, 0, 0), self.options)
            warm_queries(self.database)
        self.ready = True

    def status(self) -> worker_pb2.GetWorkerStatusResponse:
        """A consistent copy of the counters."""
        with self._lock:
            return worker_pb2.GetWorkerStatusResponse(
                channel_name=self.channel.name, subscribed=self._subscribed, ready=self.ready,
                render_options=options_to_proto(self.options),
                last_frame_report=report_to_proto(self.last_report), **asdict(self.counters))

    def run(self, stop: threading.Event) -> None:
        """Subscribe and render until the run ends (with once), the host refuses us, or stop is set."""
        try:
            while not stop.is_set():
                mailbox = LatestFrame()
                outcome: list[StreamEnd] = []
                receiver = threading.Thread(target=self._receive, args=(mailbox, stop, outcome),
                                            name="frame-receiver", daemon=True)
                receiver.start()
                while not (stop.is_set() or mailbox.ended):
                    taken = mailbox.take_stamped(0.5)
                    if taken is not None:
                        self._handle(*taken)
                self._cancel_stream()
                receiver.join()
                end = outcome[0] if outcome else StreamEnd.STOPPED
                run_over = end in (StreamEnd.RUN_OVER, StreamEnd.RUN_OVER_REFUSED)
                if end is StreamEnd.REFUSED or (run_over and self.once):
                    break
                with self._lock:
                    self.counters.resubscriptions += 1
                # After a run the host lingers a moment, refusing new subscriptions, before it
                # exits: the worker pauses before asking again, longer after each refusal
                # (services/rig/resubscribe.py), instead of asking in a tight loop. A broken stream
                # is retried after a fixed pause, the channel's reconnection backoff (at most 1 s)
                # doing the rest. Once the host is gone the subscription waits for the next one.
                stop.wait(self._backoff.pause() if run_over else _RESUBSCRIBE_S)
        finally:
            self._host.close()
            self._compositor.close()
            self.sender.close()

    def _cancel_stream(self) -> None:
        with self._lock:
            stream = self._stream
        if stream is not None:
            stream.cancel()

    def _receive(self, mailbox: LatestFrame, stop: threading.Event, outcome: list[StreamEnd]) -> None:
        """Receiver thread: drain one subscription into the mailbox; record how it ended."""
        request = host_pb2.SubscribeFramesRequest(subscriber=f"worker-{self.channel.name}",
                                                  channel_name=self.channel.name)
        end = StreamEnd.LOST
        try:
            # wait_for_ready: the host may start after the workers (any start order works).
            stream = self.host_stub.SubscribeFrames(request, wait_for_ready=True, timeout=STREAM_DEADLINE_S)
            with self._lock:
                self._stream = stream
                self._subscribed = True
            if stop.is_set():  # SIGTERM arrived before the stream was registered for cancelling
                stream.cancel()
            for response in stream:
                if response.HasField("frame"):
                    self._backoff.reset()
                    mailbox.put(response.frame)
                elif response.HasField("run_end"):
                    # The stream's last message; the host's counters in it are for the compositor.
                    status = response.run_end.host_status
                    log.info("host run %s ended (%s) after %d frames", status.run_id,
                             host_pb2.RunEndReason.Name(response.run_end.reason), status.frames_published)
            end = StreamEnd.RUN_OVER
        except grpc.RpcError as exc:
            code = exc.code()
            if code == grpc.StatusCode.INVALID_ARGUMENT:
                end = StreamEnd.REFUSED
                self.refused = exc.details() or code.name
                self._note_error(f"host refused the subscription: {self.refused}")
                log.error("host refused the subscription: %s", self.refused)
            elif code == grpc.StatusCode.CANCELLED and stop.is_set():
                end = StreamEnd.STOPPED
            elif run_ended(exc):
                end = StreamEnd.RUN_OVER_REFUSED
                log.info("host: %s; subscribing again after a pause", exc.details())
            else:
                # UNAVAILABLE (host restarting), DEADLINE_EXCEEDED (a very long session),
                # ALREADY_EXISTS (the host has not yet noticed our previous stream died): retry.
                log.warning("host stream ended: %s %s; subscribing again", code.name, exc.details())
        finally:
            with self._lock:
                self._stream = None
                self._subscribed = False
            outcome.append(end)
            mailbox.end()

    def _note_error(self, message: str) -> None:
        with self._lock:
            self.counters.last_error = clip(message)

    def refuse(self, cause: str, message: str) -> None:
        """Count a request to the worker's own server refused before it ran (add_service)."""
        with self._lock:
            self.counters.malformed_requests += 1
            self.counters.last_error = clip(f"{cause}: {message}")

    def _handle(self, frame: frame_pb2.Frame, received: float | None = None) -> None:
        """Render one frame, submit it to the compositor and acknowledge it to the host.

        received is when the frame arrived from the host (UNIX seconds; default now). Never
        raises for a bad frame or an unreachable service: those are counted and logged, and the
        frame is acknowledged with the reason, so the host is not held up.
        """
        received = time.time() if received is None else received
        number = frame.frame_number
        with self._lock:
            c = self.counters
            first_of_run = frame.run_id != c.run_id
            if first_of_run:
                self._last_taken = -1  # frame numbers start again with each run
                self._eye_below_said = False
                c.runs += 1
            if self._last_taken >= 0 and number > self._last_taken + 1:
                c.frames_skipped += number - self._last_taken - 1
            self._last_taken = number
            c.run_id = frame.run_id
            c.last_frame_number = number
            c.frames_handled += 1
            skipped = c.frames_skipped
        render_start = time.time()
        t0 = time.perf_counter()
        try:
            report = FrameReport()
            database, channel = self._scene_of(frame)
            image = render_frame(database, channel, eyepoint_from_proto(frame.eyepoint),
                                 self.options, report=report, out=self._rgb)
            stats = report.counters
            # The first frame of a run and every REPORT_EVERY-th after it go to the log at INFO, so a
            # rig's logs show where each channel's time goes without drowning in per-frame lines.
            level = logging.INFO if first_of_run or number % REPORT_EVERY == 0 else logging.DEBUG
            log.log(level, "worker %s frame %d: %s", self.channel.name, number, report.format())
            with self._lock:
                self.last_report = report
                self.counters.translucent_dropped += stats.get("translucent_dropped", 0)
                self.counters.terrain_voxels_last_frame = stats.get("terrain_voxels", 0)
                self.counters.terrain_voxels_total += stats.get("terrain_voxels", 0)
                self.counters.terrain_eye_clamped += stats.get("terrain_eye_clamped", 0)
                say_below = bool(stats.get("terrain_eye_clamped", 0)) and not self._eye_below_said
                self._eye_below_said = self._eye_below_said or say_below
            if say_below:
                # Once a run (the counter counts every frame): a host flying below the ground is
                # a host's fault the picture alone does not show.
                e = frame.eyepoint
                log.warning("worker %s frame %d: the eye (%.1f, %.1f, %.1f) is below the terrain; the "
                            "terrain is drawn from just above its surface, polygons from the eye "
                            "(counted in terrain_eye_clamped; said once a run)", self.channel.name, number,
                            e.x, e.y, e.z)
        except ValueError as exc:
            # The message names the field and value, e.g. "eyepoint.position[2]: nan is not finite".
            error = clip(f"frame {number} refused: {exc}")
            with self._lock:
                self.counters.frames_refused += 1
                self.counters.last_error = error
            log.error("%s", error)
            self._ack(number, frame.run_id, ok=False, error=str(exc))
            return
        render_time = time.perf_counter() - t0
        render_end = time.time()
        self.metrics.observe(report, render_time)
        head = compositor_pb2.SubmitChannelImageRequest(
            frame_number=number, channel_name=self.channel.name, width=self.channel.width,
            height=self.channel.height, eyepoint=frame.eyepoint, render_time_s=render_time,
            control_sample_time_unix_s=frame.control_sample_time_unix_s,
            frames_skipped=skipped, run_id=frame.run_id, frame_received_unix_s=received,
            render_start_unix_s=render_start, render_end_unix_s=render_end)
        ok, error = True, ""
        try:
            self.sender.submit(self.compositor_stub, head, image.rgb)
            with self._lock:
                self.counters.frames_rendered += 1
        except grpc.RpcError as exc:
            ok, error = False, clip(f"submit to compositor failed: {exc.code().name} {exc.details()}")
            with self._lock:
                self.counters.submit_failures += 1
                self.counters.last_error = f"frame {number}: {error}"
            log.error("frame %d: %s", number, error)
        self._ack(number, frame.run_id, ok=ok, error=error)

    def _scene_of(self, frame: frame_pb2.Frame) -> tuple[Database, ChannelSpec]:
        """The database and channel a frame is rendered with: the external host's environment
        (CIGI) applied to the scene, and its view of this channel (the last one listed) to the
        rig file's. A view changes angles only, so the image keeps the channel's size.

        Raises:
            ValueError: a bad environment or view, named ("environment.visibility_m: ...").
        """
        database, channel = self.database, self.channel
        if frame.HasField("environment"):
            database = self._environments.get(self.database, environment_from_proto(frame.environment))
        for view in frame.views:
            if view.channel == self.channel.name:
                channel = apply_view(self.channel, view)
        return database, channel

    def _ack(self, number: int, run_id: str, *, ok: bool, error: str) -> None:
        # The host refuses error text beyond MAX_TEXT_CHARS: cut it here, with room for the note.
        request = host_pb2.AckFrameRequest(channel_name=self.channel.name, frame_number=number, ok=ok,
                                           error=clip(error, MAX_TEXT_CHARS - 40), run_id=run_id)
        try:
            self.host_stub.AckFrame(request, timeout=RPC_DEADLINE_S)
        except grpc.RpcError as exc:
            with self._lock:
                self.counters.ack_failures += 1
                self.counters.last_error = f"frame {number}: acknowledgement failed: {exc.code().name}"
            log.warning("frame %d: acknowledgement to host failed: %s", number, exc.code().name)


class WorkerStatusServicer(worker_pb2_grpc.ChannelWorkerServiceServicer):
    """Thin servicer: the worker's counters."""

    def __init__(self, worker: ChannelWorker) -> None:
        self.worker = worker

    def GetWorkerStatus(self, request, context):
        return self.worker.status()


def serve_worker(worker: ChannelWorker, address: str, stop: threading.Event, *,
                 security: Security | None = None, metrics_address: str | None = None) -> None:
    """Serve the worker's health and status on address, warm up, then render; blocks until it
    is done.

    Health is NOT_SERVING while the kernels compile (minutes on a cold cache, a second or two
    from the cache) and SERVING once a warm-up frame has rendered, so the host, which waits for
    every channel that answers, knows a compiling worker from a dead one. metrics_address:
    host:port of its Prometheus metrics (docs/metrics.md), None for none; served from the start,
    so that a compiling worker is seen (ready 0).

    Raises:
        OSError: address or metrics_address cannot be bound, or plaintext off the loopback is
            not allowed.
    """
    metrics = serve_metrics(worker.metrics.registry, metrics_address)
    try:
        _serve_worker(worker, address, stop, security)
    finally:
        if metrics is not None:
            metrics.close()


def _serve_worker(worker: ChannelWorker, address: str, stop: threading.Event, security: Security | None) -> None:
    """serve_worker without the metrics."""
    server = make_server(max_workers=4)
    add_service(server, WorkerStatusServicer(worker), worker_pb2.DESCRIPTOR.services_by_name["ChannelWorkerService"],
                refused=worker.refuse)
    # Every worker holds the databases, so any can answer a CIGI host's height-of-terrain and
    # line-of-sight queries (the rig file's cigi.query_channel says which one is asked).
    add_query_service(server, worker.database, refused=worker.refuse, warm=False)
    health = add_health(server, [SERVICE], serving=worker.ready, refused=worker.refuse)
    bind(server, address, security)
    server.start()
    log.info("worker %s: health and status on %s", worker.channel.name, address)
    try:
        if not worker.ready:
            t0 = time.perf_counter()
            log.info("worker %s: compiling the render kernels (NOT_SERVING until done)",
                     worker.channel.name)
            worker.warm_up()
            log.info("worker %s: kernels ready in %.1f s; SERVING", worker.channel.name,
                     time.perf_counter() - t0)
        set_serving(health, [SERVICE])
        worker.run(stop)
    finally:
        # NOT_SERVING first, so health checkers see the worker leave before it stops answering.
        set_not_serving(health, [SERVICE])
        server.stop(grace=0.5).wait()
        c = worker.counters
        log.info("worker %s done: %d rendered, %d skipped, %d refused, %d submit failures, %d ack failures",
                 worker.channel.name, c.frames_rendered, c.frames_skipped, c.frames_refused, c.submit_failures,
                 c.ack_failures)
