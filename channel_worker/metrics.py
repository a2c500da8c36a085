"""A worker's Prometheus metrics (docs/metrics.md): its counters (GetWorkerStatus) read at
scrape time, and every frame's stage times (its FrameReport) observed into histograms.

The worker counts in WorkerCounters and measures each frame's stages in a FrameReport
(worker.py); the collector reads the GetWorkerStatusResponse built from them, so /metrics and
GetWorkerStatus say the same. The histograms are the only thing kept here: a FrameReport
describes one frame, and a histogram is the sum of them all.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from prometheus_client import CollectorRegistry, Histogram
from prometheus_client.core import Metric

from ig.v1 import worker_pb2
from services.rig.metrics import FRAME_BUCKETS, PREFIX, STAGE_BUCKETS, labelled_counter, labelled_gauge
from services.rig.report import FrameReport

#: GetWorkerStatusResponse's counters: (field, metric name without prefix and _total, help).
COUNTERS = (
    ("frames_handled", "worker_frames_handled", "Frames taken from the host's stream."),
    ("frames_rendered", "worker_frames_rendered", "Frames rendered and submitted to the compositor."),
    ("frames_skipped", "worker_frames_skipped", "Frames replaced in the mailbox before they were rendered."),
    ("frames_refused", "worker_frames_refused", "Frames refused (a bad eyepoint, environment or view)."),
    ("submit_failures", "worker_submit_failures", "Images the compositor did not take."),
    ("ack_failures", "worker_ack_failures", "Acknowledgements the host did not take."),
    ("translucent_dropped", "worker_translucent_dropped",
     "Translucent features dropped: a sample held more than max_translucent."),
    ("terrain_voxels_total", "worker_terrain_voxels", "Terrain voxels drawn, summed over the frames."),
    ("terrain_eye_clamped", "worker_terrain_eye_clamped", "Frames whose eye was below the terrain."),
    ("runs", "worker_runs", "Runs of the host the worker has rendered frames of."),
    ("malformed_requests", "worker_malformed_requests", "Requests to the worker's own server refused."),
    ("resubscriptions", "worker_resubscriptions", "Times the worker subscribed to the host again."),
)

#: Gauges of the same message: (field, metric name without prefix, help).
GAUGES = (
    ("subscribed", "worker_subscribed", "1 while the worker has an open subscription to the host."),
    ("ready", "worker_ready", "1 once the kernels are compiled and the warm-up frame rendered (health SERVING)."),
    ("last_frame_number", "worker_last_frame_number", "Number of the last frame taken."),
    ("terrain_voxels_last_frame", "worker_terrain_voxels_last_frame", "Terrain voxels drawn in the last frame."),
)


class WorkerCollector:
    """The worker's counters and gauges, from status() (ChannelWorker.status) at every scrape."""

    def __init__(self, status: Callable[[], worker_pb2.GetWorkerStatusResponse]) -> None:
        self.status = status

    def collect(self) -> Iterator[Metric]:
        s = self.status()
        channel = s.channel_name
        for field, name, documentation in COUNTERS:
            yield labelled_counter(name, documentation, ["channel"], {channel: getattr(s, field)})
        for field, name, documentation in GAUGES:
            yield labelled_gauge(name, documentation, ["channel"], {channel: int(getattr(s, field))})


class WorkerMetrics:
    """One worker's registry: its collector and its frames' time histograms.

    Args:
        channel: the channel the worker renders (every sample's channel label).
        status: the worker's status message (ChannelWorker.status).
    """

    def __init__(self, channel: str, status: Callable[[], worker_pb2.GetWorkerStatusResponse]) -> None:
        self.channel = channel
        self.registry = CollectorRegistry()
        self.registry.register(WorkerCollector(status))
        self.render_seconds = Histogram(
            PREFIX + "worker_render_seconds", "Wall-clock seconds of a frame's render (render_frame, every stage).",
            ["channel"], registry=self.registry, buckets=FRAME_BUCKETS)
        self.stage_seconds = Histogram(
            PREFIX + "worker_stage_seconds", "Wall-clock seconds of one pipeline stage of a frame (FrameReport).",
            ["channel", "stage"], registry=self.registry, buckets=STAGE_BUCKETS)
        self.part_seconds = Histogram(
            PREFIX + "worker_stage_part_seconds", "Wall-clock seconds of a part of a stage (FrameReport's "
                                                  "stage.part, inside the stage's time).",
            ["channel", "part"], registry=self.registry, buckets=STAGE_BUCKETS)

    def observe(self, report: FrameReport, render_s: float) -> None:
        """Account for one rendered frame: its FrameReport and the render's seconds."""
        self.render_seconds.labels(self.channel).observe(render_s)
        for stage, seconds in report.stage_seconds.items():
            self.stage_seconds.labels(self.channel, stage).observe(seconds)
        for part, seconds in report.part_seconds.items():
            self.part_seconds.labels(self.channel, part).observe(seconds)
