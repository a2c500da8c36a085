"""The host's Prometheus metrics: its status (GetHostStatus) read at scrape time (docs/metrics.md).

The host counts in HostStatus (publisher.py), its control sources and the CIGI session in
theirs; GetHostStatusResponse gathers them, and that one message is what this collector reads,
so /metrics and `ig status` say the same. Counters are process-lifetime: a CIGI host that starts
a new run keeps counting on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from prometheus_client import CollectorRegistry
from prometheus_client.core import Metric

from ig.v1 import host_pb2
from services.rig.metrics import counter, gauge, labelled_counter, labelled_gauge


class HostCollector:
    """Metrics of one host, from status() (HostServicer.status) at every scrape."""

    def __init__(self, status: Callable[[], host_pb2.GetHostStatusResponse]) -> None:
        self.status = status

    def collect(self) -> Iterator[Metric]:
        s = self.status()
        yield counter("host_frames_published", "Frames the host published.", s.frames_published)
        yield counter("host_runs", "Runs the host started (a CIGI host restarting its frame counter starts one).",
                      s.runs)
        yield labelled_gauge("host_run_info", "The current run (value 1) and where its eyepoints come from.",
                             ["run_id", "eyepoint_source"], {(s.run_id, s.eyepoint_source): 1})
        yield gauge("host_run_finished", "1 once the run has published its last frame.", int(s.finished))
        yield gauge("host_subscribers", "Open frame subscriptions (workers and observers).", len(s.subscribers))
        yield counter("host_eyepoints_rejected", "Eyepoints refused (a field not finite); nothing was published.",
                      s.eyepoints_rejected)
        yield counter("host_subscriptions_rejected",
                      "Subscriptions refused: a channel not in the rig, or one that already has a subscriber.",
                      s.subscriptions_rejected)
        yield labelled_counter("host_requests_refused", "Requests refused, by cause.", ["cause"],
                               dict(s.requests_refused))
        yield labelled_counter("host_ack_timeouts",
                               "Frames a channel did not acknowledge within the swap barrier's timeout.",
                               ["channel"], dict(s.ack_timeouts))
        yield labelled_counter("host_ack_failures", "Frames a channel acknowledged as failed.", ["channel"],
                               dict(s.ack_failures))
        yield labelled_counter("host_late_acks",
                               "Acknowledgements that came after the barrier had gone on without them.",
                               ["channel"], dict(s.late_acks))
        yield labelled_counter("host_channel_absent",
                               "Frames published while a channel had no open subscription (its worker down).",
                               ["channel"], dict(s.channel_absent))
        yield labelled_counter("host_queue_drops",
                               "Frames dropped from a subscriber's queue because it fell behind.",
                               ["subscriber"], dict(s.queue_drops))
        yield from _inputs(s.inputs)
        if s.HasField("cigi"):
            yield from _cigi(s.cigi)


def _inputs(inputs) -> Iterator[Metric]:
    """The control sources (--controls) or another simulator's pose stream (--simhost)."""
    if not inputs:
        return
    yield labelled_counter("host_input_accepted", "Control values (or poses) a source accepted.", ["input"],
                           {i.name: i.accepted for i in inputs})
    yield labelled_counter("host_input_rejected", "Inputs a source refused, by cause.", ["input", "cause"],
                           {(i.name, cause): n for i in inputs for cause, n in i.rejected.items()})
    yield labelled_gauge("host_input_stale", "1 while a source has had no good input for its stale timeout.",
                         ["input"], {i.name: int(i.stale) for i in inputs})


def _cigi(c: host_pb2.CigiStatus) -> Iterator[Metric]:
    """The CIGI session's counters (docs/cigi.md)."""
    yield counter("cigi_messages", "CIGI messages (datagrams) received and used.", c.messages)
    yield labelled_counter("cigi_messages_refused", "CIGI messages refused, by cause; a refused message changes "
                                                    "nothing.", ["cause"], dict(c.refused))
    yield counter("cigi_messages_dropped", "Host messages dropped unused: more than one waited for a synchronous "
                                           "frame.", c.messages_dropped)
    yield labelled_counter("cigi_packets", "CIGI packets used, by packet.", ["packet"], dict(c.packets))
    yield labelled_counter("cigi_packets_unused", "CIGI packets accepted but not used by this IG, by packet.",
                           ["packet"], dict(c.unused))
    yield counter("cigi_packets_skipped", "Packets of ids the host's CIGI version does not define, skipped.",
                  c.skipped)
    yield counter("cigi_ig_frames", "IG frames started (Start of Frame sent).", c.ig_frames)
    yield gauge("cigi_host_stale", "1 while the CIGI host has been silent for cigi.stale_after_s.", int(c.stale))
    yield counter("cigi_stale_events", "Times the CIGI host went stale.", c.stale_events)
    yield counter("cigi_restarts", "Times the CIGI host restarted its frame counter.", c.restarts)
    yield gauge("cigi_entities", "Entities the CIGI host controls (the ownship included).", c.entities)
    yield gauge("cigi_last_host_frame", "Host frame number of the last CIGI message used.", c.last_host_frame)
    # Nested, not side by side: every answer is counted answered, an invalid one invalid too,
    # and one the query service did not give failed as well.
    yield counter("cigi_queries_answered", "Height-of-terrain and line-of-sight requests answered (valid or "
                                           "not).", c.queries_answered)
    yield counter("cigi_queries_invalid", "Requests answered invalid (of those answered).", c.queries_invalid)
    yield counter("cigi_queries_failed", "Requests the query service did not answer (answered invalid).",
                  c.queries_failed)
    yield gauge("cigi_periodic_requests", "Periodic requests active.", c.periodic_requests)
    yield counter("cigi_responses_deferred", "Responses held for the next frame: one datagram could not take "
                                             "them all.", c.responses_deferred)
    yield counter("cigi_responses_dropped", "Responses dropped, the oldest first, because too many waited.",
                  c.responses_dropped)


def host_registry(status: Callable[[], host_pb2.GetHostStatusResponse]) -> CollectorRegistry:
    """A registry of its own with the host's metrics, read from status() at every scrape."""
    registry = CollectorRegistry()
    registry.register(HostCollector(status))
    return registry
