"""A CIGI 3.3 host drives the real rig: `ig host --cigi`, three workers, the compositor, and
the scripted host (host_sim/cigi/scripted_host.py) over UDP.

The scripted host flies the ownship north over the bundled airfield at 300 m with HOT, HAT,
extended HOT and LOS vector requests straight down, answering every Start of Frame once, then
falls silent; then a host starts again from frame 0. Every stitched frame must carry the host
frame it shows and exactly the eyepoint the geodetic conversion makes of that frame's ownship;
the heights must be the bundled terrain's (the same query code, run here on the scene file);
the host must be reported stale once silent, the latency report must count the host's frames,
and the restarted host must make a new run beside the first, which keeps its files.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from host_sim.cigi import packets as pk
from host_sim.cigi.geometry import pose_of_geodetic
from host_sim.cigi.scripted_host import Keyframe, Query, Script, ScriptedHost
from services.demo import local_rig
from services.rig.image_io import read_image
from services.rig.rigfile import default_rig_path, load_rig, rig_toml

from .conftest import kill_all, start, wait_all

pytestmark = pytest.mark.integration

W, H = 64, 48
RATE = 10.0
HOST_FRAMES = 30
RESTART_FRAMES = 10
SILENT_S = 1.0
DURATION_S = 7.0  # 71 IG frames: 31 of the first host, held while silent, then the second host's


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def script(origin) -> Script:
    lat, lon, h = origin
    north = 0.009  # about 1 km
    path = (Keyframe(0.0, lat - north / 2, lon, h + 300.0, 0.0, 2.0, 0.0),
            Keyframe(HOST_FRAMES / RATE, lat + north / 2, lon, h + 300.0, 10.0, 2.0, 5.0))
    return Script(path=path, frame_rate_hz=RATE, queries=(
        Query(host_frame=2, kind="hot", every=4),
        Query(host_frame=2, kind="hat", every=4),
        Query(host_frame=3, kind="hot_extended", every=4),
        Query(host_frame=3, kind="los_vector", every=4),
        # 60 km east: outside the bundled terrain and every polygon.
        Query(host_frame=5, kind="hot", params={"lon": lon + 0.7}),
    ))


@pytest.fixture(scope="module")
def cigi_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cigi")
    rig = local_rig(load_rig(default_rig_path()).with_size(W, H))
    listen, reply = free_udp_port(), free_udp_port()
    rig = replace(rig, cigi=replace(rig.cigi, listen=f"127.0.0.1:{listen}", host_port=reply, stale_after_s=0.5,
                                    query_channel="centre"))
    rig_path = tmp / "rig.toml"
    rig_path.write_text(rig_toml(rig))
    out = tmp / "out"
    procs, logs = {}, {}
    argv = {
        "compositor": ["compositor", "--out", str(out), "--exr-every", "1", "--once"],
        **{f"worker-{ch.name}": ["worker", "--channel", ch.name, "--samples", "1", "--once"] for ch in rig.channels},
        "host": ["host", "--rate", str(RATE), "--duration", str(DURATION_S), "--cigi", "--sync-timeout", "20"],
    }
    host = ScriptedHost(script(rig.cigi.origin), ig_address=("127.0.0.1", listen), bind=("127.0.0.1", reply),
                        origin=rig.cigi.origin)
    again: list[ScriptedHost] = []
    status: list[subprocess.CompletedProcess] = []
    try:
        for name, args in argv.items():
            logs[name] = open(tmp / f"{name}.log", "w")  # noqa: SIM115  (closed when the run ends)
            procs[name] = start([*args, "--rig", str(rig_path)], logs[name])
        # The workers compile and load before the first frame: the first Start of Frame may be
        # minutes away on a cold kernel cache.
        def play() -> None:
            host.run(frames=HOST_FRAMES, sof_timeout_s=300.0)
            host.close()  # its port is the second host's
            status.append(subprocess.run([sys.executable, "-m", "services.cli", "status", "--rig", str(rig_path)],
                                         capture_output=True, text=True, timeout=30))
            time.sleep(SILENT_S)
            again.append(ScriptedHost(script(rig.cigi.origin), ig_address=("127.0.0.1", listen),
                                      bind=("127.0.0.1", reply), origin=rig.cigi.origin))
            again[0].run(frames=RESTART_FRAMES, sof_timeout_s=10.0)

        player = threading.Thread(target=play)
        player.start()
        codes = wait_all(procs)
        player.join(10.0)
    finally:
        kill_all(procs, logs)
        host.close()
        for h in again:
            h.close()
    runs = sorted((out / "runs").iterdir(), key=lambda p: p.stat().st_mtime)
    reports = [json.loads((r / "report.json").read_text()) for r in runs if (r / "report.json").exists()]
    return {"rig": rig, "out": out, "codes": codes, "host": host, "runs": runs, "status": status,
            "logs": {n: (tmp / f"{n}.log").read_text() for n in argv},
            "report": reports[0] if reports else {}, "reports": reports}


def test_the_rig_runs_to_its_end_and_every_frame_is_complete(cigi_run):
    assert cigi_run["codes"] == dict.fromkeys(cigi_run["codes"], 0), cigi_run["logs"]
    reports = cigi_run["reports"]
    assert len(reports) == 2, cigi_run["logs"]["host"]
    assert sum(r["frames_published"] for r in reports) == int(DURATION_S * RATE) + 1
    for report in reports:
        assert report["frames_complete"] == report["frames_published"]
    report = cigi_run["report"]
    assert reports[1]["host"]["runs"] == 2
    cigi = report["host"]["cigi"]
    assert report["host"]["eyepoint_source"] == "cigi"
    assert cigi["version"] == "3.3" and cigi["byte_order"] == "little" and cigi["mode"] == "sync"
    # The first IG Control, then one per Start of Frame; the status is the host's when the next
    # run began, so the restarted host's first message may be in it.
    assert HOST_FRAMES + 1 <= int(cigi["messages"]) <= HOST_FRAMES + 2
    assert cigi["refused"] == {} and int(cigi["messages_dropped"]) == 0
    assert int(cigi["queries_failed"]) == 0
    # Silent after its last frame: reported stale, its last eyepoint held; the second host too.
    assert int(cigi["stale_events"]) == 1
    last = reports[1]["host"]["cigi"]
    assert last["stale"] is True and int(last["stale_events"]) == 2 and int(last["restarts"]) == 1


def test_ig_status_shows_the_cigi_session_while_the_rig_runs(cigi_run):
    [done] = cigi_run["status"]
    assert done.returncode == 0, done.stderr
    status = json.loads(done.stdout)
    assert status["eyepoint_source"] == "cigi"
    cigi = status["cigi"]
    assert cigi["version"] == "3.3" and cigi["ig_mode"] == "operate"
    assert int(cigi["packets"]["IG Control"]) >= HOST_FRAMES and int(cigi["packets"]["HAT/HOT Request"]) > 0
    assert cigi["listen"].endswith(cigi_run["rig"].cigi.listen.rpartition(":")[2])


def test_a_restarted_host_makes_a_new_run_and_the_first_keeps_its_frames(cigi_run):
    first, second = cigi_run["runs"]
    assert first.name != second.name and (cigi_run["out"] / "latest").resolve() == second.resolve()
    for run, frames in ((first, HOST_FRAMES), (second, RESTART_FRAMES)):
        shown = [int(read_image(p)[1]["host_frame_number"]) for p in sorted((run / "frames").glob("frame_*.exr"))]
        assert shown and shown[0] == 0 and shown == sorted(shown) and max(shown) == frames, run.name
    assert (first / "frames" / "frame_000000.exr").is_file()


def test_every_stitched_frame_carries_its_host_frame_and_that_frames_ownship(cigi_run):
    host, origin = cigi_run["host"], cigi_run["rig"].cigi.origin
    exrs = sorted((cigi_run["runs"][0] / "frames").glob("frame_*.exr"))
    assert len(exrs) == cigi_run["report"]["frames_published"]
    shown = []
    for path in exrs:
        _, attrs = read_image(path)
        host_frame = int(attrs["host_frame_number"])
        shown.append(host_frame)
        k = host.script.pose(host.time_s(host_frame))
        # The angles travel as float32 (Entity Control), the position as float64.
        yaw, pitch, roll = (float(np.float32(a)) for a in (k.yaw, k.pitch, k.roll))
        pose = pose_of_geodetic(k.lat, k.lon, k.alt_m, yaw, pitch, roll, origin)
        eyepoint = tuple(float(v) for v in attrs["eyepoint"].split())
        np.testing.assert_allclose(eyepoint[:3], pose.position, atol=1e-6, err_msg=path.name)
        assert eyepoint[3:] == (pose.heading_deg, pose.pitch_deg, pose.roll_deg)  # bitwise
    # Synchronous: each host frame shown once, in order, then the last one held.
    assert shown == sorted(shown)
    assert sorted(set(shown)) == list(range(shown[0], HOST_FRAMES + 1))
    frames = cigi_run["report"]["host_frames"]
    assert frames["skipped"] == 0 and frames["last"] == HOST_FRAMES
    assert frames["repeated"] == len(shown) - len(set(shown))


def test_heights_and_sight_lines_are_the_bundled_databases(cigi_run):
    from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
    from channel_worker.query.heights import height_of_terrain
    from host_sim.cigi.geometry import height_of_world, point_and_up

    host, origin = cigi_run["host"], cigi_run["rig"].cigi.origin
    database = load_scene(bundled_scene_path())
    sent = {p.request_id: p for s in host.sent for p in s.packets if isinstance(p, pk.HatHotRequest)}
    got = [r.packet for r in host.responses]
    kinds = {type(p) for p in got}
    assert {pk.HatHotResponse, pk.HatHotExtendedResponse, pk.LosResponse} <= kinds
    checked = 0
    for p in got:
        if isinstance(p, pk.HatHotResponse) and p.request_id in sent:
            req = sent[p.request_id]
            if abs(req.lon_y - origin[1]) > 0.5:
                assert not p.valid  # outside the databases
                continue
            assert p.valid
            point, up = point_and_up(req.lat_x, req.lon_y, req.alt_z, origin)
            base = point - point[2] / up[2] * up
            # Near the origin the vertical leans by 1e-4: three fixed-point steps as the service.
            z = 0.0
            for _ in range(3):
                q = base + z / up[2] * up
                z = float(height_of_terrain(database, q[:1], q[1:2], np.array([np.inf])).height_m[0])
            hot = height_of_world(base + z / up[2] * up, origin)
            expected = hot if p.response_type == 1 else req.alt_z - hot
            assert p.height == pytest.approx(expected, abs=1e-3)
            checked += 1
    assert checked >= 8
    for p in got:
        if isinstance(p, pk.LosResponse):
            assert p.valid and not p.visible and 250.0 < p.range < 400.0  # straight down from 300 m
        if isinstance(p, pk.HatHotExtendedResponse):
            assert p.valid and p.material >= 1 and 0.0 < p.hat < 400.0 and p.normal_elevation > 45.0
    # Each answer comes with the Start of Frame after the one its request answered, carrying
    # that request's host frame nibble.
    lsns = {r.packet.host_frame_lsn for r in host.responses}
    assert lsns <= set(range(16)) and len(lsns) > 1
