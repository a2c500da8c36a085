"""`ig host --simhost` and the rig file's [simhost] table: bad values exit 2 with one line
naming the flag or key; the status reports the stream as an input source."""

from __future__ import annotations

import socket
import struct

import pytest

from host_sim.server import eyepoint_source_status
from host_sim.simhost import open_simhost
from services.cli import main
from services.rig.rigfile import RigError, SimHostSpec, default_rig_path, load_rig, rig_toml


def rig_with(tmp_path, table: str):
    path = tmp_path / "rig.toml"
    path.write_text(rig_toml(load_rig(default_rig_path())) + f"\n[simhost]\n{table}\n")
    return path


def test_the_table_survives_a_round_trip(tmp_path):
    path = rig_with(tmp_path, 'url = "fgfs://0.0.0.0:5550"\neye_offset_m = [0.216, 0, -0.319]\n'
                              'timing = "extrapolate"\ndelay_s = 0.03\nmax_extrapolate_s = 0.2\nstale_after_s = 2\n'
                              'origin = [47.0, 8.0, 400.0]')
    rig = load_rig(path)
    assert rig.simhost == SimHostSpec(url="fgfs://0.0.0.0:5550", origin=(47.0, 8.0, 400.0),
                                      eye_offset_m=(0.216, 0.0, -0.319), timing="extrapolate", delay_s=0.03,
                                      max_extrapolate_s=0.2, stale_after_s=2.0)
    again = tmp_path / "again.toml"
    again.write_text(rig_toml(rig))
    assert load_rig(again).simhost == rig.simhost
    assert load_rig(default_rig_path()).simhost == SimHostSpec()


@pytest.mark.parametrize(("table", "message"), [
    ("url = 'fgfs'", "simhost.url: 'fgfs' is not a URL"),
    ("origin = [91, 0, 0]", "simhost.origin"),
    ("eye_offset_m = [1, 2]", r"simhost.eye_offset_m: \[1, 2\] is not \[x forward, y right, z down\]"),
    ("timing = 'smooth'", "simhost.timing: 'smooth' is not one of 'interpolate', 'extrapolate'"),
    ("delay_s = -1", r"simhost.delay_s: -1 is not a number in \[0, 1\]"),
    ("max_extrapolate_s = true", "simhost.max_extrapolate_s"),
    ("stale_after_s = 0", "simhost.stale_after_s"),
    ("port = 5550", r"simhost.port: unknown key \(known: url, origin"),
])
def test_bad_keys_are_named(tmp_path, table, message):
    with pytest.raises(RigError, match=message):
        load_rig(rig_with(tmp_path, table))


@pytest.mark.parametrize("argv,words", [
    (["--simhost-timing", "extrapolate"], "--simhost-timing only apply with --simhost"),
    (["--simhost", "bogus://x:1"], "unknown scheme 'bogus'"),
    (["--simhost"], "--simhost: no URL given and the rig file has no simhost.url"),
    (["--simhost", "fgfs://127.0.0.1"], "is not HOST:PORT"),
    (["--simhost", "fgfs://127.0.0.1:5550?rate=30"], "option 'rate' is not one of a fgfs:// URL (it takes none)"),
    (["--simhost", "xplane://127.0.0.1:49000?rate=fast"], "rate 'fast' is not a number in [1, 1000]"),
    (["--simhost", "xplane://127.0.0.1:49000?request=all"], "request 'all' is not 'rpos' or 'none'"),
])
def test_bad_flags_exit_2_with_one_line(argv, words, capsys):
    assert main(["host", *argv]) == 2
    err = capsys.readouterr().err
    assert "ig host: error: " in err and words in err and len(err.strip().splitlines()) == 1


def test_a_rig_file_error_names_the_key(tmp_path, capsys):
    assert main(["host", "--rig", str(rig_with(tmp_path, "timing = 'smooth'")), "--simhost"]) == 2
    assert "simhost.timing" in capsys.readouterr().err


def test_a_taken_port_exits_1(capsys):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        assert main(["host", "--simhost", f"fgfs://127.0.0.1:{taken.getsockname()[1]}"]) == 1
    assert "--simhost: cannot listen" in capsys.readouterr().err


def test_the_host_status_shows_the_stream_as_an_input_source():
    with open_simhost("fgfs-generic://127.0.0.1:0", origin=(36.6, -84.2, 349.0)) as source, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        sender.sendto(struct.pack(">4d9f", 1.0, 36.6, -84.2, 500.0, 0, 0, 90.0, 0, 0, 0, 0, 0, 0), source.address)
        sender.sendto(b"short", source.address)
        assert source.stream.wait_for(1, timeout_s=10.0)
        fields = eyepoint_source_status(source)
    assert fields["eyepoint_source"] == "simhost"
    (status,) = fields["inputs"]
    assert status.name.startswith("fgfs-generic://127.0.0.1:0") and status.accepted == 1
    assert status.values["heading_deg"] == 90.0 and status.counters["late"] == 0
    # "short" may still be on its way when the pose is in: only what has arrived is counted.
    assert set(status.rejected) <= {"truncated"}
