"""ScriptedHost against a fake IG made of one UDP socket: one IG Control per SOF, the scripted
path and requests, responses recorded with their frame, both byte orders, asynchronous mode,
and the `ig cigi-host` command."""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from host_sim.cigi.codec import decode, encode
from host_sim.cigi.packets import (
    V3_3,
    EntityControl,
    HatHotRequest,
    HatHotResponse,
    IGControl,
    LosVectorRequest,
    Message,
    StartOfFrame,
)
from host_sim.cigi.scripted_host import Keyframe, Query, Script, ScriptedHost, default_script
from services.cli import main

RECV_TIMEOUT_S = 10.0  # only bounds a hang; no test measures time


@pytest.fixture
def fake_ig() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(RECV_TIMEOUT_S)
    yield sock
    sock.close()


def _recv(sock: socket.socket) -> tuple[Message, tuple[str, int]]:
    data, addr = sock.recvfrom(65536)
    return decode(data, sender="host"), addr


def _start(host: ScriptedHost, frames: int) -> threading.Thread:
    thread = threading.Thread(target=host.run, kwargs={"frames": frames, "sof_timeout_s": RECV_TIMEOUT_S})
    thread.start()
    return thread


def _sof(ig_frame: int, last_host_frame: int, *extra: object, order: str = "<") -> bytes:
    return encode([StartOfFrame(ig_mode=1, ig_frame=ig_frame, last_host_frame=last_host_frame), *extra],
                  V3_3, order)  # type: ignore[list-item]


def _nothing_pending(sock: socket.socket) -> bool:
    sock.setblocking(False)
    try:
        sock.recv(65536)
    except BlockingIOError:
        return True
    finally:
        sock.settimeout(RECV_TIMEOUT_S)
    return False


@pytest.mark.parametrize("order", ["<", ">"])
def test_one_ig_control_per_sof_with_path_and_requests(fake_ig: socket.socket, order: str) -> None:
    script = default_script((36.3, -84.2, 100.0))
    frames = 25
    with ScriptedHost(script, ig_address=fake_ig.getsockname(), bind=("127.0.0.1", 0), byte_order=order) as host:
        thread = _start(host, frames)
        first, host_addr = _recv(fake_ig)
        assert first.byte_order == order and first.version == V3_3
        ig0 = first.packets[0]
        assert isinstance(ig0, IGControl) and ig0.ig_mode == 1 and ig0.host_frame == 0
        messages = []
        for ig_frame in range(100, 100 + frames):
            extra = [HatHotResponse(request_id=1, valid=True, response_type=1, height=100.0)] if ig_frame == 111 else []
            fake_ig.sendto(_sof(ig_frame, ig_frame - 100, *extra), host_addr)
            message, _ = _recv(fake_ig)
            messages.append((ig_frame, message))
        thread.join()
        assert _nothing_pending(fake_ig)

    for n, (ig_frame, message) in enumerate(messages, start=1):
        ig = message.packets[0]
        assert isinstance(ig, IGControl)
        assert (ig.host_frame, ig.last_ig_frame, ig.ig_mode, ig.timestamp_valid) == (n, ig_frame, 1, False)
        entity = message.packets[1]
        assert isinstance(entity, EntityControl) and entity.entity_id == 0 and entity.entity_state == 1
        expected = script.pose(n / script.frame_rate_hz)
        assert entity.lat_x == pytest.approx(expected.lat) and entity.lon_y == pytest.approx(-84.2)
        assert entity.alt_z == pytest.approx(400.0)
        kinds = [type(p) for p in message.packets[2:]]
        assert kinds == ([HatHotRequest] if n % 10 == 0 else []) + ([LosVectorRequest] if n % 10 == 5 else [])
        for p in message.packets[2:]:
            if isinstance(p, HatHotRequest):
                assert p.request_type == 1 and p.lat_x == pytest.approx(entity.lat_x)
            if isinstance(p, LosVectorRequest):
                assert p.elevation == -90.0 and p.src_alt_z == pytest.approx(400.0)

    assert [s.ig_frame for s in host.sofs] == list(range(100, 100 + frames))
    assert [(r.ig_frame, type(r.packet)) for r in host.responses] == [(111, HatHotResponse)]
    report = host.report()
    assert report["sof_count"] == frames and report["last_ig_frame"] == 100 + frames - 1
    assert report["responses_by_kind"] == {"HatHotResponse": 1} and report["host_frames_sent"] == frames + 1


def test_bad_datagrams_are_counted_not_answered(fake_ig: socket.socket) -> None:
    with ScriptedHost(Script(path=(Keyframe(0, 1, 2, 3),)), ig_address=fake_ig.getsockname(),
                      bind=("127.0.0.1", 0)) as host:
        thread = _start(host, 1)
        _, host_addr = _recv(fake_ig)
        fake_ig.sendto(b"\x01\x02garbage", host_addr)
        fake_ig.sendto(_sof(7, 0), host_addr)
        message, _ = _recv(fake_ig)
        thread.join()
    assert isinstance(message.packets[0], IGControl) and message.packets[0].last_ig_frame == 7
    assert host.report()["decode_errors"] == {"first_packet": 1}


def test_asynchronous_mode_sends_on_its_own_clock(fake_ig: socket.socket) -> None:
    with ScriptedHost(ig_address=fake_ig.getsockname(), bind=("127.0.0.1", 0), async_rate_hz=200.0) as host:
        thread = _start(host, 5)
        received = [_recv(fake_ig)[0] for _ in range(6)]
        thread.join()
    frames = [m.packets[0].host_frame for m in received]  # type: ignore[union-attr]
    assert frames == [0, 1, 2, 3, 4, 5]
    assert all(m.packets[0].timestamp_valid for m in received)  # type: ignore[union-attr]
    assert received[5].packets[0].timestamp == 5 * 100_000 // 200  # type: ignore[union-attr]


def test_script_json_round_trip_and_errors() -> None:
    script = Script(path=(Keyframe(0, 1, 2, 3), Keyframe(10, 2, 3, 4, 90, 1, 2)),
                    queries=(Query(3, "hat", {"lat": 1.0}, update_period=2), Query(4, "los_segment", every=7)))
    assert Script.from_json(script.to_json()) == script
    assert script.pose(5).lat == pytest.approx(1.5) and script.pose(5).yaw == pytest.approx(45)
    with pytest.raises(ValueError, match="query kind 'radar'"):
        Script(path=(Keyframe(0, 1, 2, 3),), queries=(Query(1, "radar"),))
    with pytest.raises(ValueError, match="script"):
        Script.from_json("{}")


def test_cli_runs_against_the_fake_ig(fake_ig: socket.socket, tmp_path: Path) -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    bind_port = probe.getsockname()[1]
    probe.close()
    ig_port = fake_ig.getsockname()[1]
    report = tmp_path / "report.json"
    result: list[int] = []
    thread = threading.Thread(target=lambda: result.append(main([
        "cigi-host", "--ig", f"127.0.0.1:{ig_port}", "--bind", f"127.0.0.1:{bind_port}", "--frames", "3",
        "--byte-order", "big", "--origin", "36.3,-84.2,0", "--report", str(report)])))
    thread.start()
    first, host_addr = _recv(fake_ig)
    assert first.byte_order == ">"
    for ig_frame in range(3):
        fake_ig.sendto(_sof(ig_frame, 0, order=">"), host_addr)
        _recv(fake_ig)
    thread.join()
    assert result == [0]
    assert json.loads(report.read_text())["sof_count"] == 3


@pytest.mark.parametrize("argv", [["--ig", "nohost"], ["--frames", "0"], ["--origin", "1,2"],
                                  ["--script", "/nonexistent/script.json"]])
def test_cli_bad_input_exits_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = main(["cigi-host", *argv])
    except SystemExit as exc:  # argparse refuses bad option values with exit 2
        code = int(exc.code or 0)
    assert code == 2
