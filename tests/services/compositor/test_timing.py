"""The chain of a composite: hops along the channel the composite waited for, adding up to the
control-to-composite latency; summarised per hop with p50/p95/p99/max."""

import numpy as np
import pytest

from services.compositor.gather import ChannelImage, ChannelTiming, CompleteFrame, percentiles
from services.compositor.stitch import compose
from services.compositor.timing import HOPS, TimingStats, chain, hop_seconds


def frame(n, base, *, late="b", timing=True):
    """Frame n sampled at base, published 1 ms later; channel `late` reaches the compositor last."""
    def t(channel):
        if not timing:
            return ChannelTiming(compositor_receive=base + 0.05)
        extra = 0.010 if channel == late else 0.0
        return ChannelTiming(frame_received=base + 0.002, render_start=base + 0.003,
                             render_end=base + 0.020 + extra, submit=base + 0.022 + extra,
                             compositor_receive=base + 0.025 + extra)
    images = tuple(ChannelImage(c, np.zeros((2, 3, 3), "<f2"), (0.0,) * 6, 0.017, base, 0, t(c)) for c in "abc")
    return CompleteFrame(n, n / 10, (0.0,) * 6, base, images, publish_time=base + 0.001, run_id="r")


def test_the_hops_follow_the_last_image_and_add_up_to_the_latency():
    composite = compose(frame(0, 100.0, late="b"), clock=lambda: 100.0375)
    hops = chain(composite)
    assert list(hops) == [key for key, _ in HOPS]
    assert hops["host_sample_to_publish"] == pytest.approx(0.001)
    assert hops["render"] == pytest.approx(0.027)  # b's render, the longest
    assert hops["render_end_to_compositor_receive"] == pytest.approx(0.005)
    assert hops["compositor_receive_to_composite"] == pytest.approx(0.0025)
    assert sum(hops.values()) == pytest.approx(composite.time - composite.frame.control_sample_time)
    assert all(v >= 0 for v in hops.values())


def test_a_missing_stamp_gives_no_chain():
    assert chain(compose(frame(0, 100.0, timing=False), clock=lambda: 100.1)) is None
    with pytest.raises(ValueError, match="stamps: 3 time stamps, expected 7"):
        hop_seconds((1.0, 2.0, 3.0))


def test_stats_report_every_hop_the_critical_channel_and_the_rate():
    stats = TimingStats()
    for n in range(5):
        base = 100.0 + n * 0.1  # a composite every 100 ms: 10 Hz
        stats.add(compose(frame(n, base, late="c" if n == 4 else "b"), clock=lambda b=base: b + 0.04))
    stats.add(compose(frame(5, 100.5, timing=False), clock=lambda: 100.54))  # counted in the latency only
    doc = stats.report()
    assert doc["control_to_composite_latency"]["count"] == 6
    assert doc["control_to_composite_latency"]["max_ms"] == pytest.approx(40.0)
    assert set(doc["latency_chain"]) == {key for key, _ in HOPS}
    assert doc["latency_chain"]["render"]["count"] == 5
    assert doc["latency_chain"]["render"]["p50_ms"] == pytest.approx(27.0)
    assert doc["critical_channel"] == {"b": 4, "c": 1}
    assert doc["composite_rate_hz"] == pytest.approx(10.0)
    assert doc["composite_interval"]["count"] == 5
    assert (doc["first_composite_time"], doc["last_composite_time"]) == pytest.approx((100.04, 100.54))


def test_percentiles_have_a_max_and_nothing_without_data():
    assert percentiles([0.001, 0.002, 0.010]) == {"p50_ms": 2.0, "p95_ms": pytest.approx(9.2),
                                                  "p99_ms": pytest.approx(9.84), "max_ms": 10.0, "count": 3}
    assert percentiles([]) == {"p50_ms": None, "p95_ms": None, "p99_ms": None, "max_ms": None, "count": 0}
    empty = TimingStats().report()
    assert empty["composite_rate_hz"] is None
    assert empty["first_composite_time"] is None and empty["last_composite_time"] is None
