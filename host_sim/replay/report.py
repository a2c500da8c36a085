"""What a replay made of a log: `ig host --replay LOG --report` (docs/replay-formats.md).

Per log: records read, used, interpolated per column, dropped by cause; each column's
coverage; per attitude column where its values came from (logged, estimated or mixed, with
the records of each); the attitude source per segment (logged, estimated in the air,
estimated on the ground, or column by column where they differ) and the estimator's
assumptions; the time span and the largest gap; and a plot of the
replayed track and attitude (the eyepoint the host would publish, sampled at PLOT_RATE_HZ)
against the log's own records, so that a reader sees at a glance where the replay follows
the log and where it had to fill in.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .track import ATTITUDE, Track

#: Rate at which the plot samples the replay, Hz: finer than any log's records (1-50 Hz), so
#: the curve between records shows how the replay interpolates.
PLOT_RATE_HZ = 20.0
#: Most samples a plot draws (a long log is sampled more coarsely).
PLOT_MAX_SAMPLES = 20000

#: Names of the attitude sources per record (Track.attitude_source).
SOURCES = {"logged": "logged", "interpolated": "logged, interpolated across short dropouts",
           "air": "estimated in the air", "ground": "estimated on the ground"}


def replay_report(track: Track, *, path: str, format: str) -> dict[str, Any]:
    """The report of one replayed log, as a JSON-able dict (module doc)."""
    used = len(track.t_s)
    dropped = {cause: n for cause, n in track.problems.items() if n and cause != "gap"}
    dt = np.diff(track.t_s)
    k = int(np.argmax(dt))
    columns = attitude_columns(track)
    return {
        "file": path,
        "format": format,
        "records_read": int(track.records_read),
        "records_used": used,
        "records_merged": int(track.merged),
        "interpolated": {c: int(n) for c, n in track.interpolated.items()},
        "coverage": {c: float(v) for c, v in track.coverage.items()},
        "dropped": dropped,
        "gaps": int(track.problems.get("gap", 0)),
        "start_time_s": float(track.start_time),
        "duration_s": float(track.duration_s),
        "largest_gap": {"seconds": float(dt[k]), "after_s": float(track.t_s[k])},
        "attitude": _summary(track, columns),
        "attitude_columns": columns,
        "attitude_segments": attitude_segments(track),
        "assumptions": list(track.assumptions),
        "notes": list(track.notes),
    }


def attitude_columns(track: Track) -> dict[str, dict[str, Any]]:
    """Per attitude column, where its values came from: "logged" (its own values, and cells
    interpolated across short dropouts), "estimated" (from the track) or "mixed", with the
    records of each kind."""
    src = np.asarray(track.column_source)
    out: dict[str, dict[str, Any]] = {}
    for j, c in enumerate(ATTITUDE):
        column = src[:, j] if src.shape == (len(track.t_s), 3) else np.array([], dtype=object)
        logged = int(np.count_nonzero(column == "logged"))
        filled = int(np.count_nonzero(column == "interpolated"))
        estimated = int(np.count_nonzero((column == "air") | (column == "ground")))
        kind = "estimated" if logged + filled == 0 else "logged" if estimated == 0 else "mixed"
        out[c] = {"source": kind, "logged": logged, "interpolated": filled, "estimated": estimated}
    return out


def _summary(track: Track, columns: dict[str, dict[str, Any]]) -> str:
    """The attitude's origin in a few words: logged, estimated, or which column came from where."""
    if track.attitude_estimated:
        return "estimated"
    kinds = {where["source"] for where in columns.values()}
    if kinds == {"logged"}:
        return "logged"
    if kinds == {"mixed"} or kinds == {"logged", "mixed"}:
        return "logged, estimated across long dropouts"
    return "per column: " + ", ".join(f"{c.removesuffix('_deg')} {where['source']}" for c, where in columns.items())


def _described(key: tuple[str, ...]) -> str:
    """The attitude source of a record: one name, or column by column where they differ."""
    if len(key) == 1:
        return SOURCES.get(key[0], key[0])
    return ", ".join(f"{c.removesuffix('_deg')} {SOURCES.get(s, s)}" for c, s in zip(ATTITUDE, key, strict=True))


def attitude_segments(track: Track) -> list[dict[str, Any]]:
    """Runs of records with one attitude source: source, first and last time, records. A
    record whose columns differ ("mixed") is described column by column (a logged cell and
    one interpolated across a short dropout count alike there)."""
    cols = np.asarray(track.column_source)
    src: list[tuple[str, ...]] = []
    for i, s in enumerate(np.asarray(track.attitude_source)):
        if s == "mixed" and cols.shape == (len(track.t_s), 3):
            src.append(tuple("logged" if v == "interpolated" else str(v) for v in cols[i]))
        else:
            src.append((str(s),))
    out: list[dict[str, Any]] = []
    start = 0
    for i in range(1, len(src) + 1):
        if i == len(src) or src[i] != src[start]:
            out.append({"source": _described(src[start]),
                        "from_s": float(track.t_s[start]), "to_s": float(track.t_s[i - 1]),
                        "records": i - start})
            start = i
    return out


def format_report(doc: dict[str, Any]) -> str:
    """The report as the text `ig host --report` prints."""
    lines = [f"replay report: {doc['file']} ({doc['format']})",
             f"  records read {doc['records_read']}, used {doc['records_used']}"
             + (f", merged into another of their time {doc['records_merged']}" if doc["records_merged"] else "")]
    if doc["dropped"]:
        lines.append("  dropped by cause: " + ", ".join(f"{c} {n}" for c, n in sorted(doc["dropped"].items())))
    else:
        lines.append("  dropped: none")
    for column, share in doc["coverage"].items():
        filled = doc["interpolated"].get(column, 0)
        lines.append(f"  {column:<12} own values in {100.0 * share:5.1f} % of the records used"
                     + (f", {filled} interpolated" if filled else ""))
    gap = doc["largest_gap"]
    lines.append(f"  time span {doc['duration_s']:.1f} s from log time {doc['start_time_s']:.3f} s; "
                 f"largest gap {gap['seconds']:.2f} s after t = {gap['after_s']:.1f} s"
                 + (f" ({doc['gaps']} gaps bridged by straight lines)" if doc["gaps"] else ""))
    for column, where in doc["attitude_columns"].items():
        counts = ", ".join(f"{k} {where[k]}" for k in ("logged", "interpolated", "estimated") if where[k])
        lines.append(f"  {column:<12} {where['source']}" + (f" ({counts})" if counts else ""))
    lines.append(f"  attitude {doc['attitude']}:")
    for seg in doc["attitude_segments"]:
        lines.append(f"    {seg['from_s']:9.1f} .. {seg['to_s']:9.1f} s  {seg['source']} "
                     f"({seg['records']} records)")
    if doc["assumptions"]:
        lines.append("  the estimate assumes:")
        lines.extend(f"    - {a}" for a in doc["assumptions"])
    if doc["notes"]:
        lines.append("  first problems:")
        lines.extend(f"    {n}" for n in doc["notes"])
    return "\n".join(lines)


def plot_replay(track: Track, out_png: str | Path, *, title: str = "") -> Path:
    """Write the plot of the replayed track and attitude against the log's records (PNG).

    Raises:
        OSError: the file cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")  # no display: the host runs headless
    import matplotlib.pyplot as plt

    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    n = int(min(PLOT_MAX_SAMPLES, max(2, math.ceil(track.duration_s * PLOT_RATE_HZ) + 1)))
    times = np.linspace(0.0, track.duration_s, n)
    eyes = [track.sample(t) for t in times]
    pos = np.array([e.position for e in eyes], np.float64)
    hpr = np.array([(e.heading_deg, e.pitch_deg, e.roll_deg) for e in eyes], np.float64)
    fig, axes = plt.subplots(5, 1, figsize=(10, 13), constrained_layout=True)
    ax = axes[0]
    ax.plot(pos[:, 0], pos[:, 1], "-", lw=1.0, label="replayed")
    ax.plot(track.position[:, 0], track.position[:, 1], ".", ms=3, label="log records")
    ax.set_xlabel("east, m")
    ax.set_ylabel("north, m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax.set_title(title or "replayed track against the log")
    ax = axes[1]
    ax.plot(times, pos[:, 2], "-", lw=1.0, label="replayed")
    ax.plot(track.t_s, track.position[:, 2], ".", ms=3, label="log records")
    ax.set_ylabel("height, m")
    ax.legend(loc="best", fontsize="small")
    logged = None if track.logged_hpr is None else track.logged_hpr.copy()
    # Heading unwrapped, so that a course through north is a line, not a jump of 360 degrees.
    hpr[:, 0] = np.degrees(np.unwrap(np.radians(hpr[:, 0])))
    if logged is not None:
        ok = np.isfinite(logged[:, 0])
        logged[ok, 0] = np.degrees(np.unwrap(np.radians(logged[ok, 0])))
    cols = np.asarray(track.column_source)
    ground = ((cols == "ground").any(axis=1) if cols.shape == (len(track.t_s), 3)
              else np.asarray(track.attitude_source) == "ground")
    for j, name in enumerate(("heading, deg", "pitch, deg", "roll, deg")):
        ax = axes[2 + j]
        ax.plot(times, hpr[:, j], "-", lw=1.0, label="replayed (world frame)")
        if logged is not None:
            ax.plot(track.t_s, logged[:, j], ".", ms=3, label="logged (local frame)")
        if ground.any():
            lo, hi = ax.get_ylim()
            ax.fill_between(track.t_s, lo, hi, where=ground, color="0.85", step="mid",
                            label="estimated on the ground")
            ax.set_ylim(lo, hi)
        ax.set_ylabel(name)
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("log time from the first record, s")
    fig.savefig(out_png, dpi=80)
    plt.close(fig)
    return out_png
