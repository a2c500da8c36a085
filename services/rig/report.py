"""FrameReport: what one rendered frame cost, stage by stage, and what its stages counted.

One object, the same wherever a frame is reported: `render_frame(..., report=FrameReport())`
fills it; the worker logs it (format()) and reports its last one in its status
(``ig.v1.FrameReport``, wire.py); `ig render --times` prints it; the benches store
to_dict() in their JSON.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class FrameReport:
    """Per-stage wall-clock seconds and counters of one frame.

    Attributes:
        stage_seconds: seconds spent in each pipeline stage, in the order the stages ran
            (view, cull, transform, backface, clip, project, edges, binning, background,
            visibility, resolve; docs/pipeline.md).
        counters: what the stages counted ("translucent_dropped", "terrain_voxels",
            "subarea_entries_full", ...; docs/pipeline.md lists them).
        part_seconds: seconds of the parts of a stage, named "stage.part" (the background's
            "background.cast", "background.depth", "background.clouds"): where a stage's time
            goes, inside its stage_seconds (not added to the total).
    """

    stage_seconds: dict[str, float] = field(default_factory=dict)
    counters: dict[str, int] = field(default_factory=dict)
    part_seconds: dict[str, float] = field(default_factory=dict)

    @property
    def total_seconds(self) -> float:
        """The sum of the stages' times."""
        return float(sum(self.stage_seconds.values()))

    def clear(self) -> None:
        """Empty it for the next frame."""
        self.stage_seconds.clear()
        self.counters.clear()
        self.part_seconds.clear()

    def to_dict(self) -> dict[str, Any]:
        """{"stages_ms": {stage: ms}, "total_ms": ms, "counters": {name: n}, "parts_ms":
        {"stage.part": ms}} (the bench JSON's form)."""
        return {"stages_ms": {k: v * 1e3 for k, v in self.stage_seconds.items()},
                "total_ms": self.total_seconds * 1e3, "counters": dict(self.counters),
                "parts_ms": {k: v * 1e3 for k, v in self.part_seconds.items()}}

    def format(self) -> str:
        """One line: every stage's milliseconds, the total, then the non-zero counters."""
        stages = " ".join(f"{k} {v * 1e3:.2f}" for k, v in self.stage_seconds.items())
        counters = " ".join(f"{k}={v}" for k, v in self.counters.items() if v)
        text = f"ms: {stages} | total {self.total_seconds * 1e3:.2f}"
        if self.part_seconds:
            parts = " ".join(f"{k} {v * 1e3:.2f}" for k, v in self.part_seconds.items())
            text = f"{text} | parts: {parts}"
        return f"{text} | {counters}" if counters else text
