"""The metrics endpoint every process serves: its registry over HTTP on a free port, 127.0.0.1
unless told otherwise, the families built from a process's counters, and the command line."""

import argparse
import socket
import urllib.request

import pytest
from prometheus_client import CollectorRegistry, Histogram

from services.rig.cli_common import add_metrics_arguments, metrics_address_of
from services.rig.metrics import (
    DEFAULT_BIND,
    MetricsEndpoint,
    counter,
    gauge,
    labelled_counter,
    labelled_gauge,
    metrics_address,
    sample_values,
    scrape,
    serve_metrics,
)


class Counts:
    """A process's own counters, read at scrape time."""

    def __init__(self):
        self.frames = 0
        self.refused = {}

    def collect(self):
        yield counter("test_frames", "Frames.", self.frames)
        yield labelled_counter("test_refused", "Refused, by cause.", ["cause"], self.refused)
        yield gauge("test_open", "Open.", 2)
        yield labelled_gauge("test_pair", "Two labels.", ["a", "b"], {("x", "y"): 1})


def test_the_endpoint_serves_the_counters_as_they_are_at_each_scrape():
    registry = CollectorRegistry()
    counts = Counts()
    registry.register(counts)
    with serve_metrics(registry, "127.0.0.1:0") as endpoint:
        address = f"127.0.0.1:{endpoint.port}"
        first = scrape(address)
        assert sample_values(first["ig_test_frames"], "_total") == {(): 0}
        assert sample_values(first["ig_test_refused"], "_total") == {}
        counts.frames = 7
        counts.refused = {"unknown_channel": 2, "other_run": 1}
        again = scrape(address)
        assert first["ig_test_frames"].type == "counter" and first["ig_test_open"].type == "gauge"
        assert sample_values(again["ig_test_frames"], "_total") == {(): 7}
        assert sample_values(again["ig_test_refused"], "_total") == {(("cause", "other_run"),): 1,
                                                                      (("cause", "unknown_channel"),): 2}
        assert sample_values(again["ig_test_pair"]) == {(("a", "x"), ("b", "y")): 1}
    with pytest.raises(OSError):
        scrape(address, timeout_s=1.0)  # closed: the port is free again


def test_each_registry_is_its_own():
    a, b = CollectorRegistry(), CollectorRegistry()
    Histogram("ig_x_seconds", "x", registry=a).observe(0.1)
    Histogram("ig_x_seconds", "x", registry=b)  # the same name in another registry: no clash
    with MetricsEndpoint(a, "127.0.0.1:0") as ea, MetricsEndpoint(b, "127.0.0.1:0") as eb:
        assert sample_values(scrape(f"127.0.0.1:{ea.port}")["ig_x_seconds"], "_count") == {(): 1}
        assert sample_values(scrape(f"127.0.0.1:{eb.port}")["ig_x_seconds"], "_count") == {(): 0}


def test_a_taken_port_is_an_os_error_naming_the_address():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(OSError, match=rf"metrics: cannot listen on 127.0.0.1:{port}"):
            serve_metrics(CollectorRegistry(), f"127.0.0.1:{port}")


def test_no_address_no_endpoint():
    assert serve_metrics(CollectorRegistry(), None) is None


def test_the_endpoint_listens_on_the_loopback_unless_told_otherwise():
    assert DEFAULT_BIND == "127.0.0.1"
    assert metrics_address(9150, None) == "127.0.0.1:9150"
    assert metrics_address(9150, "0.0.0.0") == "0.0.0.0:9150"
    assert metrics_address(9150, "::1") == "[::1]:9150"
    assert metrics_address(0, "0.0.0.0") is None and metrics_address(None, None) is None


def parse(*argv):
    parser = argparse.ArgumentParser()
    add_metrics_arguments(parser, rig_key="[host] metrics_port")
    return parser.parse_args(argv)


def test_the_flag_overrides_the_rig_file_and_0_turns_the_metrics_off():
    assert metrics_address_of(parse(), 0) is None
    assert metrics_address_of(parse(), 50250) == "127.0.0.1:50250"
    assert metrics_address_of(parse("--metrics-port", "9000"), 50250) == "127.0.0.1:9000"
    assert metrics_address_of(parse("--metrics-port", "0"), 50250) is None
    assert metrics_address_of(parse("--metrics-bind", "0.0.0.0"), 50250) == "0.0.0.0:50250"


@pytest.mark.parametrize("bad", ["-1", "65536", "http", "1.5"])
def test_a_bad_metrics_port_is_refused(bad, capsys):
    with pytest.raises(SystemExit):
        parse("--metrics-port", bad)
    assert f"{bad!r} is not a port in [1, 65535], or 0 for none" in capsys.readouterr().err


def test_the_endpoint_answers_plain_http_get():
    registry = CollectorRegistry()
    registry.register(Counts())
    endpoint = MetricsEndpoint(registry, "127.0.0.1:0")
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{endpoint.port}/metrics", timeout=5) as response:
            assert response.status == 200
            assert response.headers["Content-Type"].startswith("text/plain")
            body = response.read().decode()
    finally:
        endpoint.close()
    assert "# TYPE ig_test_frames_total counter" in body
    assert "ig_test_frames_total 0.0" in body
