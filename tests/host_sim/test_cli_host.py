"""`ig host` option errors exit 2 with a named error before anything is served."""

from __future__ import annotations

import socket

import pytest

from services.cli import main


@pytest.fixture
def csv_log(tmp_path):
    path = tmp_path / "f.csv"
    path.write_text("time_s,x_m,y_m,z_m\n0,0,0,10\n1,0,40,10\n2,0,80,12\n")
    return path


@pytest.mark.parametrize("argv,words", [
    (["--speed", "2"], "--speed only apply with --replay"),
    (["--loop", "--start", "1"], "--start, --loop only apply with --replay"),
    (["--stale-after", "1"], "--stale-after only apply with --controls"),
    (["--end-after-silence", "2"], "--end-after-silence only apply with --cigi"),
    (["--controls", "bogus://x"], "bogus://x: unknown control source scheme"),
    (["--controls", "can://virtual/cli-test?bitrat=1"], "option 'bitrat' is not a CAN bus option"),
    (["--replay", "/nonexistent/flight.igc"], "no such file"),
])
def test_bad_sources_exit_2(argv, words, capsys):
    assert main(["host", *argv]) == 2
    err = capsys.readouterr().err
    assert "ig host: error: " in err and words in err


def test_errors_name_the_problem(csv_log, capsys):
    assert main(["host", "--replay", str(csv_log), "--start", "5"]) == 2
    assert "start: 5.0 s is outside the log (0 .. 2.000 s)" in capsys.readouterr().err
    bad = csv_log.with_name("bad.csv")
    bad.write_text("time_s,x_m,y_m,z_m\n0,0,0,10\nx,y,z,w\n")
    assert main(["host", "--replay", str(bad)]) == 2
    assert "bad.csv: 1 usable record(s), need at least 2 (corrupt 1)" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--controls", "can://virtual/x", "--replay", "f.csv"],
                                  ["--replay", "f.csv", "--replay-origin", "100,0,0"],
                                  ["--replay", "f.csv", "--replay-format", "kml"],
                                  ["--replay", "f.csv", "--speed", "0"],
                                  ["--pace", "fast"]])
def test_bad_options_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["host", *argv])
    assert exc.value.code == 2


def test_a_binary_igc_log_is_named_as_no_text_log(tmp_path, capsys):
    garbage = tmp_path / "garbage.igc"
    garbage.write_bytes(bytes(range(256)) * 20)
    assert main(["host", "--replay", str(garbage)]) == 2
    err = capsys.readouterr().err
    assert "ig host: error: garbage.igc: not a text IGC log (" in err and "usable record" not in err


@pytest.mark.parametrize("argv,words", [
    # .invalid never resolves (RFC 6761); 192.0.2.1 (TEST-NET-1) is no machine's own address.
    (["--cigi", "udp://nohost.invalid"], "--cigi: 'udp://nohost.invalid': cannot listen there: no such host"),
    (["--cigi", "udp://192.0.2.1:8000"],
     "--cigi: 'udp://192.0.2.1:8000': cannot listen there: not an address of this machine"),
    (["--simhost", "fgfs://nohost.invalid:5550"],
     "--simhost: 'fgfs://nohost.invalid:5550': cannot listen there: no such host"),
])
def test_a_listen_address_that_is_not_this_machines_exits_2(argv, words, capsys):
    assert main(["host", *argv, "--duration", "0"]) == 2
    err = capsys.readouterr().err
    assert f"ig host: error: {words}" in err and len(err.strip().splitlines()) == 1


def test_a_taken_cigi_port_exits_1(capsys):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        assert main(["host", "--cigi", f"udp://127.0.0.1:{taken.getsockname()[1]}", "--duration", "0"]) == 1
    assert "--cigi: cannot listen" in capsys.readouterr().err


class _Silence:
    """A CIGI session's silent_for(): None until the host's first message, then the given
    seconds in turn (the last repeated)."""

    def __init__(self, *values):
        self.values = list(values)

    def silent_for(self):
        return self.values.pop(0) if len(self.values) > 1 else self.values[0]


def test_the_run_ends_once_the_cigi_host_has_gone_silent():
    import threading

    from host_sim.cli_host import end_when_silent

    stop = threading.Event()
    # Nothing yet, then messages 0.1 and 1.5 s ago, then 2.5 s of silence: past the 2 s asked.
    end_when_silent(_Silence(None, None, 0.1, 1.5, 2.5), 2.0, stop, poll_s=0.001)
    assert stop.is_set()


def test_a_cigi_host_that_never_spoke_does_not_end_the_run():
    import threading

    from host_sim.cli_host import end_when_silent

    stop = threading.Event()
    watcher = threading.Thread(target=end_when_silent, args=(_Silence(None), 0.01, stop, 0.001))
    watcher.start()
    watcher.join(0.2)
    assert watcher.is_alive() and not stop.is_set()  # still waiting for a first message
    stop.set()  # SIGTERM's way: the watcher returns
    watcher.join(1.0)
    assert not watcher.is_alive()
