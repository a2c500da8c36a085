"""A flight log made into a track that can be sampled at any time (docs/replay-formats.md).

The readers give a RawLog: records in file order, as found, NaN where a record has no value
for a column. build_track() puts them in time order, chooses between records with the same
time, drops records whose motion no aircraft the rig flies could fly (a misdated record),
fills each column's missing cells by interpolating that column alone, finds gaps, converts
geodetic positions to the world's east-north-up frame and fills in the attitude when the log
has none; every problem is counted in the track's report. sample() gives the eyepoint at a
log time: positions on a cubic Hermite curve through the records (smooth: continuous
velocity), attitudes by quaternion slerp.
"""

from __future__ import annotations

import bisect
import itertools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from services.rig import geodetic
from services.rig.frame import Eyepoint

from . import attitude

log = logging.getLogger("ig.host.replay")

#: Problems counted while reading and building a track; every one is a key of the report.
PROBLEMS = (
    "corrupt",            # a record or cell that cannot be parsed (the rest of a CSV row is kept)
    "out_of_range",       # a value outside physics (RANGES): refused with its field and line
    "no_fix",             # a record the logger marked as having no valid position (IGC 'V')
    "no_position",        # a record with no position that cannot be interpolated (before the
                          # first or after the last position of the log), or with nothing but a time
    "duplicate",          # a second record at the time of another (the one that fits its
                          # neighbours' motion is kept)
    "impossible_motion",  # a record the aircraft cannot have flown to and from (misdated): dropped
    "misdated",           # a record out of time order whose time is a gap away from the records
                          # around it in the file (a date or week rollover, a clock step): dropped
    "out_of_order",       # a record with a time before an earlier record's (sorted into place)
    "gap",                # an interval longer than the gap threshold (bridged by a straight line)
)
#: An interval is a gap when longer than GAP_FACTOR x the median interval and GAP_MIN_S.
GAP_FACTOR = 5.0
GAP_MIN_S = 1.0
#: Longest run of consecutive records in the file judged as misdated; a longer one is a block
#: of the log written out of order (logs concatenated in the wrong order).
MISDATED_RUN = 2
#: Records around a record (itself included) whose median time it is judged against.
MISDATED_WINDOW = 11
#: Records at either end of the file not judged by their time (too narrow a window).
MISDATED_EDGE = 2
#: Problems named in the report (the counters keep counting past them).
_NOTED = 10

#: Largest |time|, seconds: about 317 years, so every clock a logger uses (Unix time, GPS
#: seconds, time since boot) fits, and a time like -1e300 (a garbage word) does not.
MAX_TIME_S = 1e10
#: Heights, metres: the lowest dry land is the Dead Sea shore (-430 m); 100 km is the edge
#: of space. Applies to geodetic heights and world z.
ALT_RANGE_M = (-500.0, 100_000.0)
#: Largest |x|, |y| of a world-frame position, metres: half the earth's circumference, the
#: farthest any point of the earth can be from the origin.
MAX_WORLD_XY_M = 2e7
#: Accepted values by field, inclusive. Heading may be any finite value (it is taken mod 360).
RANGES: dict[str, tuple[float, float]] = {
    "time_s": (-MAX_TIME_S, MAX_TIME_S),
    "lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 180.0), "alt_m": ALT_RANGE_M,
    "x_m": (-MAX_WORLD_XY_M, MAX_WORLD_XY_M), "y_m": (-MAX_WORLD_XY_M, MAX_WORLD_XY_M), "z_m": ALT_RANGE_M,
    "heading_deg": (-math.inf, math.inf), "pitch_deg": (-90.0, 90.0), "roll_deg": (-180.0, 180.0),
}

#: Fastest ground speed of the aircraft the rig flies, m/s: an airliner cruises at about
#: 250 m/s true airspeed and a jet-stream tailwind adds up to 80; 350 leaves no flight out
#: and puts a record that jumps kilometres in a second (a misdated one) far outside.
MAX_SPEED_MPS = 350.0
#: Largest acceleration, m/s^2: 9 g, the structural limit of aerobatic and fighter aircraft;
#: an airliner pulls under 2.5 g. Bounds how far a record can stray from the line through two
#: others (|deviation| <= MAX_ACCEL_MPS2 |t - ta| |t - tb| / 2, the interpolation error bound).
MAX_ACCEL_MPS2 = 9.0 * attitude.G_MPS2
#: Position noise allowed on top of the motion limits, metres: a GNSS fix is good to a few
#: metres, IGC stores 1.85 m steps and a CSV with 5 decimals of a degree 1.1 m; at 50 records
#: a second that noise alone would look like an impossible speed or acceleration.
POSITION_TOL_M = 25.0
#: When the motion check would drop more than this share of the records, it drops none: the
#: whole log moves too fast (another aircraft, or a wrong time unit), which is no misdated
#: record; the log is kept and a note says so.
MAX_DROPPED_SHARE = 0.5

#: The attitude columns, in RawLog.hpr order; heading and roll are interpolated on the circle.
ATTITUDE = ("heading_deg", "pitch_deg", "roll_deg")
_CIRCULAR = (True, False, True)


def out_of_range(name: str, value: float) -> str | None:
    """Why value is refused for field name (RANGES), or None when it is accepted.

    Raises:
        KeyError: name is not a field of RANGES.
    """
    lo, hi = RANGES[name]
    if not math.isfinite(value):
        return f"{name} = {value} is not finite"
    if not lo <= value <= hi:
        return f"{name} = {value:g} outside [{lo:g}, {hi:g}]"
    return None


@dataclass
class RawLog:
    """Records of a log in file order, as a reader found them.

    Attributes:
        times: record times, seconds (any origin), finite.
        coords: (n, 3): latitude deg, longitude deg, height m when geodetic, else world
            x, y, z metres; NaN where the record has no value.
        geodetic: what coords hold.
        hpr: (n, 3) heading, pitch, roll degrees (NaN where the record has no value), or None
            when the log has no attitude.
        problems: counts by cause (PROBLEMS) found by the reader.
        notes: the first few problems, with their line or record numbers.
        lines: the line (text formats) or record number of each record, for notes; empty:
            records are numbered from 1.
        numbered: what lines counts, for notes ("line", or e.g. "position" for a topic).
        records_read: records with data the reader found, refused ones included; 0: as many
            as were kept.
        columns: the columns the log provides, for the coverage ("position" and attitude
            names); None: "position", and the attitude columns when hpr is not None.
    """

    times: list[float] = field(default_factory=list)
    coords: list[tuple[float, float, float]] = field(default_factory=list)
    geodetic: bool = True
    hpr: list[tuple[float, float, float]] | None = None
    problems: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PROBLEMS, 0))
    notes: list[str] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)
    numbered: str = "line"
    records_read: int = 0
    columns: tuple[str, ...] | None = None

    def problem(self, cause: str, note: str) -> None:
        """Count a problem and keep its note if it is one of the first."""
        self.problems[cause] += 1
        if sum(self.problems.values()) <= _NOTED:
            self.notes.append(f"{cause}: {note}")


@dataclass(frozen=True)
class Track:
    """A cleaned log, ready to sample.

    Attributes:
        t_s: (n,) strictly increasing times, seconds from the first record.
        position: (n, 3) float64 world (east, north, up) metres.
        quat: (n, 4) attitudes as quaternions (attitude.py), neighbours on one hemisphere.
        gap: (n - 1,) True where the interval after a record is a gap.
        tangent: (n, 3) velocity at each record for the Hermite curve, m/s.
        attitude_estimated: the log had no attitude column with a value; the whole attitude was
            estimated from the track.
        problems: counts by cause (PROBLEMS).
        notes: the first few problems.
        origin: the geodetic reference point (lat deg, lon deg, h m) of the world frame, or
            None for a log already in world coordinates.
        start_time: time of the first record in the log's own time base, seconds.
        records_read: records with data the reader found, refused and dropped ones included.
        coverage: per column the log provides ("position", and "heading_deg", "pitch_deg",
            "roll_deg" when it has attitude columns), the share of the track's records with
            their own value for it, in [0, 1] (position: all three cells).
        interpolated: per column, the track's records whose cell was filled (interpolated, or
            held beyond the column's first or last value); position: records with any cell
            filled.
        logged_hpr: (n, 3) heading, pitch, roll degrees as logged at the track's records, NaN
            where the record had none; None when the attitude was estimated.
        attitude_source: (n,) per record "logged", "interpolated" (a cell filled across a
            short dropout), or estimated from the track "air" or "ground" (the estimator found
            a ground roll there): a log without attitude, or a dropout longer than a gap
            (report.py); "mixed" where the columns differ (column_source says how).
        column_source: (n, 3) the same per record and attitude column (heading, pitch, roll):
            a column without any value is estimated while the others stay logged.
        assumptions: what the attitude estimate took for granted (empty when logged).
        merged: records merged into another record of the same time whose missing cells
            they held (two sensors logging at one time): neither used apart nor dropped.
    """

    t_s: np.ndarray
    position: np.ndarray
    quat: np.ndarray
    gap: np.ndarray
    tangent: np.ndarray
    attitude_estimated: bool
    problems: dict[str, int]
    notes: list[str]
    origin: tuple[float, float, float] | None
    start_time: float
    records_read: int = 0
    coverage: dict[str, float] = field(default_factory=dict)
    interpolated: dict[str, int] = field(default_factory=dict)
    logged_hpr: np.ndarray | None = None
    attitude_source: np.ndarray = field(default_factory=lambda: np.array([], dtype=object))
    column_source: np.ndarray = field(default_factory=lambda: np.empty((0, 3), dtype=object))
    assumptions: list[str] = field(default_factory=list)
    merged: int = 0

    @property
    def duration_s(self) -> float:
        """Time from the first record to the last, seconds."""
        return float(self.t_s[-1])

    def sample(self, t_s: float) -> Eyepoint:
        """The eyepoint at t_s seconds from the first record (clamped to the track).

        Raises:
            ValueError: t_s is NaN.
        """
        t = float(t_s)
        if math.isnan(t):
            raise ValueError("t_s: nan is not a time")
        t = min(max(t, 0.0), self.duration_s)
        i = min(int(np.searchsorted(self.t_s, t, side="right")) - 1, len(self.t_s) - 2)
        # h > 0: t_s is strictly increasing (build_track keeps one record per time).
        h = float(self.t_s[i + 1] - self.t_s[i])
        s = (t - float(self.t_s[i])) / h
        p0, p1 = self.position[i], self.position[i + 1]
        if self.gap[i]:
            pos = p0 + s * (p1 - p0)  # across a gap a curve would invent a path: go straight
        else:
            s2, s3 = s * s, s * s * s
            pos = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * self.tangent[i]
                   + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * h * self.tangent[i + 1])
        heading, pitch, roll = attitude.to_hpr(attitude.slerp(self.quat[i], self.quat[i + 1], s))
        return Eyepoint.of(float(pos[0]), float(pos[1]), float(pos[2]), heading, pitch, roll)


class _Problems:
    """The counts and notes of build_track, continuing the reader's."""

    def __init__(self, raw: RawLog) -> None:
        self.counts, self.notes = dict(raw.problems), list(raw.notes)
        #: Records merged into another of the same time (no problem: cells it lacked).
        self.merged = 0
        for cause in PROBLEMS:
            self.counts.setdefault(cause, 0)

    def __call__(self, cause: str, note: str) -> None:
        self.counts[cause] += 1
        if sum(self.counts.values()) <= _NOTED:
            self.notes.append(f"{cause}: {note}")


def build_track(raw: RawLog, *, origin: tuple[float, float, float] | None = None, name: str = "log") -> Track:
    """Clean a raw log into a Track (module doc, docs/replay-formats.md "Cleaning").

    Args:
        raw: the records as read.
        origin: geodetic reference (lat deg, lon deg, h m) of the world frame; default the
            first record of the track. Ignored for logs in world coordinates.
        name: the log's name, for messages.

    Raises:
        ValueError: fewer than two usable records (naming the log and what was found).
    """
    problem = _Problems(raw)
    n_in = len(raw.times)
    times = np.asarray(raw.times, np.float64).reshape(-1)
    coords = np.asarray(raw.coords, np.float64).reshape(-1, 3)
    hpr = None if raw.hpr is None else np.asarray(raw.hpr, np.float64).reshape(-1, 3)
    numbers = np.asarray(raw.lines if raw.lines else range(1, n_in + 1), np.int64)
    word = raw.numbered if raw.lines else "record"

    def label(i: int | np.integer) -> str:
        return f"{word} {numbers[i]}"

    # Readers keep only finite times; a RawLog built elsewhere is held to the same rule.
    finite = np.isfinite(times)
    for i in np.flatnonzero(~finite):
        problem("corrupt", f"{label(i)}: time_s = {times[i]} is not finite")
    # Misdated records, judged among the records with some position: a row of nothing but a
    # time says nothing about where it belongs (it is counted as no_position below).
    for m in _misdated(times, np.flatnonzero(finite & np.isfinite(coords).any(axis=1))):
        finite[m] = False
        problem("misdated", f"{label(m)} at t={times[m]:.3f} s lies a gap away from the records around "
                            f"it in the file (a date rollover or a clock step)")
    # Out of order: the records outside the longest run in time order (in file order), the
    # fewest that put the file in order when moved: one misdated record counts once, not
    # with every record it is ahead of.
    idx = np.flatnonzero(finite)
    for i in idx[_out_of_order(times[idx])]:
        problem("out_of_order", f"{label(i)} at t={times[i]:.3f} s is out of time order in the file")
    order = idx[np.argsort(times[idx], kind="stable")]
    times, coords, numbers = times[order], coords[order], numbers[order]
    hpr = None if hpr is None else hpr[order]
    keep = np.ones(len(times), bool)

    metres = _Metres(coords, raw.geodetic)
    _choose_duplicates(times, coords, hpr, keep, metres, problem, label)
    _drop_impossible(times, coords, keep, metres, problem, label)
    keep &= _positioned(times, coords, hpr, keep, problem, label)

    times, coords, numbers = times[keep], coords[keep], numbers[keep]
    hpr = None if hpr is None else hpr[keep]
    if len(times) < 2:
        found = ", ".join(f"{k} {v}" for k, v in problem.counts.items() if v) or "no problems"
        raise ValueError(f"{name}: {len(times)} usable record(s), need at least 2 ({found})")

    columns = raw.columns or (("position",) + (ATTITUDE if raw.hpr is not None else ()))
    own_position = np.isfinite(coords).all(axis=1)
    coverage = {"position": float(np.mean(own_position))}
    interpolated = {"position": int(np.count_nonzero(~own_position))}
    coords = np.stack([_fill(times, coords[:, j], circular=False) for j in range(3)], axis=1)
    logged = None
    # Per record and attitude column: the dropout its cell is filled across (0: its own value).
    dropout = np.zeros((len(times), 3))
    have = np.zeros(3, bool)  # the attitude columns with a value in some record used
    own = np.zeros((len(times), 3), bool)
    if hpr is not None:
        own = np.isfinite(hpr)
        have = np.asarray(own.any(axis=0))
        for j, c in enumerate(ATTITUDE):
            coverage[c] = float(np.mean(own[:, j]))
        if have.any():
            logged = hpr.copy()
            logged[:, 0] %= 360.0
            # Each column on its own: one with values is filled across its short dropouts;
            # one without (an ADS-B log has no pitch) is estimated below, the others kept.
            dropout = np.stack([_dropout(times, own[:, j]) for j in range(3)], axis=1)
            hpr = np.stack([_fill(times, hpr[:, j], circular=_CIRCULAR[j]) for j in range(3)], axis=1)
            if not have.all():
                empty = ", ".join(c for j, c in enumerate(ATTITUDE) if not have[j])
                problem.notes.append(f"attitude: {empty} has no value in any record used; estimated "
                                     f"from the track, the other attitude columns as logged")
        else:
            problem.notes.append(f"attitude: {', '.join(ATTITUDE)} have no value in any record used; "
                                 f"the attitude is estimated from the track")
            hpr = None
    for c in columns:  # a column the log names but that never had a value
        coverage.setdefault(c, 0.0)

    if raw.geodetic:
        origin = origin or (float(coords[0, 0]), float(coords[0, 1]), float(coords[0, 2]))
        position = geodetic.enu(coords[:, 0], coords[:, 1], coords[:, 2], origin)
    else:
        origin, position = None, coords.copy()
    t = times - times[0]

    dt = np.diff(t)
    threshold = max(GAP_FACTOR * float(np.median(dt)), GAP_MIN_S)
    gap = dt > threshold
    for i in np.flatnonzero(gap):
        problem("gap", f"{dt[i]:.1f} s without records after t={t[i]:.3f} s (gaps are over {threshold:.1f} s)")

    estimated = hpr is None
    assumptions: list[str] = []
    # An attitude dropout longer than a position gap (an AHRS failure) is not interpolated:
    # holding or bridging it would freeze the picture through a turn; the track says more.
    # A column without any value is lost everywhere.
    lost = (dropout > threshold) | ~have
    if lost.any():
        est = attitude.estimate_with_report(t, position)
        assumptions = est.assumptions
        guessed = np.where(est.on_ground, "ground", "air").astype(object)
    # Per record and column: "logged", "interpolated", or estimated "air" / "ground".
    column_source = np.empty((len(t), 3), dtype=object)
    if hpr is None:
        hpr = est.hpr
        column_source[:] = guessed[:, None]
    else:
        column_source[:] = np.where(dropout > 0.0, "interpolated", "logged")
        for j, c in enumerate(ATTITUDE):
            interpolated[c] = int(np.count_nonzero(~own[:, j] & ~lost[:, j]))
        if lost.any():
            # The estimate is in the world frame; the logged angles are against the local frame
            # at the aircraft: the estimate joins them there, angle by angle.
            local_est = est.hpr if not raw.geodetic or origin is None else \
                attitude.world_to_local(est.hpr, coords[:, 0], coords[:, 1], origin)
            hpr = np.where(lost, local_est, hpr)
            column_source[lost] = np.broadcast_to(guessed[:, None], lost.shape)[lost]
        if raw.geodetic and origin is not None:  # (origin is set for every geodetic log)
            # Logged angles are against local north and the local horizontal at the aircraft;
            # the world is the tangent plane at the origin (5.4 degrees apart at 600 km).
            hpr = attitude.local_to_world(hpr, coords[:, 0], coords[:, 1], origin)
        dropped = lost & have & ~own  # dropouts of columns that have values elsewhere
        if dropped.any():
            spans = _runs(np.asarray(dropped.any(axis=1)))
            problem.notes.append(
                f"attitude: {len(spans)} dropout(s) longer than {threshold:.1f} s estimated from the track "
                f"({', '.join(f'{t[a]:.1f}-{t[b]:.1f} s' for a, b in spans[:3])}"
                f"{', ...' if len(spans) > 3 else ''})")
    for c in ATTITUDE:
        if c in columns:
            interpolated.setdefault(c, 0)
    # Per record: "logged" / "interpolated" when every column is logged (interpolated: some
    # cell filled), the estimate's "air" / "ground" when every column is estimated, else "mixed".
    family = np.where(column_source == "interpolated", "logged", column_source)
    source = np.where((family == "logged").all(axis=1),
                      np.where((column_source == "interpolated").any(axis=1), "interpolated", "logged"),
                      np.where((family == family[:, :1]).all(axis=1), family[:, 0], "mixed")).astype(object)
    quat = attitude.continuous(attitude.from_hpr(hpr))
    track = Track(t, position, quat, gap, _tangents(t, position, gap), estimated, problem.counts, problem.notes,
                  origin, float(times[0]), records_read=max(raw.records_read, n_in), coverage=coverage,
                  interpolated=interpolated, logged_hpr=logged, attitude_source=source,
                  column_source=column_source, assumptions=assumptions, merged=problem.merged)
    for a in (track.t_s, track.position, track.quat, track.gap, track.tangent, track.logged_hpr):
        if a is not None:
            a.setflags(write=False)
    return track


def _misdated(times: np.ndarray, idx: np.ndarray) -> list[int]:
    """Records (indices into times, among idx: records with finite times, in file order) out
    of time order in the file (_out_of_order) whose time is also far from the median time of
    every window of records around them in the file, in runs of at most MISDATED_RUN
    consecutive records.

    Such a record sits where its position belongs (between its file neighbours) under a wrong
    time: sorted by time it would land far from them, often beyond the log's end where no
    speed is impossible over the long interval, and stretch the replay by the error. The
    windows are the one centred on the record (narrower near either end of the file, so that
    it stays centred) and every run of MISDATED_WINDOW consecutive records that holds it (the
    whole file when shorter), whose median is expected as many median intervals from the
    record's time as the record is from the window's centre. The median of a centred window
    of a file in time order is the record itself, whatever pauses the logger made: a log in
    order never has a misdated record, and a few wrong times in a window do not move the
    median of the rest far. Far means more than the gap threshold plus half a window of
    median intervals (what the wrong times can move the median by). The first and last
    MISDATED_EDGE records have too narrow a centred window to be judged so (a window of three
    holds as many wrong times as right ones); the motion check still judges them by their
    positions. A longer run of far records is a block of the log written out of order (logs
    concatenated in the wrong order): it is only sorted. A far record whose time agrees with
    a file neighbour that is not far stays (a misdated record disagrees with both sides).
    """
    t = times[idx]
    n = len(t)
    if n < 3:
        return []
    step = float(np.median(np.abs(np.diff(t))))
    half = MISDATED_WINDOW // 2
    tolerance = max(GAP_FACTOR * step, GAP_MIN_S) + half * step
    padded = np.concatenate([np.full(half, np.nan), t, np.full(half, np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1).copy()
    # Near the ends keep the window centred: cut as many records off its far side as the
    # file lacks on the near side.
    reach = np.minimum(np.arange(n), np.arange(n)[::-1])
    for j in np.flatnonzero(reach < half):
        windows[j, : half - reach[j]] = np.nan
        windows[j, half + reach[j] + 1:] = np.nan
    centre = np.nanmedian(windows, axis=1)
    late = np.zeros(n, bool)
    late[_out_of_order(t)] = True
    far = (np.abs(t - centre) > tolerance) & (reach >= MISDATED_EDGE) & late
    # A misdated record is a wrong time among many right ones: then every window that holds it
    # is mostly right times and disagrees with it. A good record near an end of the file has a
    # narrow centred window that three garbage records outvote (and, with a garbage record on
    # either side, no neighbour vouches for it); a full window reaching into the log is mostly
    # good records, and agrees with it. Outvoting a good record takes wrong times (on one side
    # of its time) in most of every window that holds it: six garbage records among the ten
    # after it, and among the ten before it unless it is that near the file's start (likewise
    # at the end). The record is off the centre of such a window: the median is expected that
    # many median intervals from its time, so that a window off centre is no more lenient
    # than the centred one (a clock step of a few intervals still lands far).
    size = min(MISDATED_WINDOW, n)
    medians = np.median(np.lib.stride_tricks.sliding_window_view(t, size), axis=1)
    # Per record, the medians of the full windows holding it: column j is the window that
    # starts size - 1 - j records before it (NaN where that window would leave the file),
    # whose centre is (size - 1) / 2 - j records before it.
    held = np.lib.stride_tricks.sliding_window_view(
        np.concatenate([np.full(size - 1, np.nan), medians, np.full(size - 1, np.nan)]), size)
    expected = held + ((size - 1) / 2 - np.arange(size)) * step
    far &= ~(np.abs(t[:, None] - expected) <= tolerance).any(axis=1)
    # A record whose time agrees with a file neighbour's that is not itself far belongs with
    # it: a misdated record disagrees with the records on both sides (near an end of the file
    # a few wrong times can outnumber the right ones in its narrow window).
    near = np.abs(np.diff(t)) <= tolerance
    far &= ~(np.r_[False, near & ~far[:-1]] | np.r_[near & ~far[1:], False])
    out: list[int] = []
    k = 0
    while k < n:
        if not far[k]:
            k += 1
            continue
        end = k
        while end < n and far[end]:
            end += 1
        if end - k <= MISDATED_RUN:
            out += [int(i) for i in idx[k:end]]
        k = end
    return out


def _out_of_order(t: np.ndarray) -> np.ndarray:
    """Indices of the records not in a longest non-decreasing subsequence of t (patience
    sorting, O(n log n)); the later of equal choices is kept in the subsequence."""
    tails: list[float] = []  # smallest last time of a run of each length
    tail_at: list[int] = []
    prev = np.full(len(t), -1)
    for i, v in enumerate(t):
        k = bisect.bisect_right(tails, v)
        if k == len(tails):
            tails.append(v)
            tail_at.append(i)
        else:
            tails[k], tail_at[k] = v, i
        prev[i] = tail_at[k - 1] if k else -1
    in_run = np.zeros(len(t), bool)
    i = tail_at[-1] if tail_at else -1
    while i >= 0:
        in_run[i] = True
        i = prev[i]
    return np.flatnonzero(~in_run)


class _Metres:
    """Positions in metres for the motion checks: world coordinates as they are, geodetic ones
    in ENU around the first record with a full position (any reference serves: the checks
    measure distances over a few kilometres, where the frame's curvature is negligible)."""

    def __init__(self, coords: np.ndarray, geodetic_coords: bool) -> None:
        full = np.flatnonzero(np.isfinite(coords).all(axis=1))
        self.ref = tuple(float(v) for v in coords[full[0]]) if geodetic_coords and len(full) else None

    def __call__(self, c: np.ndarray) -> np.ndarray:
        c = np.asarray(c, np.float64).reshape(-1, 3)
        if self.ref is None:
            return c
        return geodetic.enu(c[:, 0], c[:, 1], c[:, 2], self.ref)  # type: ignore[arg-type]


def _choose_duplicates(times, coords, hpr, keep, metres, problem, label) -> None:
    """Keep one record per time: the one whose position best fits the motion of its nearest
    neighbours with a full position (linear between them), the first in the file on a tie or
    without neighbours. A record that only adds cells the kept one lacks (two sensors logged
    at the same time) is merged into it instead of counted."""
    n = len(times)
    if n < 2:
        return
    starts = np.flatnonzero(np.r_[True, np.diff(times) > 0.0])
    ends = np.r_[starts[1:], n]
    full = np.isfinite(coords).all(axis=1)
    for s, e in zip(starts, ends, strict=True):
        if e - s < 2:
            continue
        members = np.arange(s, e)
        pred = _neighbour_prediction(times, coords, full, s, e)
        has_pos = np.isfinite(coords[members]).any(axis=1)
        miss = np.zeros(len(members))
        if pred is not None and has_pos.any():
            filled = np.where(np.isfinite(coords[members]), coords[members], pred)
            miss = np.linalg.norm(metres(filled) - metres(pred), axis=1)
        miss[~has_pos] = np.inf  # a record with a position is kept before one without
        k = members[int(np.argmin(miss))]  # argmin: the first of equals
        for o in members:
            if o == k:
                continue
            cells_o = _cells(coords, hpr, o)
            cells_k = _cells(coords, hpr, k)
            keep[o] = False
            if not (cells_o & cells_k).any():
                coords[k] = np.where(np.isfinite(coords[k]), coords[k], coords[o])
                if hpr is not None:
                    hpr[k] = np.where(np.isfinite(hpr[k]), hpr[k], hpr[o])
                problem.merged += 1
                continue
            why = ("the first is kept" if pred is None else
                   f"kept {label(k)}, {miss[k - s]:.0f} m from its neighbours' motion; this one "
                   f"{miss[o - s]:.0f} m")
            problem("duplicate", f"{label(o)}: another record at t={times[o]:.3f} s ({why})")


def _cells(coords, hpr, i) -> np.ndarray:
    own = np.isfinite(coords[i])
    return own if hpr is None else np.r_[own, np.isfinite(hpr[i])]


def _neighbour_prediction(times, coords, full, s, e) -> np.ndarray | None:
    """Position at times[s] from the nearest full records before s and from e on (the median
    of each neighbour's own duplicates), linear in time; None without any."""
    before = np.flatnonzero(full[:s])
    after = np.flatnonzero(full[e:]) + e
    sides = []
    for idx in (before[times[before] == times[before[-1]]] if len(before) else before,
                after[times[after] == times[after[0]]] if len(after) else after):
        sides.append(None if len(idx) == 0 else (float(times[idx[0]]), np.median(coords[idx], axis=0)))
    a, b = sides
    if a is None:
        return b[1] if b is not None else None
    if b is None:
        return a[1]
    # b[0] > a[0]: neighbours are on either side of the group's time.
    f = (float(times[s]) - a[0]) / (b[0] - a[0])
    return a[1] + f * (b[1] - a[1])


def _drop_impossible(times, coords, keep, metres, problem, label) -> None:
    """Drop records whose motion to their neighbours is impossible (MAX_SPEED_MPS,
    MAX_ACCEL_MPS2): first among records with a full position, worst first and repeatedly
    (a record next to a dropped one is judged again without it), then records with part of
    a position (their missing cells interpolated) against the full ones kept."""
    full = keep & np.isfinite(coords).all(axis=1)
    ref = np.flatnonzero(full)
    if len(ref) < 3:
        return  # two records cannot say which one is wrong
    pos = metres(coords)
    dropped: list[tuple[int, float]] = []
    alive = ref.copy()
    for _ in range(len(ref)):
        score = _misfit(times[alive], pos[alive], times[alive], pos[alive], self_index=True)
        bad = score > 1.0
        if not bad.any():
            break
        # Of neighbouring misfits only the worst goes in one round: a good record next to a
        # bad one also misfits when judged with it, and is judged again without it.
        worst = bad.copy()
        for shift in (1, 2):
            worst[shift:] &= score[shift:] > score[:-shift]
            worst[:-shift] &= score[:-shift] >= score[shift:]
        dropped += [(int(i), float(s)) for i, s in zip(alive[worst], score[worst], strict=True)]
        alive = alive[~worst]
        if len(alive) < 3:
            break
    if len(dropped) > MAX_DROPPED_SHARE * len(ref):
        problem.notes.append(f"impossible_motion: {len(dropped)} of {len(ref)} records move faster than "
                             f"{MAX_SPEED_MPS:.0f} m/s or {MAX_ACCEL_MPS2:.0f} m/s^2; none dropped (the whole "
                             f"log moves so: check its time unit)")
        log.warning("%s", problem.notes[-1])
        return
    for i, _ in sorted(dropped):
        keep[i] = False
        problem("impossible_motion", f"{label(i)}: t={times[i]:.3f} s {_implied(times, pos, alive, i)}")
    partial = np.flatnonzero(keep & ~full & np.isfinite(coords).any(axis=1))
    if len(partial) == 0 or len(alive) < 2:
        return
    filled = coords[partial].copy()
    for j in range(3):
        own = keep & np.isfinite(coords[:, j])
        filled[:, j] = np.where(np.isfinite(filled[:, j]), filled[:, j],
                                np.interp(times[partial], times[own], coords[own, j]))
    ppos = metres(filled)
    score = _misfit(times[partial], ppos, times[alive], pos[alive], self_index=False)
    for k, p, s in zip(partial.tolist(), ppos, score, strict=True):
        if s > 1.0:
            keep[k] = False
            pos[k] = p
            problem("impossible_motion", f"{label(k)}: t={times[k]:.3f} s {_implied(times, pos, alive, k)}")


def _implied(times, pos, alive, i) -> str:
    """The speeds from the kept record before i and to the one after, for a note."""
    k = int(np.searchsorted(times[alive], times[i]))
    parts = []
    for j, word in ((k - 1, "from the record before"), (k, "to the record after")):
        if 0 <= j < len(alive) and times[alive[j]] != times[i]:
            # dt != 0: the kept records have times other than i's (duplicates were resolved).
            v = np.linalg.norm(pos[i] - pos[alive[j]]) / abs(times[i] - times[alive[j]])
            parts.append(f"{v:.0f} m/s {word}")
    return "implies " + " and ".join(parts) if parts else "does not fit its neighbours"


def _misfit(t, p, tr, pr, *, self_index: bool) -> np.ndarray:
    """How far each record (t, p) is from fitting the motion of reference records (tr, pr),
    both in time order with distinct times; > 1 is impossible.

    A record is judged by its four nearest references (two on either side where there are).
    Each pair of them vouches for it when the record is within reach of both
    (|p - pa| <= MAX_SPEED_MPS |t - ta| + POSITION_TOL_M) and within the acceleration bound of
    the line through them (MAX_ACCEL_MPS2 |t - ta| |t - tb| / 2 + POSITION_TOL_M); the score
    is the best pair's largest ratio of distance to bound. Judged by the best pair, a good
    record next to a bad one is vouched for by two good ones.

    Args:
        self_index: the records are the references themselves (each is left out of its own
            window).
    """
    m = len(tr)
    if m < 2:
        return np.zeros(len(t))
    if self_index:
        k = np.arange(m)
        start = np.clip(k - 2, 0, max(m - 5, 0))
        win = start[:, None] + np.arange(5)
        win = np.where(win == k[:, None], -1, win)
    else:
        k = np.searchsorted(tr, t)
        start = np.clip(k - 2, 0, max(m - 4, 0))
        win = start[:, None] + np.arange(4)
    win = np.where(win < m, win, -1)
    best = np.full(len(t), np.inf)
    for a, b in itertools.combinations(range(win.shape[1]), 2):
        ia, ib = win[:, a], win[:, b]
        ok = (ia >= 0) & (ib >= 0)
        ia, ib = np.where(ok, ia, 0), np.where(ok, ib, 0)
        ta, tb, pa, pb = tr[ia], tr[ib], pr[ia], pr[ib]
        # tb - ta != 0 wherever ok (distinct reference times); the others are masked below.
        span = np.where(ok & (tb != ta), tb - ta, 1.0)
        pred = pa + ((t - ta) / span)[:, None] * (pb - pa)
        dev = np.linalg.norm(p - pred, axis=1) / (MAX_ACCEL_MPS2 * np.abs(t - ta) * np.abs(t - tb) / 2
                                                  + POSITION_TOL_M)
        # The bounds are >= POSITION_TOL_M > 0: no division by zero.
        reach_a = np.linalg.norm(p - pa, axis=1) / (MAX_SPEED_MPS * np.abs(t - ta) + POSITION_TOL_M)
        reach_b = np.linalg.norm(p - pb, axis=1) / (MAX_SPEED_MPS * np.abs(t - tb) + POSITION_TOL_M)
        score = np.maximum(dev, np.maximum(reach_a, reach_b))
        best = np.where(ok & (tb != ta), np.minimum(best, score), best)
    return np.where(np.isfinite(best), best, 0.0)


def _positioned(times, coords, hpr, keep, problem, label) -> np.ndarray:
    """Records that can have a position: within the span of every position column's own
    values (no position is invented before a log's first fix or after its last) and with at
    least one value of their own (position or attitude)."""
    ok = keep.copy()
    for j in range(3):
        own = np.flatnonzero(keep & np.isfinite(coords[:, j]))
        if len(own) == 0:
            ok[:] = False
            break
        ok &= (times >= times[own[0]]) & (times <= times[own[-1]])
    anything = np.isfinite(coords).any(axis=1)
    if hpr is not None:
        anything |= np.isfinite(hpr).any(axis=1)
    ok &= anything
    for i in np.flatnonzero(keep & ~ok):
        why = "nothing but a time" if not anything[i] else "no position, and none to interpolate from"
        problem("no_position", f"{label(i)}: t={times[i]:.3f} s has {why}")
    return ok


def _dropout(t: np.ndarray, own: np.ndarray) -> np.ndarray:
    """Per record, the length of the dropout of a column it lies in (0 where the column has
    its own value): the time between the column's values before and after it; before the
    first or after the last value, twice the time to that value (a dropout as long on the
    side the log does not show)."""
    out = np.zeros(len(t))
    have = np.flatnonzero(own)
    if len(have) == 0:
        return out
    for i in np.flatnonzero(~own):
        k = int(np.searchsorted(have, i))
        before = t[have[k - 1]] if k > 0 else None
        after = t[have[k]] if k < len(have) else None
        if before is not None and after is not None:
            out[i] = after - before
        else:
            out[i] = 2.0 * abs(t[i] - (after if after is not None else before))
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True in mask."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), (np.flatnonzero(edges == -1) - 1).tolist(),
                    strict=True))


def _fill(t: np.ndarray, v: np.ndarray, *, circular: bool) -> np.ndarray:
    """The column v with its NaN cells interpolated in time over its own values (held beyond
    the first and last); a circular column (degrees) turns the short way through 0/360."""
    own = np.isfinite(v)
    if own.all() or not own.any():
        return v.copy()
    vals = v[own]
    if circular:
        vals = np.degrees(np.unwrap(np.radians(vals)))
    out = v.copy()
    out[~own] = np.interp(t[~own], t[own], vals)
    if circular:  # back to [-180, 180): roll's range (heading is taken mod 360 where used)
        out[~own] = (out[~own] + 180.0) % 360.0 - 180.0
    return out


def _tangents(t: np.ndarray, p: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Velocity at each record: the time-weighted mean of the slopes on either side
    (Catmull-Rom for uneven spacing), using only a side that is not a gap."""
    # np.diff(t) > 0: the times are strictly increasing.
    slope = np.diff(p, axis=0) / np.diff(t)[:, None]
    h = np.diff(t)
    out = np.zeros_like(p)
    for i in range(len(t)):
        left = i > 0 and not gap[i - 1]
        right = i < len(t) - 1 and not gap[i]
        if left and right:
            out[i] = (slope[i - 1] * h[i - 1] + slope[i] * h[i]) / (h[i - 1] + h[i])
        elif left:
            out[i] = slope[i - 1]
        elif right:
            out[i] = slope[i]
    return out
