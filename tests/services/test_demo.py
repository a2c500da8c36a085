"""`ig demo`'s own numbers: the time to its first stitched frame and the flight apart from the
compile and the rig's start (the whole demo runs in tests/integration/test_demo.py)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from services.demo import Timeline, demo_times, format_times, process_start_time
from services.rig.rigfile import default_rig_path

#: When this module was imported: the pytest process had started before.
IMPORTED = time.time()


def test_the_first_frame_counts_from_the_start_and_the_flight_from_its_first_composite():
    timeline = Timeline(started=1000.0, compile_s=30.0, rig_started=1033.5)
    doc = {"first_composite_time": 1041.5, "last_composite_time": 1061.5, "frames_complete": 31}
    times = demo_times(timeline, doc, ended=1064.0, simulated_s=20.0)
    assert times == {"first_frame_s": 41.5, "total_s": 64.0, "compile_s": 30.0, "rig_start_s": 8.0,
                     "flight_wall_s": 20.0, "flight_frames": 31, "flight_rate_hz": 1.5, "flight_simulated_s": 20.0}
    text = format_times(times)
    assert text.splitlines() == [
        "first stitched frame 41.5 s after ig demo started (kernels 30.0 s, then the rig's start to its first "
        "frame 8.0 s)",
        "the flight: 31 stitched frames in 20.0 s wall-clock (1.50 Hz) for 20 simulated seconds",
        "64 s in all"]


def test_without_a_composite_the_demo_says_so():
    times = demo_times(Timeline(started=10.0), {"first_composite_time": None, "last_composite_time": None,
                                                "frames_complete": 0}, ended=15.0, simulated_s=20.0)
    assert times["first_frame_s"] is None and times["flight_wall_s"] is None and times["flight_rate_hz"] is None
    assert format_times(times).splitlines() == ["no stitched frame", "5 s in all"]


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="reads the start time from Linux /proc")
def test_the_process_start_is_the_process_s_not_the_call_s():
    # The pytest process started before it imported this module, and after the machine booted.
    started = process_start_time()
    uptime_s = float(Path("/proc/uptime").read_text().split()[0])
    assert time.time() - uptime_s <= started <= IMPORTED


# -- ig demo --replay ---------------------------------------------------------------------------

def test_replay_takes_a_sample_by_name_and_flies_it_round_the_rigs_origin():
    from host_sim.replay.samples import sample_path
    from services.cli import build_parser
    from services.demo import replay_host_args
    from services.rig.rigfile import load_rig

    args = build_parser("demo").parse_args(["demo", "--replay", "circuit"])
    assert args.replay == "circuit"
    rig = load_rig(default_rig_path())
    host_args, duration_s = replay_host_args("circuit", rig)
    lat, lon, h = rig.cigi.origin
    assert host_args == ["--replay", str(sample_path("circuit")), "--replay-origin", f"{lat!r},{lon!r},{h!r}"]
    assert duration_s == pytest.approx(147.0)
    # The options parse as ig host's, and the host reads the same log.
    host = build_parser("host").parse_args(["host", *host_args])
    assert host.replay_origin == rig.cigi.origin


def test_a_log_file_is_taken_by_its_path(tmp_path):
    from services.demo import replay_host_args
    from services.rig.rigfile import load_rig

    log = tmp_path / "mine.csv"
    log.write_text("time_s,x_m,y_m,z_m\n0,0,-900,3\n1,0,-860,3\n2,0,-800,5\n")
    host_args, duration_s = replay_host_args(str(log), load_rig(default_rig_path()))
    assert host_args[:2] == ["--replay", str(log)] and duration_s == 2.0


@pytest.mark.parametrize("argv,message", [
    (["--replay", "circiut"], "ig demo: error: --replay: 'circiut' is neither a bundled flight (departure, circuit, "
                              "low-pass) nor a file"),
    (["--replay", "circuit", "--fdm", "point-mass"],
     "ig demo: error: --replay 'circuit' and --fdm 'point-mass' are two sources of the flight; give one"),
    (["--replay", "{garbage}"], "ig demo: error: --replay: garbage.igc: not a text IGC log ("),
])
def test_a_replay_that_cannot_fly_exits_2_before_anything_starts(tmp_path, capsys, argv, message):
    from services.cli import main

    garbage = tmp_path / "garbage.igc"
    garbage.write_bytes(bytes(range(256)) * 20)
    argv = [a.format(garbage=garbage) for a in argv]
    out = tmp_path / "demo"
    assert main(["demo", *argv, "--scene", "airfield", "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_the_local_rig_moves_the_metrics_ports_set_to_free_ones_too():
    from dataclasses import replace

    from services.demo import local_rig
    from services.rig.rigfile import load_rig

    rig = load_rig(default_rig_path())
    assert local_rig(rig).host_metrics_port == 0  # none set, none made
    chans = tuple(replace(ch, metrics_port=50261 + i) for i, ch in enumerate(rig.channels))
    local = local_rig(replace(rig, host_metrics_port=50250, compositor_metrics_port=50251, channels=chans))
    ports = [local.host_metrics_port, local.compositor_metrics_port, *(ch.metrics_port for ch in local.channels)]
    assert all(ports)  # free ports of this machine, as the addresses
    assert [ch.metrics_port for ch in local_rig(replace(rig, channels=chans[:1] + rig.channels[1:])).channels][1:] \
        == [0, 0]
