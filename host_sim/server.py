"""The host's gRPC service: a thin servicer over FramePublisher, and serve()."""

from __future__ import annotations

import logging
import threading

import grpc

from ig.v1 import host_pb2, host_pb2_grpc
from services.grpc_util import add_health, bind, make_server, set_not_serving

from .publisher import ChannelTaken, FramePublisher, UnknownChannel

log = logging.getLogger("ig.host")
SERVICE = "ig.v1.HostService"

#: How often a stream handler wakes up to notice a cancelled client or a stopping host.
_POLL_S = 0.5


class HostServicer(host_pb2_grpc.HostServiceServicer):
    def __init__(self, publisher: FramePublisher, stop: threading.Event) -> None:
        self.publisher = publisher
        self.stop = stop

    def SubscribeFrames(self, request, context):
        try:
            sub = self.publisher.subscribe(request.subscriber or context.peer(), request.channel_name)
        except UnknownChannel as exc:
            log.warning("subscription refused: %s", exc)
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        except ChannelTaken as exc:
            log.warning("subscription refused: %s", exc)
            context.abort(grpc.StatusCode.ALREADY_EXISTS, str(exc))
        log.info("subscriber %s (channel %r) joined", sub.subscriber, sub.channel_name)
        try:
            while context.is_active() and not self.stop.is_set():
                frame = sub.get(_POLL_S)
                if frame is not None:
                    yield host_pb2.SubscribeFramesResponse(frame=frame)
                elif sub.closed:
                    return
        finally:
            self.publisher.unsubscribe(sub)

    def AckFrame(self, request, context):
        try:
            self.publisher.ack(request.channel_name, request.frame_number, ok=request.ok, error=request.error)
        except UnknownChannel as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        return host_pb2.AckFrameResponse()

    def GetHostStatus(self, request, context):
        s = self.publisher.snapshot()
        return host_pb2.GetHostStatusResponse(
            run_id=s.run_id, frames_published=s.frames_published, eyepoints_rejected=s.eyepoints_rejected,
            ack_timeouts=s.ack_timeouts, ack_failures=s.ack_failures, queue_drops=s.queue_drops,
            subscriptions_rejected=s.subscriptions_rejected, subscribers=s.subscribers,
            finished=s.finished, last_error=s.last_error, channel_absent=s.channel_absent)


def serve(publisher: FramePublisher, address: str, stop: threading.Event, *,
          linger_s: float = 2.0) -> int:
    """Serve the host on address and run the publisher until the run ends or stop is set.

    After the run it keeps answering for linger_s so that late acknowledgements and status
    requests still succeed, then stops. Returns the bound port.
    """
    server = make_server()
    host_pb2_grpc.add_HostServiceServicer_to_server(HostServicer(publisher, stop), server)
    health = add_health(server, [SERVICE])
    port = bind(server, address)
    server.start()
    log.info("host listening on %s (run %s, %d frames at %.1f Hz)", address, publisher.status.run_id,
             publisher.tick_count, publisher.rate_hz)
    runner = threading.Thread(target=publisher.run, args=(stop,), name="publisher", daemon=True)
    runner.start()
    while runner.is_alive() and not stop.wait(0.2):
        pass
    runner.join()
    stop.wait(linger_s)
    set_not_serving(health, [SERVICE])
    server.stop(grace=1.0).wait()
    s = publisher.snapshot()
    log.info("host done: %d frames published, %d eyepoints rejected, ack timeouts %s",
             s.frames_published, s.eyepoints_rejected, s.ack_timeouts)
    return port
