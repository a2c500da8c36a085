"""The rig's types to and from their ``ig.v1`` messages, in one place for every process."""

from __future__ import annotations

from ig.v1 import frame_pb2, render_pb2

from .frame import Eyepoint
from .options import RenderOptions, option_names
from .report import FrameReport


def eyepoint_to_proto(eyepoint: Eyepoint) -> frame_pb2.Eyepoint:
    """The message of an eyepoint (float64 all the way: the compositor compares bits)."""
    x, y, z = (float(v) for v in eyepoint.position)
    return frame_pb2.Eyepoint(x=x, y=y, z=z, heading_deg=float(eyepoint.heading_deg),
                              pitch_deg=float(eyepoint.pitch_deg), roll_deg=float(eyepoint.roll_deg))


def eyepoint_from_proto(msg: frame_pb2.Eyepoint) -> Eyepoint:
    """The Eyepoint of a message."""
    return Eyepoint.of(msg.x, msg.y, msg.z, msg.heading_deg, msg.pitch_deg, msg.roll_deg)


def options_to_proto(options: RenderOptions) -> render_pb2.RenderOptions:
    """The message of render options, every field set."""
    return render_pb2.RenderOptions(**options.to_mapping())


def options_from_proto(msg: render_pb2.RenderOptions,
                       base: RenderOptions | None = None) -> RenderOptions:
    """The options a message sets, over base (the defaults); an unset field keeps base's.

    Raises:
        ValueError: a bad value, named with its field (as the rig file's would be).
    """
    given = {name: getattr(msg, name) for name in option_names() if msg.HasField(name)}
    return RenderOptions.from_mapping(given, where="render_options", base=base)


def report_to_proto(report: FrameReport) -> render_pb2.FrameReport:
    """The message of a frame report."""
    return render_pb2.FrameReport(
        stages=[render_pb2.StageTime(stage=k, seconds=v) for k, v in report.stage_seconds.items()],
        counters=report.counters,
        parts=[render_pb2.StageTime(stage=k, seconds=v) for k, v in report.part_seconds.items()])


def report_from_proto(msg: render_pb2.FrameReport) -> FrameReport:
    """The FrameReport of a message."""
    return FrameReport({s.stage: s.seconds for s in msg.stages}, dict(msg.counters),
                       {s.stage: s.seconds for s in msg.parts})
