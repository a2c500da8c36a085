"""What every process's Prometheus metrics share: the HTTP endpoint, the names' prefix, the
histogram buckets and the families built from a process's own counters (docs/metrics.md).

Each process keeps counting the way it always has (the host's HostStatus, the worker's
WorkerCounters and FrameReport, the compositor's gatherers, the CIGI session's Counters); its
collector reads those counters when Prometheus scrapes, so /metrics, GetHostStatus,
GetWorkerStatus and report.json never disagree. Histograms are observed where the time is
measured (a worker's stage times, the compositor's latency chain). Every process object has a
CollectorRegistry of its own, not prometheus_client's global one, so that several can live in
one process (the tests; `ig demo` runs them apart anyway).

The endpoint is plain HTTP with no authentication and serves nothing but the counters; it
listens on 127.0.0.1 unless told otherwise (`--metrics-bind`; docs/security.md).
"""

from __future__ import annotations

import logging
import urllib.request
from collections.abc import Iterable, Mapping
from typing import Any

from prometheus_client import CollectorRegistry, start_http_server
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.parser import text_string_to_metric_families

log = logging.getLogger("ig")

#: Every metric's name starts with it.
PREFIX = "ig_"

#: Where a metrics endpoint listens unless told otherwise: the services' bind rule, this
#: machine only.
DEFAULT_BIND = "127.0.0.1"

#: Buckets of a pipeline stage's time, seconds: a stage of a small channel takes well under a
#: millisecond, the background of a 1280 x 1024 channel on two cores most of a second.
STAGE_BUCKETS = (0.0002, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)

#: Buckets of a frame's time (a whole render, control-to-composite latency, its hops), seconds:
#: from a 60 Hz rig's frame (16.7 ms) to the seconds of a two-core machine's demo, with the
#: FAA's transport-delay limits (100, 150 ms; docs/latency.md) as bounds.
FRAME_BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.0167, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0,
                 2.0, 5.0, 10.0)


def counter(name: str, documentation: str, value: float) -> CounterMetricFamily:
    """A counter without labels; name without the prefix and without _total (both added)."""
    return CounterMetricFamily(PREFIX + name, documentation, value=value)


def gauge(name: str, documentation: str, value: float) -> GaugeMetricFamily:
    """A gauge without labels; name without the prefix."""
    return GaugeMetricFamily(PREFIX + name, documentation, value=value)


def labelled_counter(name: str, documentation: str, labels: Iterable[str],
                     values: Mapping[Any, float]) -> CounterMetricFamily:
    """A counter with one sample per key of values: a key is the label value (one label) or a
    tuple of them (several)."""
    labels = list(labels)
    family = CounterMetricFamily(PREFIX + name, documentation, labels=labels)
    for key, value in sorted(values.items()):
        family.add_metric(_label_values(key, len(labels)), value)
    return family


def labelled_gauge(name: str, documentation: str, labels: Iterable[str],
                   values: Mapping[Any, float]) -> GaugeMetricFamily:
    """A gauge with one sample per key of values (as labelled_counter)."""
    labels = list(labels)
    family = GaugeMetricFamily(PREFIX + name, documentation, labels=labels)
    for key, value in sorted(values.items()):
        family.add_metric(_label_values(key, len(labels)), value)
    return family


def _label_values(key: Any, count: int) -> list[str]:
    values = [str(v) for v in key] if isinstance(key, tuple) else [str(key)]
    if len(values) != count:
        raise ValueError(f"label values {values} for {count} label(s)")
    return values


def metrics_address(port: int | None, bind: str | None) -> str | None:
    """host:port a process's metrics endpoint listens on: port (None or 0: no endpoint) on bind
    (None: DEFAULT_BIND, this machine only)."""
    if not port:
        return None
    host = bind or DEFAULT_BIND
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


class MetricsEndpoint:
    """/metrics of one registry over HTTP, served on a daemon thread until close().

    Args:
        registry: what is served.
        address: host:port to listen on; port 0 takes a free port (tests), see port.

    Raises:
        OSError: the address cannot be bound (in use, not this machine's).
    """

    def __init__(self, registry: CollectorRegistry, address: str) -> None:
        host, _, port = address.rpartition(":")
        self._server, self._thread = start_http_server(int(port), addr=host.strip("[]"), registry=registry)
        #: The bound port (the one asked for, or the free one port 0 took).
        self.port: int = self._server.server_port
        self.address = f"{host}:{self.port}"
        log.info("metrics on http://%s/metrics", self.address)

    def close(self) -> None:
        """Stop serving and release the port."""
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5.0)

    def __enter__(self) -> MetricsEndpoint:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def serve_metrics(registry: CollectorRegistry, address: str | None) -> MetricsEndpoint | None:
    """A MetricsEndpoint of registry on address; None when address is None (metrics off).

    Raises:
        OSError: the address cannot be bound; the message names it.
    """
    if address is None:
        return None
    try:
        return MetricsEndpoint(registry, address)
    except OSError as exc:
        raise OSError(f"metrics: cannot listen on {address}: {exc.strerror or exc}") from exc


def scrape(address: str, *, timeout_s: float = 5.0) -> dict[str, Metric]:
    """What Prometheus reads at http://address/metrics, parsed: families by name (a counter's
    name without _total, its samples with it).

    Raises:
        OSError: nothing answers at address.
    """
    with urllib.request.urlopen(f"http://{address}/metrics", timeout=timeout_s) as response:
        text = response.read().decode()
    return {family.name: family for family in text_string_to_metric_families(text)}


def sample_values(family: Metric, suffix: str = "") -> dict[tuple[tuple[str, str], ...], float]:
    """A family's samples named family.name + suffix ("_total", "_count", ...), by their sorted
    labels."""
    return {tuple(sorted(s.labels.items())): s.value for s in family.samples if s.name == family.name + suffix}
