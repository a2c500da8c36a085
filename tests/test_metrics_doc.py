"""docs/metrics.md names every metric the host, the workers and the compositor serve, with its
type, and nothing they do not serve."""

import re
from collections import Counter
from pathlib import Path

from prometheus_client import CollectorRegistry

from channel_worker.metrics import WorkerMetrics
from host_sim.metrics import HostCollector
from ig.v1 import host_pb2, worker_pb2
from services.compositor.metrics import CompositorMetrics
from services.compositor.timing import HOPS
from services.rig.report import FrameReport

DOC = Path(__file__).resolve().parents[1] / "docs" / "metrics.md"


def served() -> dict[str, str]:
    """Every metric's name as Prometheus shows it (counters with _total) and its type."""
    host = CollectorRegistry()
    host.register(HostCollector(lambda: host_pb2.GetHostStatusResponse(
        inputs=[host_pb2.InputSourceStatus(name="can://virtual/rig", rejected={"bad_crc": 1})],
        cigi=host_pb2.CigiStatus())))
    worker = WorkerMetrics("centre", lambda: worker_pb2.GetWorkerStatusResponse(channel_name="centre"))
    worker.observe(FrameReport(stage_seconds={"view": 0.001}, part_seconds={"background.cast": 0.001}), 0.002)
    compositor = CompositorMetrics(Counter, lambda: {"run_id": "r", "frames_pending": 0, "pending_bytes": 0},
                                   tuple(key for key, _ in HOPS))
    # A compositor with a live view (docs/live-view.md) serves its counts too.
    compositor.add_view(lambda: {"frames_encoded": 0, "composites_skipped": 0, "frames_dropped": 0, "clients": 0})
    names = {}
    for registry in (host, worker.registry, compositor.registry):
        for family in registry.collect():
            names[family.name + ("_total" if family.type == "counter" else "")] = family.type
    return names


def documented() -> dict[str, str]:
    rows = re.findall(r"^\| `(ig_\w+)` \| (\w+) \|", DOC.read_text(), re.M)
    assert len(rows) == len(set(rows)), "a metric documented twice"
    return dict(rows)


def test_every_metric_served_is_documented_with_its_type_and_no_other():
    assert documented() == served()


def test_every_name_has_the_prefix_and_its_unit():
    for name, kind in served().items():
        assert name.startswith("ig_"), name
        assert name.endswith("_total") == (kind == "counter"), name
        assert kind != "histogram" or name.endswith("_seconds"), name
