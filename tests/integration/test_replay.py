"""A flight log replayed through the real rig: host --replay, three workers, the compositor.

An IGC log (geodetic fixes, no attitude) is placed over the bundled airfield with
--replay-origin, played from 1 s in at twice its speed, and rendered and composited as
processes over gRPC. Every stitched frame must carry exactly the eyepoint the replay gives for
its frame time (computed here with the same code), and its channels must be the renders of
that eyepoint.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from services.demo import local_rig
from services.rig.image_io import read_image
from services.rig.options import RenderOptions
from services.rig.rigfile import WireSpec, default_rig_path, load_rig, rig_toml

from .conftest import kill_all, start, wait_all

pytestmark = pytest.mark.integration


W, H = 64, 48
RATE, SPEED, START = 10.0, 2.0, 1.0
ORIGIN = (46.5, 7.0, 600.0)  # the geodetic point placed at the world origin


def write_igc(path: Path) -> Path:
    """A glider crossing the airfield northwards at 25 m/s, 30 m up, turning gently right."""
    lines = ["AXXX001", "HFDTE010725"]
    for k in range(8):
        east, north = 2.0 * k * k, -150.0 + 25.0 * k
        lat = ORIGIN[0] + north / 111_200.0
        lon = ORIGIN[1] + east / (111_320.0 * math.cos(math.radians(ORIGIN[0])))
        lat_d, lon_d = int(lat), int(lon)
        lat_m, lon_m = round((lat - lat_d) * 60000), round((lon - lon_d) * 60000)
        lines.append(f"B1200{k:02d}{lat_d:02d}{lat_m:05d}N{lon_d:03d}{lon_m:05d}EA00630{630:05d}")
    path.write_text("\r\n".join(lines) + "\r\n")
    return path


@pytest.fixture(scope="module")
def replay_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("replay")
    # Half floats on the wire (inline: shared memory off): the EXRs are then the renders'
    # values, and the rig's other wire is covered end to end (test_rig.py covers the default).
    rig = replace(local_rig(load_rig(default_rig_path()).with_size(W, H)), wire=WireSpec("half", False))
    rig_path = tmp / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    log = write_igc(tmp / "glider.igc")
    out = tmp / "out"
    procs, logs = {}, {}
    origin = ",".join(str(v) for v in ORIGIN)
    argv = {
        "compositor": ["compositor", "--out", str(out), "--exr-every", "1", "--once"],
        **{f"worker-{ch.name}": ["worker", "--channel", ch.name, "--samples", "1", "--once"] for ch in rig.channels},
        "host": ["host", "--rate", str(RATE), "--replay", str(log), "--speed", str(SPEED), "--start", str(START),
                 "--replay-origin", origin, "--sync-timeout", "20"],
    }
    try:
        for name, args in argv.items():
            logs[name] = open(tmp / f"{name}.log", "w")  # noqa: SIM115  (closed when the run ends)
            procs[name] = start([*args, "--rig", str(rig_path)], logs[name])
        codes = wait_all(procs)
    finally:
        kill_all(procs, logs)
    report_path = out / "latest" / "report.json"
    return {"rig": rig, "out": out, "log": log, "codes": codes,
            "logs": {n: (tmp / f"{n}.log").read_text() for n in argv},
            "report": json.loads(report_path.read_text()) if report_path.exists() else {}}


def expected_replay(log):
    from host_sim.replay import Replay, load_track
    track, _ = load_track(log, origin=ORIGIN)
    return Replay(track, speed=SPEED, start_s=START)


def test_the_replay_runs_to_its_end_and_every_process_exits_cleanly(replay_run):
    assert replay_run["codes"] == dict.fromkeys(replay_run["codes"], 0), replay_run["logs"]
    replay = expected_replay(replay_run["log"])
    frames = int(round(replay.duration_s * RATE)) + 1  # (7 s - 1 s) / 2 at 10 Hz: 31 frames
    report = replay_run["report"]
    assert report["frames_published"] == frames
    assert report["frames_complete"] == frames
    assert report["frames_incomplete"] == {"missing_channel": 0, "eyepoint_mismatch": 0}
    assert "glider.igc (igc): 8 records over 7.0 s, attitude estimated from the track" in replay_run["logs"]["host"]
    # The compositor's report carries the host's account of the replay.
    assert report["host"]["eyepoint_source"] == "replay"
    assert report["host"]["replay"]["format"] == "igc" and report["host"]["replay"]["records"] == "8"
    assert report["host"]["replay"]["attitude_estimated"] is True


def test_every_stitched_frame_has_the_replayed_eyepoint(replay_run):
    replay = expected_replay(replay_run["log"])
    exrs = sorted((replay_run["out"] / "latest" / "frames").glob("frame_*.exr"))
    assert exrs
    for path in exrs:
        n = int(path.stem.split("_")[1])
        _, attrs = read_image(path)
        e = replay.eyepoint_at(n / RATE)
        assert tuple(float(v) for v in attrs["eyepoint"].split()) == (*e.position, e.heading_deg, e.pitch_deg,
                                                                      e.roll_deg), n  # bitwise
    last = replay.eyepoint_at((len(exrs) - 1) / RATE)
    assert last.position[1] == pytest.approx(25.0, abs=1.0)  # at the end of the log: 175 m north of its start
    assert 20.0 < last.position[2] < 40.0 and 0.0 < last.heading_deg < 90.0 and last.roll_deg > 0.0  # right turn


def test_the_channels_are_renders_of_the_replayed_eyepoint(replay_run):
    from channel_worker.pipeline.render import render_frame
    from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene

    database = load_scene(bundled_scene_path())
    replay = expected_replay(replay_run["log"])
    n = 15
    pixels, _ = read_image(replay_run["out"] / "latest" / "frames" / f"frame_{n:06d}.exr")
    eyepoint = replay.eyepoint_at(n / RATE)
    for i, ch in enumerate(replay_run["rig"].channels):
        expected = render_frame(database, ch.spec, eyepoint, RenderOptions(samples=1)).rgb.astype(np.float16)
        np.testing.assert_allclose(pixels[:, i * W:(i + 1) * W], expected.astype(np.float32), rtol=1e-3, atol=1e-3,
                                   err_msg=f"frame {n} channel {ch.name}")
