"""`ig latency`: the transport delay of the rig, measured as 14 CFR Part 60 measures it (docs/latency.md).

A step of the pitch control goes in through the real input path, and the time to the first
composite whose image shows the response comes out, repeated and summarised; the frames' own
time stamps split each measurement into the hops of the chain.

- The cockpit: this process plays a CAN adapter (slcan, LAWICEL ASCII frames) on a
  pseudo-terminal, and sends CANaerospace pitch_control_position frames on it 20 times a
  second, as a cockpit node does; the host, `ig host --controls can://slcan/dev/pts/N`, opens
  the pseudo-terminal's other end as its adapter through python-can. So the host runs in its
  own process, as in a rig, and reads its controls through python-can and its slcan
  interface. (python-can's `virtual` bus reaches only its own process; its `udp_multicast`
  needs msgpack, which the project does not install.)
- The aircraft stands on the runway at rest, where the stick only pitches the nose (8 degrees
  per unit of stick, through the flight model's 0.4 s stick lag): the picture moves by the
  pitch alone, and nothing else changes between frames.
- The steps alternate between two stick positions (0.25 and 0.75 by default). Before each, the
  harness waits until the horizon of the watched channel (the rig's middle one) is steady,
  then for a random part of a frame (Part 60's input comes at any time of the host's cycle);
  then it sends the new position and notes the time. The response is the first composite
  whose rows have moved (WatchComposites: a luminance profile per row) by more than a
  threshold (a tenth of a pixel by default) in the direction of the step, relative to the
  last composite before it. The latency is that composite's time (stitched in the
  compositor's memory) minus the step's.
- The alternation makes any motion left over from the previous step run against the next
  response, so it cannot be mistaken for it; the first step goes down, against the nose
  rising from the runway to the first position.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import random
import select
import threading
import time
import tty
from dataclasses import asdict, dataclass, field
from pathlib import Path

import grpc
import numpy as np

from ig.v1 import compositor_pb2, compositor_pb2_grpc
from services.compositor.gather import percentiles
from services.compositor.timing import HOPS, hop_seconds
from services.demo import (
    AUTO_RATE_MAX_HZ,
    EXIT_INTERRUPTED,
    Failure,
    Processes,
    StopFlag,
    add_rig_options,
    compile_kernels,
    host_pace_args,
    milliseconds_cells,
    prepare_rig,
    rate_or_auto,
    start_workers,
    stop_flag,
    wait_for_exit,
)
from services.rig.cli_common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, error, positive
from services.rig.grpc_util import STREAM_DEADLINE_S, make_channel
from services.rig.rigfile import Rig, rig_toml
from services.rig.threads import usable_cores

#: FAA 14 CFR Part 60, test 4.a.2 (transport delay) of Appendices A (aeroplanes) and C
#: (helicopters), qualification levels C and D: the longest time from a control's movement
#: to the visual system's response, seconds.
PART60_LIMITS: tuple[tuple[str, float], ...] = (
    ("aeroplanes (Part 60 App. A, test 4.a.2, levels C and D)", 0.150),
    ("helicopters (Part 60 App. C, test 4.a.2, levels C and D)", 0.100),
)

#: The first hop of the harness's chain, before the compositor's HOPS.
CONTROL_HOP = ("control_to_host_sample", "cockpit -> host: CAN frame, wait for the host's next sample")

#: How often the cockpit repeats the pitch control, Hz (a CANaerospace node sends at 20 Hz or more).
CONTROL_HZ = 20.0

#: Longest wait for the first composite after the host starts (workers loading kernels), seconds.
_FIRST_COMPOSITE_S = 300.0
#: Longest wait for any further composite, seconds: a rig that stops delivering them is broken.
_NEXT_COMPOSITE_S = 60.0
#: Settling: this many consecutive frame-to-frame shifts must be below a quarter of the threshold.
_SETTLE_FRAMES = 3
#: Simulated seconds to wait for the picture to settle before stepping anyway (15 stick lags),
#: and at least this many frames. Counted in the frames' simulation time, not in frames: with the
#: host paced by the rig the frame intervals vary, and the stick lag runs in simulated time.
_SETTLE_MAX_SIM_S = 6.0
_SETTLE_MIN_FRAMES = _SETTLE_FRAMES + 2
#: Simulated seconds, and at least this many frames, within which a step's response must show.
_RESPONSE_MAX_SIM_S = 2.0
_RESPONSE_MAX_FRAMES = 10


class RigFailed(RuntimeError):
    """The rig stopped delivering: a process failed, no composite came in time, or a signal."""


# --- the cockpit ---------------------------------------------------------------------------------

class SlcanCockpit:
    """A cockpit node behind an slcan CAN adapter, on a pseudo-terminal (module doc).

    The host opens `url` (its end of the pseudo-terminal) as an slcan adapter. Once it has (the
    adapter is told "O" to open the channel), a thread sends the pitch control CONTROL_HZ times
    a second; set_pitch sends a new position at once and returns when it was sent.

    Args:
        pitch: the stick's first position, -1 .. 1.
    """

    def __init__(self, pitch: float) -> None:
        from host_sim.inputs import canaerospace

        self._encode = canaerospace.encode
        self._master, self._slave = os.openpty()
        # No echo and no line editing on the host's end until pyserial sets it up the same way.
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.url = f"can://slcan{os.ttyname(self._slave)}@115200?sleep_after_open=0"
        self.opened = threading.Event()
        self.frames_sent = 0
        self.frames_dropped = 0  # periodic frames the host was not reading yet (before its first frame)
        self._pitch = pitch
        self._message_code = 0
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cockpit", daemon=True)
        self._thread.start()

    def set_pitch(self, pitch: float) -> float:
        """Move the stick to pitch and send it now; returns the time it was sent, UNIX seconds.

        Raises:
            RigFailed: the host has not read its adapter for _NEXT_COMPOSITE_S seconds.
        """
        deadline = time.monotonic() + _NEXT_COMPOSITE_S
        with self._lock:
            self._pitch = pitch
            while (sent := self._send_locked()) is None:
                # The adapter's buffer is full; the host reads it every frame.
                if time.monotonic() > deadline:
                    raise RigFailed("the host does not read its CAN adapter")
                time.sleep(0.001)
            return sent

    def close(self) -> None:
        """Stop sending and close the pseudo-terminal."""
        self._closed.set()
        self._thread.join()
        os.close(self._master)
        os.close(self._slave)

    def _send_locked(self) -> float | None:
        """Write the stick's position as an slcan frame (lock held); the time it was written, UNIX
        seconds, or None if the adapter's buffer was full (the host is not reading yet)."""
        can_id, data = self._encode("pitch_control_position", self._pitch, message_code=self._message_code)
        line = f"t{can_id:03X}{len(data)}{data.hex().upper()}\r".encode()
        now = time.time()
        try:
            written = os.write(self._master, line)
        except BlockingIOError:
            return None
        if written < len(line):
            self._write_all(line[written:])  # never leave half a frame on the line
        self._message_code = (self._message_code + 1) % 256  # CANaerospace counts each identifier's messages
        self.frames_sent += 1
        return now

    def _write_all(self, data: bytes) -> None:
        while data:
            try:
                data = data[os.write(self._master, data):]
            except BlockingIOError:
                time.sleep(0.001)

    def _run(self) -> None:
        period = 1.0 / CONTROL_HZ
        next_send = time.monotonic()
        while not self._closed.is_set():
            # Drain what the host writes to its adapter: "O" when it opens the channel.
            ready, _, _ = select.select([self._master], [], [], max(0.0, min(period, next_send - time.monotonic())))
            if ready:
                try:
                    if b"O\r" in os.read(self._master, 4096):
                        self.opened.set()
                except (BlockingIOError, OSError):
                    pass
            if self.opened.is_set() and time.monotonic() >= next_send:
                with self._lock:
                    if self._send_locked() is None:
                        self.frames_dropped += 1
                next_send = max(next_send + period, time.monotonic())


# --- detecting the response ----------------------------------------------------------------------

def profile_shift(profile: np.ndarray, reference: np.ndarray, *, max_shift: int = 96) -> float:
    """How far the rows of an image moved down from a reference image, pixels, from their row
    luminance profiles (positive: the picture moved down, as when the nose pitches up).

    The whole-pixel shift with the least mean squared difference over the rows the two share,
    refined to a fraction by a parabola through it and its neighbours; at most
    min(max_shift, rows / 4) either way.
    """
    p = np.asarray(profile, np.float64)
    r = np.asarray(reference, np.float64)
    if p.shape != r.shape or p.ndim != 1 or p.size < 4:
        raise ValueError(f"profile: {p.shape} rows against a reference of {r.shape}; expected equal, >= 4")
    n = p.size
    reach = max(1, min(max_shift, n // 4))
    errors = np.empty(2 * reach + 1)
    for i, k in enumerate(range(-reach, reach + 1)):
        diff = p[k:] - r[:n - k] if k >= 0 else p[:n + k] - r[-k:]
        errors[i] = np.mean(diff * diff)
    best = int(np.argmin(errors))
    offset = 0.0
    if 0 < best < 2 * reach:
        below, at, above = errors[best - 1], errors[best], errors[best + 1]
        curvature = below - 2.0 * at + above
        if curvature > 0:
            offset = 0.5 * (below - above) / curvature
    return best - reach + offset


@dataclass
class StepResult:
    """One step of the pitch control and the composite that showed it.

    Attributes:
        index: 1, 2, ...
        direction: "up" (stick aft, nose up) or "down".
        stick_from, stick_to: stick positions, -1 .. 1.
        step_time_unix_s: when the cockpit sent the new position.
        settled: the picture was steady before the step (else the step went after the wait's limit).
        threshold_px: the shift that counts as a response, pixels.
        detected: a response was seen; the fields below are for its composite.
        frame_number: the composite's frame.
        shift_px: how far its rows had moved in the step's direction, pixels.
        latency_ms: step -> composite, milliseconds (None: not detected).
        chain_ms: CONTROL_HOP then HOPS along the channel the composite waited for, milliseconds
            (they add up to latency_ms).
        critical_channel: that channel.
        composites_after_step: composites that came after the step up to and including this one.
        frames_after_eyepoint_change: frames from the first one whose eyepoint had moved in the
            step's direction to this one (0: the image showed the first frame that could show it).
        missed_composites: composites the watch missed during the step (dropped, or incomplete
            frames): when not 0, the response may have come earlier than detected.
        problem: why there is no measurement, or what is doubtful about it; "" when fine.
    """

    index: int
    direction: str
    stick_from: float
    stick_to: float
    step_time_unix_s: float
    settled: bool
    threshold_px: float
    detected: bool = False
    frame_number: int = -1
    shift_px: float = 0.0
    latency_ms: float | None = None
    chain_ms: dict[str, float] = field(default_factory=dict)
    critical_channel: str = ""
    composites_after_step: int = 0
    frames_after_eyepoint_change: int | None = None
    missed_composites: int = 0
    problem: str = ""

    @property
    def measured(self) -> bool:
        """A response was detected and nothing casts doubt on it."""
        return self.detected and not self.problem


def response_chain(step_time: float, c: compositor_pb2.WatchCompositesResponse) -> tuple[dict[str, float], str]:
    """The step's chain in seconds (CONTROL_HOP, then HOPS along the channel whose image the
    compositor received last) and that channel."""
    critical = max(c.channels, key=lambda ch: ch.compositor_receive_unix_s)
    hops = hop_seconds((c.control_sample_time_unix_s, c.publish_time_unix_s, critical.frame_received_unix_s,
                        critical.render_start_unix_s, critical.render_end_unix_s,
                        critical.compositor_receive_unix_s, c.composite_time_unix_s)) or {}
    return {CONTROL_HOP[0]: c.control_sample_time_unix_s - step_time, **hops}, critical.channel_name


class Composites:
    """The compositor's WatchComposites stream, read on a thread into a queue.

    next() returns the next composite, or raises RigFailed when a process failed, the stop flag
    is up, or none came in time.
    """

    def __init__(self, address: str, channel: str, procs: Processes, stop: StopFlag) -> None:
        self.procs = procs
        self.stop = stop
        self.channel = channel
        self._queue: queue.Queue[compositor_pb2.WatchCompositesResponse | Exception | None] = queue.Queue()
        self.seen = 0
        self.last_drops = 0
        self.last_frame = -1
        self._grpc = make_channel(address)
        stub = compositor_pb2_grpc.CompositorServiceStub(self._grpc)
        self._stream = stub.WatchComposites(
            compositor_pb2.WatchCompositesRequest(watcher="ig latency", profile_channels=[channel]),
            wait_for_ready=True, timeout=STREAM_DEADLINE_S)
        self._thread = threading.Thread(target=self._read, name="composites", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for response in self._stream:
                self._queue.put(response)
            self._queue.put(None)
        except grpc.RpcError as exc:
            self._queue.put(exc)

    def next(self, timeout_s: float = _NEXT_COMPOSITE_S) -> compositor_pb2.WatchCompositesResponse:
        """The next composite (the first may take _FIRST_COMPOSITE_S: the workers load their kernels)."""
        deadline = time.monotonic() + (_FIRST_COMPOSITE_S if not self.seen else timeout_s)
        composite = self.poll(deadline)
        if composite is None:
            raise RigFailed(f"no composite for {timeout_s:.0f} s")
        return composite

    def poll(self, deadline: float) -> compositor_pb2.WatchCompositesResponse | None:
        """The next composite, or None if none came by deadline (time.monotonic() seconds)."""
        while True:
            if self.stop.why:
                raise RigFailed(self.stop.why)
            failed = self.procs.failed()
            if failed:
                name, code = next(iter(failed.items()))
                raise RigFailed(f"{name} exited with code {code}")
            try:
                item = self._queue.get(timeout=max(0.0, min(0.2, deadline - time.monotonic())))
            except queue.Empty:
                if time.monotonic() >= deadline:
                    return None
                continue
            if item is None:
                raise RigFailed("the compositor ended its stream (the run is over)")
            if isinstance(item, Exception):
                raise RigFailed(f"composite stream: {item}")
            self.seen += 1
            return item

    def profile(self, c: compositor_pb2.WatchCompositesResponse) -> np.ndarray:
        """The watched channel's row profile of a composite."""
        return np.asarray(c.profiles[0].luminance, np.float32)

    def missed(self, c: compositor_pb2.WatchCompositesResponse) -> int:
        """Composites missed just before c: dropped by the watch, or frames never composited."""
        gap = max(0, c.frame_number - self.last_frame - 1) if self.last_frame >= 0 else 0
        drops = c.watcher_drops - self.last_drops
        self.last_frame, self.last_drops = c.frame_number, c.watcher_drops
        return max(gap, drops)

    def close(self) -> None:
        self._stream.cancel()
        self._grpc.close()


def measure_steps(composites: Composites, cockpit: SlcanCockpit, *, steps: int, levels: tuple[float, float],
                  threshold_px: float, log=print) -> list[StepResult]:
    """Step the pitch control `steps` times between levels and detect each response (module doc).

    The stick starts at the high level, so that the first step, down, runs against the nose
    rising from the runway's 0 degrees to the high level's pitch, as every later step runs
    against what is left of the one before.

    Each step goes at a random moment of the frame cycle, a uniform fraction of the interval
    between composites after the picture settled: stepping right after a composite would
    always catch the host at the same point of its cycle, where Part 60 expects the input
    "at any time in the iteration".

    The waits for the picture to settle and for the response are bounded in the composites'
    simulation time (and a least number of composites), so they hold at any rate, fixed or
    paced by the rig.
    """
    phase = random.Random(0)  # the same moments on every run, for comparable runs
    results: list[StepResult] = []
    position = 1
    previous = composites.next()
    composites.missed(previous)
    for index in range(1, steps + 1):
        # Settle: the picture has stopped moving (the stick lag has run its course).
        quiet, waited, settle_from = 0, 0, previous.sim_time_s
        while quiet < _SETTLE_FRAMES and not _waited_enough(waited, previous.sim_time_s - settle_from,
                                                            _SETTLE_MIN_FRAMES, _SETTLE_MAX_SIM_S):
            c = composites.next()
            shift = profile_shift(composites.profile(c), composites.profile(previous))
            composites.missed(c)
            quiet = quiet + 1 if abs(shift) < threshold_px / 4 else 0
            waited += 1
            interval = c.composite_time_unix_s - previous.composite_time_unix_s
            previous = c
        # A random moment of the cycle; the composites meanwhile move the reference along.
        until = time.monotonic() + phase.uniform(0.0, max(interval, 0.0))
        while (c := composites.poll(until)) is not None:
            composites.missed(c)
            previous = c
        reference = previous
        stick_from, stick_to = levels[position], levels[1 - position]
        sign = 1.0 if stick_to > stick_from else -1.0
        result = StepResult(index, "up" if sign > 0 else "down", stick_from, stick_to, 0.0,
                            settled=quiet >= _SETTLE_FRAMES, threshold_px=threshold_px)
        result.step_time_unix_s = cockpit.set_pitch(stick_to)
        position = 1 - position
        ref_profile, ref_pitch = composites.profile(reference), reference.eyepoint.pitch_deg
        eyepoint_moved: int | None = None
        while True:
            if _waited_enough(result.composites_after_step, previous.sim_time_s - reference.sim_time_s,
                              _RESPONSE_MAX_FRAMES, _RESPONSE_MAX_SIM_S):
                result.problem = (f"no response within {result.composites_after_step} composites "
                                  f"({previous.sim_time_s - reference.sim_time_s:.2f} simulated s)")
                break
            c = composites.next()
            previous = c
            result.composites_after_step += 1
            result.missed_composites += composites.missed(c)
            # Frames published before the step may still drift; the first one after it that moved
            # is the first that could show the step.
            if eyepoint_moved is None and c.publish_time_unix_s >= result.step_time_unix_s \
                    and (c.eyepoint.pitch_deg - ref_pitch) * sign > 0:
                eyepoint_moved = c.frame_number
            shift = profile_shift(composites.profile(c), ref_profile) * sign
            if shift > threshold_px:
                chain_s, critical = response_chain(result.step_time_unix_s, c)
                result.detected = True
                result.frame_number = c.frame_number
                result.shift_px = round(shift, 3)
                result.latency_ms = round((c.composite_time_unix_s - result.step_time_unix_s) * 1000.0, 3)
                result.chain_ms = {k: round(v * 1000.0, 3) for k, v in chain_s.items()}
                result.critical_channel = critical
                result.frames_after_eyepoint_change = (None if eyepoint_moved is None
                                                       else c.frame_number - eyepoint_moved)
                if c.publish_time_unix_s < result.step_time_unix_s:
                    result.problem = "the composite's frame was published before the step: not its response"
                elif result.missed_composites:
                    result.problem = f"{result.missed_composites} composite(s) missed during the step"
                elif not result.settled:
                    result.problem = "the picture had not settled before the step"
                break
        results.append(result)
        log(format_step(result))
    return results


def _waited_enough(frames: int, sim_s: float, min_frames: int, min_sim_s: float) -> bool:
    """A wait of frames composites spanning sim_s simulated seconds has lasted at least min_frames
    composites and min_sim_s simulated seconds."""
    return frames >= min_frames and sim_s >= min_sim_s


# --- the report ----------------------------------------------------------------------------------

def summarise(results: list[StepResult]) -> dict:
    """Percentiles of the measured steps' latency and of each hop of their chain."""
    measured = [r for r in results if r.measured]
    keys = [CONTROL_HOP[0]] + [k for k, _ in HOPS]
    return {
        "steps": len(results),
        "measured": len(measured),
        "control_to_composite": percentiles([r.latency_ms / 1000.0 for r in measured if r.latency_ms is not None]),
        "chain": {k: percentiles([r.chain_ms[k] / 1000.0 for r in measured if k in r.chain_ms]) for k in keys},
        "frames_after_eyepoint_change": sorted({r.frames_after_eyepoint_change for r in measured
                                                if r.frames_after_eyepoint_change is not None}),
    }


def limits_verdict(summary: dict) -> list[dict]:
    """Each Part 60 limit against the longest measured delay (every test must meet it) and the p99."""
    worst, p99 = summary["control_to_composite"]["max_ms"], summary["control_to_composite"]["p99_ms"]
    return [{"limit": name, "limit_ms": round(limit * 1000.0, 3),
             "met_by_max": None if worst is None else worst <= limit * 1000.0,
             "met_by_p99": None if p99 is None else p99 <= limit * 1000.0} for name, limit in PART60_LIMITS]


def format_step(r: StepResult) -> str:
    """One line per step, as they happen."""
    head = f"  step {r.index:3d} {r.direction:<4} stick {r.stick_from:+.2f} -> {r.stick_to:+.2f}"
    if not r.detected:
        return f"{head}: {r.problem}"
    late = "" if r.frames_after_eyepoint_change in (0, None) else \
        f", {r.frames_after_eyepoint_change} frame(s) after the eyepoint moved"
    note = f"  ({r.problem})" if r.problem else ""
    return (f"{head}: frame {r.frame_number}, rows moved {r.shift_px:+.2f} px, "
            f"{r.latency_ms:7.1f} ms{late}{note}")


def host_pace(rate_hz: float | None) -> str:
    """How the host was paced, for the report: by the rig (rate_hz None) or at a fixed rate."""
    if rate_hz is None:
        return f"host paced by the rig (at most {AUTO_RATE_MAX_HZ:g} Hz)"
    return f"host at {rate_hz:g} Hz"


def format_summary(summary: dict, verdicts: list[dict], *, rate_hz: float | None, size: str) -> str:
    """The table `ig latency` prints."""
    labels = dict([CONTROL_HOP, *HOPS])
    rows = [("control step -> composite", summary["control_to_composite"])]
    rows += [(f"  {labels[k]}", p) for k, p in summary["chain"].items()]
    width = max(len(n) for n, _ in rows)
    lines = [f"ig latency: {summary['measured']} of {summary['steps']} steps measured; rig {size}, "
             f"{host_pace(rate_hz)}", "",
             f"  {'milliseconds':<{width}}  {'p50':>9} {'p95':>9} {'p99':>9} {'max':>9}"]
    lines += [f"  {name:<{width}}  {milliseconds_cells(p)}" for name, p in rows]
    lines += ["", "  (the chain follows, for each step, the channel whose image the composite waited for;",
              "   its hops add up to control step -> composite)", "",
              "FAA 14 CFR Part 60 transport delay, control movement -> first visual response:"]
    for v in verdicts:
        worst = summary["control_to_composite"]["max_ms"]
        if worst is None:
            lines.append(f"  {v['limit']}: <= {v['limit_ms']:g} ms; nothing measured")
            continue
        lines.append(f"  {v['limit']}: <= {v['limit_ms']:g} ms: max {worst:.1f} ms "
                     f"{'within' if v['met_by_max'] else 'OVER'}, p99 "
                     f"{summary['control_to_composite']['p99_ms']:.1f} ms "
                     f"{'within' if v['met_by_p99'] else 'OVER'}")
    return "\n".join(lines)


# --- the command ---------------------------------------------------------------------------------

def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig latency`."""
    parser.add_argument("--rate", type=rate_or_auto, default=None,
                        help="auto (default): the host paced by the rig, each frame as soon as every channel "
                             f"acknowledged the last (at most {AUTO_RATE_MAX_HZ:g} Hz), the controls sampled just "
                             "before it; or a fixed host frame rate, Hz. Any rate works: above what the rig "
                             "renders, the host goes as fast as "
                             "the channels acknowledge (frame lock)")
    parser.add_argument("--steps", type=_count, default=10, help="steps of the pitch control to measure (default 10)")
    parser.add_argument("--step-size", type=positive, default=0.5,
                        help="stick travel of each step, a fraction of full travel <= 1, centred on half aft "
                             "stick (default 0.5: between 0.25 and 0.75)")
    parser.add_argument("--threshold", type=positive, default=0.1, metavar="PX",
                        help="rows must move more than this many pixels for a composite to count as the "
                             "response (default 0.1; the picture is otherwise still)")
    parser.add_argument("--channel", default=None,
                        help="channel whose picture is watched (default: the rig's middle channel)")
    parser.add_argument("--out", default="out/latency/latency.json",
                        help="the results as JSON (default out/latency/latency.json)")
    parser.add_argument("--work", default="out/latency",
                        help="directory for the rig file, the processes' logs and the compositor's report "
                             "(default out/latency)")
    add_rig_options(parser, out="WORK")


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} is not >= 1")
    return value


def run(args: argparse.Namespace) -> int:
    """Measure; 0 when every step was measured, 1 otherwise, 2 on bad input, 130 on Ctrl-C."""
    if args.step_size > 1.0:
        error("latency", f"--step-size: {args.step_size:g} is more than the stick's travel from mid-aft (1)")
        return EXIT_BAD_INPUT
    prepared = prepare_rig("latency", args)
    if isinstance(prepared, int):
        return prepared
    rig, scene_path = prepared
    channel = args.channel or rig.channel_names[len(rig.channels) // 2]
    if channel not in rig.channel_names:
        error("latency", f"--channel: {channel!r} is not a channel of the rig ({', '.join(rig.channel_names)})")
        return EXIT_BAD_INPUT
    work, out = Path(args.work), Path(args.out)
    try:
        work.mkdir(parents=True, exist_ok=True)
        (work / "latest").unlink(missing_ok=True)  # the compositor points it at the run it writes
        rig_path = work / "rig.toml"
        rig_path.write_text(rig_toml(rig))
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        error("latency", f"--work/--out: {exc}")
        return EXIT_BAD_INPUT
    levels = (0.5 - args.step_size / 2.0, 0.5 + args.step_size / 2.0)
    spec = rig.channels[0].spec
    size = f"{len(rig.channels)} x {spec.width} x {spec.height}, samples {rig.render.samples}"
    print(f"ig latency: {args.steps} steps of the pitch control ({levels[0]:g} <-> {levels[1]:g}) through "
          f"CANaerospace on slcan; watching channel {channel}; rig {size}; logs in {work / 'logs'}", flush=True)
    procs = Processes(work / "logs", args.verbose)
    with stop_flag() as stop:
        try:
            outcome = _measure(procs, rig, rig_path, ["--scene", scene_path], work, args, channel, levels, stop)
        finally:
            procs.stop_all()
    if stop.why:
        print(f"\nig latency: {stop.why}; every process was stopped")
        return EXIT_INTERRUPTED if stop.why == "interrupted" else EXIT_FAILED
    if isinstance(outcome, str):
        print(f"ig latency: {outcome}; every process was stopped")
        for name in procs.procs:
            tail = procs.log_tail(name, 8)
            if tail and name != "compile":
                print(f"--- last lines of {work / 'logs' / (name + '.log')} ---\n{tail}")
        return EXIT_FAILED
    results = outcome
    rate = args.rate
    summary = summarise(results)
    verdicts = limits_verdict(summary)
    report_path = work / "latest" / "report.json"
    compositor_report = json.loads(report_path.read_text()) if report_path.exists() else None
    doc = {
        "rig": {"channels": list(rig.channel_names), "width": spec.width, "height": spec.height,
                "samples": str(rig.render.samples), "filter": rig.render.filter, "scene": scene_path,
                "threads_per_worker": rig.render.threads},
        # rate_hz: the fixed rate, or null when the host was paced by the rig (at most max_rate_hz).
        "rate_hz": rate, "pace": "ticks" if rate is not None else "acks",
        "max_rate_hz": rate if rate is not None else AUTO_RATE_MAX_HZ,
        "watched_channel": channel, "stick_levels": list(levels), "threshold_px": args.threshold,
        "input": "CANaerospace pitch_control_position over slcan (pseudo-terminal), python-can in the host",
        "summary": summary, "part60": verdicts,
        "steps": [asdict(r) for r in results],
        # Every frame of the run, not only the steps' responses (docs/frame-lock.md).
        "compositor": {k: compositor_report.get(k) for k in (
            "frames_complete", "frames_incomplete", "control_to_composite_latency", "latency_chain",
            "critical_channel", "composite_rate_hz", "render_time", "wire")} if compositor_report else None,
        "machine": machine_summary(),
    }
    out.write_text(json.dumps(doc, indent=2) + "\n")
    print()
    print(format_summary(summary, verdicts, rate_hz=rate, size=size))
    print(f"\nresults: {out}")
    return EXIT_OK if summary["measured"] == summary["steps"] else EXIT_FAILED


def machine_summary() -> dict[str, object]:
    """Where the figures were measured: the date, the CPU model, the cores this process may use
    (every process of the rig ran on them), the load average."""
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass  # not Linux: the model stays unknown
    return {"date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "cpu": cpu,
            "usable_cores": usable_cores(),
            "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}


def _measure(procs: Processes, rig: Rig, rig_path: Path, scene: list[str], work: Path, args: argparse.Namespace,
             channel: str, levels: tuple[float, float], stop: StopFlag) -> list[StepResult] | str:
    """Start the rig, measure, stop the host and let the compositor write its report; the step
    results, or why not.

    With --rate auto the host is paced by the rig (no calibration run: the rate the rig
    sustains is what the compositor reports)."""
    failure: Failure | None = compile_kernels(procs, "latency", rig_path, scene, stop)
    if failure or stop.why:
        return f"{failure[0]} exited with code {failure[1]}" if failure else ""
    start_workers(procs, rig, rig_path, scene)
    compositor = procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(work),
                                            "--record-every", "0", "--exr-every", "0", "--once"])
    cockpit = SlcanCockpit(levels[1])  # where measure_steps starts
    composites = None
    try:
        procs.start("host", ["host", "--rig", str(rig_path), *host_pace_args(args.rate), "--controls", cockpit.url])
        composites = Composites(rig.compositor_address, channel, procs, stop)
        print(f"ig latency: {host_pace(args.rate)}; waiting for the picture to settle before each step", flush=True)
        results = measure_steps(composites, cockpit, steps=args.steps, levels=levels, threshold_px=args.threshold)
    except RigFailed as exc:
        return str(exc)
    finally:
        if composites is not None:
            composites.close()
        # The host's run ends on SIGTERM; the compositor then finishes and writes its report.
        procs.terminate("host")
        wait_for_exit(procs, compositor, stop, timeout_s=30.0)
        cockpit.close()
    print(f"ig latency: the cockpit sent {cockpit.frames_sent} CAN frames ({cockpit.frames_dropped} more while the "
          "host was not reading yet)", flush=True)
    return results
