"""The compositor's Prometheus metrics (docs/metrics.md): its gatherers' counters read at scrape
time, summed over the runs it has followed, and the latency of every composite observed into
histograms where it is measured (timing.TimingStats.add).

The compositor counts per run, in each run's FrameGatherer (frames complete, incomplete by cause,
images late, submissions refused by cause, what came over the wire), its stitcher and its
recorder; report.json shows them run by run. A Prometheus counter must only grow, so the
compositor folds a run's counts into its totals once the run is over and no longer current
(Compositor.counts), and /metrics shows those totals plus the runs still live: the same numbers
as the reports, added up, never counted a second time.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from prometheus_client import CollectorRegistry, Histogram
from prometheus_client.core import Metric

from services.rig.metrics import FRAME_BUCKETS, PREFIX, counter, gauge, labelled_counter, labelled_gauge

#: A count's key: (what, its label values); Compositor.counts sums them over the runs.
CountKey = tuple[str, tuple[str, ...]]

#: The counters: (key of run_counts, metric name without prefix and _total, label names, help).
COUNTERS: tuple[tuple[str, str, tuple[str, ...], str], ...] = (
    ("frames_published", "compositor_frames_published", (), "Frames the host published, seen on its stream."),
    ("frames_complete", "compositor_frames_complete", (),
     "Frames complete: every channel's image, each of the published eyepoint, bitwise."),
    ("frames_incomplete", "compositor_frames_incomplete", ("cause",), "Frames not stitched, by cause."),
    ("frames_evicted", "compositor_frames_evicted", (),
     "Frames finalised incomplete early because the open frames exceeded their bounds."),
    ("images_missing", "compositor_images_missing", ("channel",),
     "Images a channel never delivered for a frame finalised incomplete."),
    ("images_late", "compositor_images_late", ("channel",), "Images that came after their frame was decided."),
    ("submissions_rejected", "compositor_submissions_rejected", ("cause",), "Submissions refused, by cause."),
    ("images", "compositor_images", ("channel", "wire"), "Images taken, by channel and wire format."),
    ("images_shared_memory", "compositor_images_shared_memory", ("channel",),
     "Images taken out of the worker's shared memory (the rest came inline)."),
    ("composites", "compositor_composites", ("format",), "Frames stitched, by the composite's format."),
    ("stitch_errors", "compositor_stitch_errors", (), "Complete frames that could not be stitched."),
    ("frames_written", "compositor_frames_written", (), "Composites written to disk (PNG or EXR)."),
    ("frames_not_recorded", "compositor_frames_not_recorded", (),
     "Composites due for recording left out because the writer was behind."),
    ("write_errors", "compositor_write_errors", (), "Composites whose files could not be written."),
)


def run_counts(gathered: Mapping[str, Any], *, stitch_errors: int, composites: Mapping[str, int],
               written: int, not_recorded: int, write_errors: int) -> Counter[CountKey]:
    """One run's counts, keyed for COUNTERS: the gatherer's (FrameGatherer.counters()), the
    stitcher's and the recorder's."""
    out: Counter[CountKey] = Counter()
    for key in ("frames_published", "frames_complete", "frames_evicted"):
        out[key, ()] = gathered[key]
    for key, by in (("frames_incomplete", "frames_incomplete"), ("images_missing", "missing_by_channel"),
                    ("images_late", "late_by_channel"), ("submissions_rejected", "rejected_submissions"),
                    ("images_shared_memory", "shared_memory_by_channel")):
        for label, n in gathered[by].items():
            out[key, (label,)] = n
    for channel, wires in gathered["images_by_channel"].items():
        for wire, n in wires.items():
            out["images", (channel, wire)] = n
    for fmt, n in composites.items():
        out["composites", (fmt,)] = n
    out["stitch_errors", ()] = stitch_errors
    out["frames_written", ()] = written
    out["frames_not_recorded", ()] = not_recorded
    out["write_errors", ()] = write_errors
    return out


class CompositorCollector:
    """The compositor's counters over its life (counts()) and the current run's state
    (current()) at every scrape.

    Args:
        counts: Compositor.counts: every run's counts, summed.
        current: Compositor.current: the current run's id, and its open frames and their bytes.
    """

    def __init__(self, counts: Callable[[], Counter[CountKey]], current: Callable[[], Mapping[str, Any]]) -> None:
        self.counts = counts
        self.current = current

    def collect(self) -> Iterator[Metric]:
        counts = self.counts()
        for key, name, labels, documentation in COUNTERS:
            if not labels:
                yield counter(name, documentation, counts.get((key, ()), 0))
            else:
                yield labelled_counter(name, documentation, labels,
                                       {values: n for (k, values), n in counts.items() if k == key})
        now = self.current()
        yield labelled_gauge("compositor_run_info", "The run the compositor follows now (value 1).", ["run_id"],
                             {now["run_id"]: 1})
        yield gauge("compositor_frames_pending", "Frames open now: seen, not decided yet.", now["frames_pending"])
        yield gauge("compositor_pending_bytes", "Bytes of pixels the open frames hold.", now["pending_bytes"])


class CompositorMetrics:
    """The compositor's registry: its collector and its composites' latency histograms.

    Args:
        counts: as CompositorCollector.
        current: as CompositorCollector.
        hops: the latency chain's hops, in order (timing.HOPS' keys).
    """

    def __init__(self, counts: Callable[[], Counter[CountKey]], current: Callable[[], Mapping[str, Any]],
                 hops: tuple[str, ...]) -> None:
        self.registry = CollectorRegistry()
        self.registry.register(CompositorCollector(counts, current))
        self.latency_seconds = Histogram(
            PREFIX + "compositor_control_to_composite_seconds",
            "Seconds from the host's control sample of a frame to its composite stitched (docs/latency.md).",
            registry=self.registry, buckets=FRAME_BUCKETS)
        self.hop_seconds = Histogram(
            PREFIX + "compositor_latency_hop_seconds",
            "Seconds of one hop of a composite's latency chain, along the channel it waited for "
            "(docs/latency.md); the hops add up to control_to_composite.",
            ["hop"], registry=self.registry, buckets=FRAME_BUCKETS)
        self.interval_seconds = Histogram(
            PREFIX + "compositor_composite_interval_seconds", "Seconds between one composite and the next of a run.",
            registry=self.registry, buckets=FRAME_BUCKETS)
        self.hops = hops

    def add_view(self, counts: Callable[[], Mapping[str, int]]) -> None:
        """Serve the live view's counts too (liveview.frames.FrameSource.counts), read at every
        scrape; only a compositor with a view has these series."""
        self.registry.register(ViewCollector(counts))

    def observe(self, latency_s: float, hops: Mapping[str, float] | None, interval_s: float | None) -> None:
        """Account for one composite: its latency, its chain's hops (None: a worker that does
        not stamp them) and the interval since the run's composite before it (None: the first)."""
        self.latency_seconds.observe(latency_s)
        if hops is not None:
            for key in self.hops:
                self.hop_seconds.labels(key).observe(hops[key])
        if interval_s is not None:
            self.interval_seconds.observe(interval_s)


class ViewCollector:
    """The live view's counts (docs/live-view.md) at every scrape.

    Args:
        counts: FrameSource.counts: frames_encoded, composites_skipped, frames_dropped, clients.
    """

    def __init__(self, counts: Callable[[], Mapping[str, int]]) -> None:
        self.counts = counts

    def collect(self) -> Iterator[Metric]:
        now = self.counts()
        yield counter("compositor_view_frames", "Frames the live view encoded and offered to its browsers.",
                      now["frames_encoded"])
        yield counter("compositor_view_composites_skipped",
                      "Composites the live view did not show: a newer one came first (its rate cap).",
                      now["composites_skipped"])
        yield counter("compositor_view_frames_dropped",
                      "Live-view frames a browser did not get: it was still receiving an earlier one.",
                      now["frames_dropped"])
        yield gauge("compositor_view_clients", "Browsers receiving the live view's stream now.", now["clients"])
