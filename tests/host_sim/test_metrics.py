"""The host's /metrics over HTTP: the same numbers as its GetHostStatus, the CIGI session's
counters, and an endpoint that lives as long as serve()."""

import math
import socket
import threading
import time

import pytest

from host_sim.cigi.endpoint import CigiEndpoint, QueryClient
from host_sim.cigi.scripted_host import Keyframe, Query, Script, ScriptedHost
from host_sim.cigi.session import CigiSession
from host_sim.metrics import host_registry
from host_sim.publisher import FrameOutOfRange, FramePublisher, UnknownChannel
from host_sim.server import HostServicer, serve
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.metrics import sample_values, scrape, serve_metrics


def scraped(servicer):
    """/metrics of the servicer's host, fetched over HTTP from an endpoint on a free port."""
    with serve_metrics(host_registry(servicer.status), "127.0.0.1:0") as endpoint:
        return scrape(f"127.0.0.1:{endpoint.port}")


def by_label(family, label, suffix="_total"):
    return {dict(labels)[label]: v for labels, v in sample_values(family, suffix).items()}


def test_the_host_counters_are_its_status():
    def source(t):  # the third tick's eyepoint is not finite: refused, nothing published
        return Eyepoint.of(math.nan if round(t * 100) == 2 else t, 0.0, 10.0, 0.0, 0.0, 0.0)

    pub = FramePublisher(source=source, channels=["left", "right"], rate_hz=100.0, duration_s=0.04,
                         sync_timeout_s=0.1, start_timeout_s=5.0)
    left, right = pub.subscribe("worker-left", "left"), pub.subscribe("worker-right", "right")
    with pytest.raises(UnknownChannel):
        pub.subscribe("rogue", "middle")

    def acknowledge():  # left acknowledges every frame, the second as failed; right never does
        while (frame := left.get(0.05)) is not None or not left.closed:
            if frame is not None:
                pub.ack("left", frame.frame_number, ok=frame.frame_number != 1, error="boom")

    acker = threading.Thread(target=acknowledge)
    acker.start()
    pub.run(threading.Event())
    acker.join()
    with pytest.raises(FrameOutOfRange):
        pub.ack("right", 99)
    servicer = HostServicer(pub)
    status = servicer.status()
    m = scraped(servicer)

    assert status.frames_published == 4 and status.eyepoints_rejected == 1
    assert sample_values(m["ig_host_frames_published"], "_total") == {(): 4}
    assert sample_values(m["ig_host_eyepoints_rejected"], "_total") == {(): 1}
    assert sample_values(m["ig_host_subscriptions_rejected"], "_total") == {(): 1}
    assert by_label(m["ig_host_ack_timeouts"], "channel") == dict(status.ack_timeouts) == {"left": 0, "right": 4}
    assert by_label(m["ig_host_ack_failures"], "channel") == dict(status.ack_failures) == {"left": 1, "right": 0}
    assert by_label(m["ig_host_late_acks"], "channel") == dict(status.late_acks)
    assert by_label(m["ig_host_channel_absent"], "channel") == dict(status.channel_absent)
    assert by_label(m["ig_host_requests_refused"], "cause") == dict(status.requests_refused) == {"out_of_range": 1}
    assert by_label(m["ig_host_queue_drops"], "subscriber") == dict(status.queue_drops)
    assert sample_values(m["ig_host_runs"], "_total") == {(): 1}
    assert sample_values(m["ig_host_run_finished"]) == {(): 1}
    assert sample_values(m["ig_host_subscribers"]) == {(): len(status.subscribers)}
    assert sample_values(m["ig_host_run_info"]) == {(("eyepoint_source", "bundled"), ("run_id", pub.status.run_id)): 1}
    assert "ig_cigi_messages" not in m and "ig_host_input_accepted" not in m
    right.close()


ORIGIN = (36.6089, -84.1708, 349.2)


def free_port(kind=socket.SOCK_STREAM):
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_cigi_session_counters_are_its_status():
    session = CigiSession(origin=ORIGIN, channels={0: ChannelSpec.symmetric("centre", 64, 48, 60.0)})
    # Nothing answers queries on port 1: every one is answered invalid and counted failed.
    client = QueryClient("127.0.0.1:1", origin=ORIGIN, timeout_s=0.2)
    host_port = free_port(socket.SOCK_DGRAM)
    ep = CigiEndpoint(session, ("127.0.0.1", 0), host_port=host_port, queries=client)
    lat, lon, h = ORIGIN
    script = Script(path=(Keyframe(0.0, lat, lon, h + 300.0), Keyframe(10.0, lat + 0.01, lon, h + 300.0)),
                    queries=(Query(host_frame=2, kind="hot", every=3),), frame_rate_hz=60.0)
    try:
        with ScriptedHost(script, ig_address=ep.listen, bind=("127.0.0.1", host_port), origin=ORIGIN) as host:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rogue:
                rogue.sendto(b"\x01", ep.listen)  # one byte: no CIGI message, refused
            player = threading.Thread(target=host.run, kwargs={"frames": 10, "sof_timeout_s": 3.0})
            player.start()
            while player.is_alive():
                ep.frame_input(0.0)
                player.join(0.01)
        pub = FramePublisher(source=ep.frame_input, channels=["centre"])
        servicer = HostServicer(pub, eyepoints=ep)
        status = ep.session.status()
        m = scraped(servicer)
    finally:
        ep.close()
    assert status["messages"] >= 10 and status["queries_failed"] > 0 and status["refused"]
    assert sample_values(m["ig_cigi_messages"], "_total") == {(): status["messages"]}
    assert by_label(m["ig_cigi_messages_refused"], "cause") == status["refused"]
    assert by_label(m["ig_cigi_packets"], "packet") == status["packets"]
    assert by_label(m["ig_cigi_packets_unused"], "packet") == status["unused"]
    assert sample_values(m["ig_cigi_ig_frames"], "_total") == {(): status["ig_frames"]}
    for key in ("queries_answered", "queries_invalid", "queries_failed", "restarts", "stale_events",
                "messages_dropped", "responses_deferred", "responses_dropped"):
        assert sample_values(m[f"ig_cigi_{key}"], "_total") == {(): status[key]}, key
    assert sample_values(m["ig_cigi_host_stale"]) == {(): int(status["stale"])}
    assert sample_values(m["ig_cigi_entities"]) == {(): status["entities"]}
    assert dict(next(iter(sample_values(m["ig_host_run_info"])))) ["eyepoint_source"] == "cigi"


def test_serve_serves_the_metrics_while_it_runs_and_frees_the_port():
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0.0, 10.0, 0.0, 0.0, 0.0), channels=["left"],
                         rate_hz=50.0, duration_s=1e6, start_timeout_s=0.0)
    stop = threading.Event()
    metrics = f"127.0.0.1:{free_port()}"
    runner = threading.Thread(target=serve, args=(pub, f"127.0.0.1:{free_port()}", stop),
                              kwargs={"metrics_address": metrics})
    runner.start()
    try:
        deadline = time.monotonic() + 10.0
        while True:
            try:
                published = sample_values(scrape(metrics)["ig_host_frames_published"], "_total")[()]
            except OSError:
                published = 0
            if published >= 3 or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        assert published >= 3
    finally:
        stop.set()
        runner.join()
    with pytest.raises(OSError):
        scrape(metrics, timeout_s=1.0)


def test_a_taken_metrics_port_fails_serve_before_it_runs():
    pub = FramePublisher(source=lambda t: Eyepoint.of(t, 0.0, 10.0, 0.0, 0.0, 0.0), channels=["left"])
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        address = f"127.0.0.1:{free_port()}"
        with pytest.raises(OSError, match="metrics: cannot listen"):
            serve(pub, address, threading.Event(), metrics_address=f"127.0.0.1:{taken.getsockname()[1]}")
    assert pub.snapshot().frames_published == 0
    with socket.socket() as again:  # the gRPC port was given back
        again.bind(("127.0.0.1", int(address.rpartition(":")[2])))
