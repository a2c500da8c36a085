"""A channel worker: subscribe to the host, render the newest frame, submit it, acknowledge it.

A receiver thread drains the host's stream into a one-frame slot, so the render loop always
takes the newest frame: a worker never renders an old frame late. Frames that were replaced in
the slot before they were rendered are counted as skipped (none in synchronous mode, where the
host waits for every channel).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import grpc
import numpy as np

from host_sim.publisher import eyepoint_of
from ig.v1 import compositor_pb2, compositor_pb2_grpc, frame_pb2, host_pb2, host_pb2_grpc
from services.grpc_util import RPC_DEADLINE_S, add_health, bind, make_channel, make_server, set_not_serving

from .pipeline.render import render_frame
from .pipeline.types import ChannelSpec, Database, Eyepoint

log = logging.getLogger("ig.worker")
SERVICE = "ig.v1.ChannelWorker"


@dataclass
class WorkerCounters:
    frames_rendered: int = 0
    frames_skipped: int = 0
    frames_refused: int = 0
    submit_failures: int = 0
    ack_failures: int = 0


def encode_rgb_f16(rgb: np.ndarray) -> bytes:
    """PIXEL_FORMAT_RGB_F16: linear RGB as little-endian half floats, top row first."""
    return np.ascontiguousarray(rgb, dtype="<f2").tobytes()


class LatestFrame:
    """A one-frame mailbox: put replaces what is there; take waits for something new."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._frame: frame_pb2.Frame | None = None
        self._ended = False

    def put(self, frame: frame_pb2.Frame) -> None:
        with self._cond:
            self._frame = frame
            self._cond.notify_all()

    def end(self) -> None:
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def take(self, timeout_s: float) -> frame_pb2.Frame | None:
        with self._cond:
            self._cond.wait_for(lambda: self._frame is not None or self._ended, timeout=timeout_s)
            frame, self._frame = self._frame, None
            return frame

    @property
    def ended(self) -> bool:
        with self._cond:
            return self._ended and self._frame is None


class ChannelWorker:
    """Renders one channel of the rig for as long as the host publishes.

    Args:
        database: the loaded scene.
        channel: this channel's view.
        host_address, compositor_address: host:port of the services.
        samples: sample pattern name or count.
        once: stop when the host's run ends instead of subscribing again.
    """

    def __init__(self, database: Database, channel: ChannelSpec, *, host_address: str,
                 compositor_address: str, samples: int | str = 4, once: bool = False) -> None:
        self.database = database
        self.channel = channel
        self.samples = samples
        self.once = once
        self.counters = WorkerCounters()
        self._host = make_channel(host_address)
        self._compositor = make_channel(compositor_address)
        self.host_stub = host_pb2_grpc.HostServiceStub(self._host)
        self.compositor_stub = compositor_pb2_grpc.CompositorServiceStub(self._compositor)
        self._last_rendered = -1

    def warm_up(self) -> None:
        """Compile the numba kernels before the first real frame (several seconds the first time)."""
        tiny = ChannelSpec("warm-up", 8, 6, self.channel.left_deg, self.channel.right_deg,
                           self.channel.bottom_deg, self.channel.top_deg)
        render_frame(self.database, tiny, Eyepoint.of(0, 0, 10, 0, 0, 0), samples=self.samples)

    def run(self, stop: threading.Event) -> None:
        """Subscribe and render until the run ends (once) or stop is set."""
        while not stop.is_set():
            mailbox = LatestFrame()
            receiver = threading.Thread(target=self._receive, args=(mailbox, stop), daemon=True)
            receiver.start()
            got_any = False
            while not stop.is_set():
                frame = mailbox.take(0.5)
                if frame is None:
                    if mailbox.ended:
                        break
                    continue
                got_any = True
                self._handle(frame)
            receiver.join(timeout=2.0)
            if self.once and got_any:
                break
            stop.wait(1.0)  # host not there yet, or its run ended: subscribe again shortly
        self._host.close()
        self._compositor.close()

    def _receive(self, mailbox: LatestFrame, stop: threading.Event) -> None:
        request = host_pb2.SubscribeFramesRequest(subscriber=f"worker-{self.channel.name}",
                                                  channel_name=self.channel.name)
        try:
            stream = self.host_stub.SubscribeFrames(request, wait_for_ready=True, timeout=None)
            for response in stream:
                mailbox.put(response.frame)
                if stop.is_set():
                    stream.cancel()
                    break
        except grpc.RpcError as exc:
            if exc.code() == grpc.StatusCode.INVALID_ARGUMENT:
                log.error("host refused the subscription: %s", exc.details())
                stop.set()
            elif exc.code() != grpc.StatusCode.CANCELLED:
                log.warning("host stream ended: %s %s", exc.code().name, exc.details())
        finally:
            mailbox.end()

    def _handle(self, frame: frame_pb2.Frame) -> None:
        number = frame.frame_number
        if self._last_rendered >= 0 and number > self._last_rendered + 1:
            self.counters.frames_skipped += number - self._last_rendered - 1
        self._last_rendered = number
        t0 = time.perf_counter()
        try:
            image = render_frame(self.database, self.channel, eyepoint_of(frame.eyepoint), samples=self.samples)
        except ValueError as exc:
            self.counters.frames_refused += 1
            log.error("frame %d refused: %s", number, exc)
            self._ack(number, ok=False, error=str(exc))
            return
        render_time = time.perf_counter() - t0
        request = compositor_pb2.SubmitChannelImageRequest(
            frame_number=number, channel_name=self.channel.name, width=self.channel.width,
            height=self.channel.height, pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
            pixels=encode_rgb_f16(image.rgb), eyepoint=frame.eyepoint, render_time_s=render_time,
            control_sample_time_unix_s=frame.control_sample_time_unix_s,
            frames_skipped=self.counters.frames_skipped, run_id=frame.run_id)
        ok, error = True, ""
        try:
            self.compositor_stub.SubmitChannelImage(request, timeout=RPC_DEADLINE_S)
            self.counters.frames_rendered += 1
        except grpc.RpcError as exc:
            self.counters.submit_failures += 1
            ok, error = False, f"submit to compositor failed: {exc.code().name} {exc.details()}"
            log.error("frame %d: %s", number, error)
        self._ack(number, ok=ok, error=error)

    def _ack(self, number: int, *, ok: bool, error: str) -> None:
        try:
            self.host_stub.AckFrame(host_pb2.AckFrameRequest(channel_name=self.channel.name, frame_number=number,
                                                             ok=ok, error=error), timeout=RPC_DEADLINE_S)
        except grpc.RpcError as exc:
            self.counters.ack_failures += 1
            log.warning("frame %d: acknowledgement to host failed: %s", number, exc.code().name)


def serve_worker(worker: ChannelWorker, address: str, stop: threading.Event) -> None:
    """Serve the worker's health on address while it renders; blocks until it is done."""
    server = make_server(max_workers=4)
    health = add_health(server, [SERVICE])
    bind(server, address)
    server.start()
    log.info("worker %s: health on %s", worker.channel.name, address)
    try:
        worker.run(stop)
    finally:
        set_not_serving(health, [SERVICE])
        server.stop(grace=0.5).wait()
        c = worker.counters
        log.info("worker %s done: %d rendered, %d skipped, %d refused, %d submit failures",
                 worker.channel.name, c.frames_rendered, c.frames_skipped, c.frames_refused, c.submit_failures)
