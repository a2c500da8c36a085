"""The host's gRPC service: a thin servicer over FramePublisher, and serve()."""

from __future__ import annotations

import logging
import threading
from typing import Any

import grpc

from ig.v1 import host_pb2, host_pb2_grpc
from services.rig.grpc_util import Security, add_health, add_service, bind, make_server, set_not_serving
from services.rig.metrics import serve_metrics

from .metrics import host_registry
from .publisher import (
    COMPLETED,
    STOPPED,
    ChannelTaken,
    FrameOutOfRange,
    FramePublisher,
    OtherRun,
    RunOver,
    UnknownChannel,
)

log = logging.getLogger("ig.host")
SERVICE = "ig.v1.HostService"

#: How often a stream handler wakes up to notice a cancelled client.
_POLL_S = 0.5

#: Longest a stopped host (SIGTERM) keeps serving for its streams to deliver the end of the run
#: (the final counters) before it stops, seconds; they take milliseconds, the publisher closing
#: every subscription within a tenth of a second of the stop.
_STOP_DRAIN_S = 2.0

_END_REASONS = {COMPLETED: host_pb2.RUN_END_REASON_COMPLETED, STOPPED: host_pb2.RUN_END_REASON_STOPPED}


class HostServicer(host_pb2_grpc.HostServiceServicer):
    """HostService over a publisher; eyepoints is what feeds it (for GetHostStatus): a
    ControlledFlight, a Replay, or None for the bundled flight."""

    def __init__(self, publisher: FramePublisher, *, eyepoints: Any = None) -> None:
        self.publisher = publisher
        self.eyepoints = eyepoints

    def SubscribeFrames(self, request, context):
        try:
            sub = self.publisher.subscribe(request.subscriber or context.peer(), request.channel_name)
        except UnknownChannel as exc:
            log.warning("subscription refused: %s", exc)
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        except ChannelTaken as exc:
            log.warning("subscription refused: %s", exc)
            context.abort(grpc.StatusCode.ALREADY_EXISTS, str(exc))
        except RunOver as exc:
            log.info("subscriber %s (channel %r) refused: %s", request.subscriber or context.peer(),
                     request.channel_name, exc)
            context.abort(grpc.StatusCode.FAILED_PRECONDITION, str(exc))
        log.info("subscriber %s (channel %r) joined", sub.subscriber, sub.channel_name)
        try:
            # The stream runs until the publisher closes the subscription, at the end of the run
            # or within a tenth of a second of a stop (SIGTERM), so that every frame published
            # and the end of the run reach the subscriber however the host stops.
            while context.is_active():
                frame = sub.get(_POLL_S)
                if frame is not None:
                    yield host_pb2.SubscribeFramesResponse(frame=frame)
                elif sub.closed:
                    yield host_pb2.SubscribeFramesResponse(run_end=self.run_end())
                    return
        finally:
            self.publisher.unsubscribe(sub)

    def run_end(self) -> host_pb2.RunEnd:
        """The end of the run, the stream's last message: how it ended and the final counters."""
        reason = _END_REASONS.get(self.publisher.end_reason, host_pb2.RUN_END_REASON_UNSPECIFIED)
        return host_pb2.RunEnd(reason=reason, host_status=self.status())

    def AckFrame(self, request, context):
        try:
            self.publisher.ack(request.channel_name, request.frame_number, ok=request.ok, error=request.error,
                               run_id=request.run_id)
        except UnknownChannel as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
        except OtherRun as exc:
            context.abort(grpc.StatusCode.FAILED_PRECONDITION, str(exc))
        except FrameOutOfRange as exc:
            context.abort(grpc.StatusCode.OUT_OF_RANGE, str(exc))
        return host_pb2.AckFrameResponse()

    def GetHostStatus(self, request, context):
        return self.status()

    def status(self) -> host_pb2.GetHostStatusResponse:
        """The host's counters and its eyepoint source's."""
        s = self.publisher.snapshot()
        return host_pb2.GetHostStatusResponse(
            run_id=s.run_id, frames_published=s.frames_published, eyepoints_rejected=s.eyepoints_rejected,
            ack_timeouts=s.ack_timeouts, ack_failures=s.ack_failures, queue_drops=s.queue_drops,
            subscriptions_rejected=s.subscriptions_rejected, subscribers=s.subscribers,
            finished=s.finished, last_error=s.last_error, channel_absent=s.channel_absent,
            requests_refused=s.requests_refused, late_acks=s.late_acks, runs=s.runs,
            **eyepoint_source_status(self.eyepoints))


def eyepoint_source_status(eyepoints: Any) -> dict[str, Any]:
    """GetHostStatusResponse fields describing the eyepoint source (controls, replay, bundled)."""
    from .controlled import ControlledFlight
    from .replay import Replay

    if isinstance(eyepoints, ControlledFlight):
        inputs, model = eyepoints.status()
        return {"eyepoint_source": "controls",
                "inputs": [host_pb2.InputSourceStatus(
                    name=i.name, accepted=i.accepted, rejected=i.rejected, stale=i.stale,
                    last_input_age_s=i.last_input_age_s, last_rejection=i.last_rejection,
                    counters=i.counters, values=i.values) for i in inputs],
                "flight_model": host_pb2.FlightModelStatus(steps=model.steps, speed_mps=model.speed_mps,
                                                           on_ground=model.on_ground)}
    if isinstance(eyepoints, Replay):
        r = eyepoints.status()
        return {"eyepoint_source": "replay",
                "replay": host_pb2.ReplayStatus(
                    path=r.path, format=r.format, records=r.records, problems=r.problems,
                    attitude_estimated=r.attitude_estimated, log_duration_s=r.log_duration_s,
                    log_time_s=r.log_time_s, loops=r.loops)}
    from .cigi.endpoint import CigiEndpoint

    if isinstance(eyepoints, CigiEndpoint):
        status = eyepoints.session.status()
        status["listen"] = f"{eyepoints.listen[0]}:{eyepoints.listen[1]}"
        return {"eyepoint_source": "cigi", "cigi": host_pb2.CigiStatus(**status)}
    from .simhost.receiver import UdpPoseSource

    if isinstance(eyepoints, UdpPoseSource):
        p = eyepoints.status()
        values = {**p.values, "interval_s": p.interval_s, "delay_s": p.delay_s}
        return {"eyepoint_source": "simhost",
                "inputs": [host_pb2.InputSourceStatus(
                    name=p.name, accepted=p.accepted, rejected=p.refused, stale=p.stale,
                    last_input_age_s=p.last_input_age_s, last_rejection=p.last_rejection, counters=p.counters(),
                    values=values)]}
    return {"eyepoint_source": "bundled"}


def serve(publisher: FramePublisher, address: str, stop: threading.Event, *,
          linger_s: float = 2.0, eyepoints: Any = None, security: Security | None = None,
          metrics_address: str | None = None) -> int:
    """Serve the host on address and run the publisher until the run ends or stop is set.

    After a run that ends by itself it keeps answering for linger_s so that late
    acknowledgements and status requests still succeed, refusing new subscriptions; stopped
    (stop set: SIGTERM) it keeps answering only until every stream has delivered the end of the
    run, with the final counters (at most _STOP_DRAIN_S). Then it stops. eyepoints is what the
    publisher's source belongs to (HostServicer); security: mutual TLS or plaintext
    (grpc_util.bind); metrics_address: host:port of its Prometheus metrics (docs/metrics.md),
    None for none. Returns the bound port.

    Raises:
        OSError: address or metrics_address cannot be bound, or plaintext off the loopback is
            not allowed.
    """
    servicer = HostServicer(publisher, eyepoints=eyepoints)
    metrics = serve_metrics(host_registry(servicer.status), metrics_address)
    try:
        server = make_server()
        add_service(server, servicer, host_pb2.DESCRIPTOR.services_by_name["HostService"], refused=publisher.refuse)
        health = add_health(server, [SERVICE], refused=publisher.refuse)
        port = bind(server, address, security)
        _run(publisher, server, health, address, stop, linger_s)
    finally:
        if metrics is not None:
            metrics.close()
    return port


def _run(publisher: FramePublisher, server: grpc.Server, health: Any, address: str, stop: threading.Event,
         linger_s: float) -> None:
    """serve()'s life of the server: start, run the publisher, linger or drain, stop."""
    server.start()
    if publisher.pace == "ticks":
        log.info("host listening on %s (run %s, %d frames at %.1f Hz)", address, publisher.status.run_id,
                 publisher.tick_count, publisher.rate_hz)
    else:
        log.info("host listening on %s (run %s, %g simulated s paced by the rig, at most %.1f Hz)", address,
                 publisher.status.run_id, publisher.duration_s, publisher.rate_hz)
    runner = threading.Thread(target=publisher.run, args=(stop,), name="publisher", daemon=True)
    runner.start()
    while runner.is_alive() and not stop.wait(0.2):
        pass
    runner.join()
    if stop.is_set():
        if not publisher.wait_streams_ended(_STOP_DRAIN_S):
            log.warning("stopping with %d stream(s) still open after %.0f s: their subscribers get no final "
                        "counters", len(publisher.snapshot().subscribers), _STOP_DRAIN_S)
    else:
        stop.wait(linger_s)
    set_not_serving(health, [SERVICE])
    server.stop(grace=1.0).wait()
    s = publisher.snapshot()
    log.info("host done: %d frames published, %d eyepoints rejected, ack timeouts %s",
             s.frames_published, s.eyepoints_rejected, s.ack_timeouts)
