"""FrameReport and the proto conversions of the rig's types."""

from __future__ import annotations

import math

import pytest

from ig.v1 import render_pb2
from services.rig.frame import Eyepoint
from services.rig.options import RenderOptions
from services.rig.report import FrameReport
from services.rig.wire import (
    eyepoint_from_proto,
    eyepoint_to_proto,
    options_from_proto,
    options_to_proto,
    report_from_proto,
    report_to_proto,
)


def test_frame_report_totals_and_round_trips():
    r = FrameReport({"view": 0.001, "visibility": 0.0125}, {"translucent_dropped": 3, "terrain_voxels": 0})
    assert r.total_seconds == pytest.approx(0.0135)
    d = r.to_dict()
    assert d == {"stages_ms": {"view": 1.0, "visibility": 12.5}, "total_ms": pytest.approx(13.5),
                 "counters": {"translucent_dropped": 3, "terrain_voxels": 0}, "parts_ms": {}}
    assert list(d["stages_ms"]) == ["view", "visibility"]  # in the order the stages ran
    text = r.format()
    assert "view 1.00" in text and "total 13.50" in text and "translucent_dropped=3" in text
    assert "terrain_voxels" not in text  # zero counters are left out of the line
    r.clear()
    assert r.total_seconds == 0.0 and not r.counters


def test_frame_report_through_the_proto_keeps_stage_order():
    r = FrameReport({"view": 1e-4, "cull": 2e-4, "background": 5e-3, "visibility": 9e-3},
                    {"terrain_voxels": 12345})
    back = report_from_proto(report_to_proto(r))
    assert list(back.stage_seconds) == list(r.stage_seconds)
    assert back.stage_seconds == r.stage_seconds and back.counters == r.counters
    assert back.part_seconds == {}


def test_parts_of_a_stage_are_reported_apart_from_the_total():
    r = FrameReport({"background": 0.01, "visibility": 0.002}, {},
                    {"background.cast": 0.006, "background.depth": 0.0035})
    assert r.total_seconds == pytest.approx(0.012)  # parts lie inside their stage
    assert r.to_dict()["parts_ms"] == {"background.cast": pytest.approx(6.0),
                                       "background.depth": pytest.approx(3.5)}
    assert "parts: background.cast 6.00 background.depth 3.50" in r.format()
    back = report_from_proto(report_to_proto(r))
    assert list(back.part_seconds) == ["background.cast", "background.depth"]
    assert back.part_seconds == r.part_seconds
    r.clear()
    assert not r.part_seconds


def test_options_through_the_proto_and_unset_fields_keep_the_base():
    o = RenderOptions(samples=16, filter="gaussian", terrain_bias=-2, haze=False, threads=2)
    assert options_from_proto(options_to_proto(o)) == o
    assert options_from_proto(options_to_proto(o.replace(coverage="samples"))).coverage == "samples"
    partial = render_pb2.RenderOptions(samples="centre", with_range=False)
    assert options_from_proto(partial, base=o) == o.replace(samples="centre", with_range=False)
    with pytest.raises(ValueError, match=r"render_options\.samples: 3 has no pattern"):
        options_from_proto(render_pb2.RenderOptions(samples="3"))


def test_eyepoint_through_the_proto_is_bit_exact():
    e = Eyepoint.of(1.0e6 + 0.1, -2.0e6 / 3.0, 1234.5678, 359.999, -89.9, 180.0)
    back = eyepoint_from_proto(eyepoint_to_proto(e))
    assert back.position.tolist() == e.position.tolist()
    assert (back.heading_deg, back.pitch_deg, back.roll_deg) == (e.heading_deg, e.pitch_deg, e.roll_deg)
    nan = eyepoint_from_proto(eyepoint_to_proto(Eyepoint.of(math.nan, 0, 0, 0, 0, 0)))
    assert math.isnan(nan.position[0])
