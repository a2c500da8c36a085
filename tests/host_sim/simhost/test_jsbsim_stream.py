"""A real third-party program drives the rig: JSBSim (its Python package, the c172x take-off
script c1723) streams FGNetFDM over UDP with its own FLIGHTGEAR output, as `fgfs
--native-fdm` does, into `ig host --simhost fgfs://...`; the eyepoints the host publishes must
follow JSBSim's own state.

JSBSim is paced by the wall clock here (its `--realtime` busy-spins and its `--nice` sleeps far
too long in 1.3.3), from 21 s of its script, just before the lift-off at about 25 s, to 29 s,
when the aircraft is climbing through about 20 m. Each output tick (60 Hz) the driver logs the
wall time of the send and JSBSim's state: geodetic latitude, longitude, altitude above sea
level (what FGOutputFG.cpp puts in the datagram) and the Euler angles.

The expected eyepoint of a published frame is computed here independently of the host's code:
JSBSim's logged state interpolated at the frame's publish time less the interpolation delay
([simhost] delay_s), turned into the world through geodetic.enu about the rig's origin, plus
the eye offset in body axes turned by the ZYX Euler angles. Tolerances, and why:
- the median position error 0.1 m and attitude error 0.05 degree: with every process on time
  the host follows JSBSim to millimetres (measured 4-7 mm, 0.02-0.03 degree at most, on the
  2-core development machine); the interpolation between 60 Hz datagrams of a smooth take-off
  adds millimetres, the float32 angles of FGNetFDM 1e-5 degree;
- the largest position error 2 m and attitude error 1 degree: the host stamps a datagram when
  its reader thread gets it, not when JSBSim sent it, so a reader kept off the CPU for a few
  milliseconds shifts the poses in time; at the up to 40 m/s of the climb-out 2 m is 50 ms of
  such slack, and the pitch rate at rotation, about 5 degrees a second, makes 1 degree 200 ms
  (measured at most 0.37-0.63 m and 0.03 degree in six runs on the 2-core machine).
"""

from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import grpc
import numpy as np
import pytest

from ig.v1 import host_pb2, host_pb2_grpc
from services.demo import local_rig
from services.rig.geodetic import enu
from services.rig.rigfile import default_rig_path, load_rig, rig_toml

jsbsim = pytest.importorskip("jsbsim")

ROOT = Path(__file__).resolve().parents[3]
#: The c172x's eye from the point JSBSim reports, body axes x forward, y right, z down, metres
#: (docs/sim-hosts.md: its EYEPOINT less its centre of gravity).
EYE_OFFSET_M = (0.216, 0.0, -0.319)
DELAY_S = 0.05
START_S, END_S = 21.0, 29.0
POSITION_MEDIAN_M, POSITION_MAX_M = 0.1, 2.0
ANGLE_MEDIAN_DEG, ANGLE_MAX_DEG = 0.05, 1.0


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _jsbsim_at(t_s: float, port: int, out_dir: Path):
    """JSBSim on the c172x take-off script, run (unpaced, output off) to t_s, its FLIGHTGEAR
    UDP output to 127.0.0.1:port set up but not yet sending."""
    root = jsbsim.get_default_root_dir()
    fdm = jsbsim.FGFDMExec(root)
    fdm.set_debug_level(0)
    fdm.load_script(os.path.join(root, "scripts", "c1723.xml"))
    directive = out_dir / "fg_out.xml"
    directive.write_text('<?xml version="1.0"?>\n<output name="127.0.0.1" type="FLIGHTGEAR" protocol="UDP" '
                         f'port="{port}" rate="60"/>\n')
    # An absolute path: JSBSim resolves a relative one against its root.
    assert fdm.set_output_directive(str(directive.resolve()))
    fdm.run_ic()
    fdm.disable_output()
    while fdm.get_sim_time() < t_s:
        fdm.run()
    return fdm


def _state(fdm) -> tuple[float, ...]:
    return (fdm["position/lat-geod-deg"], fdm["position/long-gc-deg"], fdm["position/h-sl-ft"] * 0.3048,
            math.degrees(fdm["attitude/phi-rad"]), math.degrees(fdm["attitude/theta-rad"]),
            math.degrees(fdm["attitude/psi-rad"]))


def _stream(fdm, end_s: float) -> list[tuple[float, tuple[float, ...]]]:
    """Run JSBSim to end_s paced by the wall clock, sending its datagrams; (wall time, state)
    after every step (120 Hz). Every second step sends its state at the end of its run (60 Hz
    output); which of the two depends on JSBSim's output counter, so every step is kept."""
    fdm.enable_output()
    log = []
    sim0, wall0 = fdm.get_sim_time(), time.time()
    while fdm.get_sim_time() < end_s:
        fdm.run()
        log.append((time.time(), _state(fdm)))
        ahead = (fdm.get_sim_time() - sim0) - (time.time() - wall0)
        if ahead > 0:
            time.sleep(ahead)
    return log


def _expected(state: tuple[float, ...], origin: tuple[float, float, float]) -> tuple[np.ndarray, float, float, float]:
    """The eyepoint of one JSBSim state: position through geodetic.enu, plus the eye offset
    turned from body axes (x forward, y right, z down) to north-east-down by the ZYX Euler
    angles, then to east-north-up."""
    lat, lon, h, phi, theta, psi = state
    ref = np.asarray(enu(np.array([lat]), np.array([lon]), np.array([h]), origin)).reshape(3)
    cp, sp = math.cos(math.radians(psi)), math.sin(math.radians(psi))
    ct, st = math.cos(math.radians(theta)), math.sin(math.radians(theta))
    cf, sf = math.cos(math.radians(phi)), math.sin(math.radians(phi))
    body_to_ned = np.array([
        [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
        [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
        [-st, sf * ct, cf * ct]])
    n, e, d = body_to_ned @ np.asarray(EYE_OFFSET_M)
    return ref + np.array([e, n, -d]), psi % 360.0, theta, phi


def _interpolate(log, t: float) -> tuple[float, ...] | None:
    times = [w for w, _ in log]
    k = int(np.searchsorted(times, t))
    if k == 0 or k >= len(log):
        return None
    (t0, a), (t1, b) = log[k - 1], log[k]
    f = (t - t0) / (t1 - t0)
    out = [x + f * (y - x) for x, y in zip(a, b, strict=True)]
    # Heading on the shorter arc (it stays near 200 degrees in this script, but say so).
    dpsi = (b[5] - a[5] + 180.0) % 360.0 - 180.0
    out[5] = a[5] + f * dpsi
    return tuple(out)


def test_jsbsim_take_off_streamed_to_ig_host_is_followed(tmp_path):
    port = _free_udp_port()
    fdm = _jsbsim_at(START_S, port, tmp_path)
    lat, lon, _h, *_ = _state(fdm)
    origin = (round(lat, 6), round(lon, 6), 0.0)
    rig = local_rig(load_rig(default_rig_path()))
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_toml(rig) + f"\n[simhost]\norigin = [{origin[0]}, {origin[1]}, 0.0]\n"
                        f"eye_offset_m = [{EYE_OFFSET_M[0]}, {EYE_OFFSET_M[1]}, {EYE_OFFSET_M[2]}]\n"
                        f'timing = "interpolate"\ndelay_s = {DELAY_S}\n')
    # The host's log to a file: it warns of the absent channels on every frame, and a pipe
    # nobody reads until the end fills and blocks it.
    log_path = tmp_path / "host.log"
    with open(log_path, "w") as log_file:
        host = subprocess.Popen(
            [sys.executable, "-m", "services.cli", "host", "--rig", str(rig_path), "--simhost",
             f"fgfs://127.0.0.1:{port}", "--rate", "60", "--duration", "30", "--start-timeout", "0"],
            cwd=ROOT, stdout=log_file, stderr=subprocess.STDOUT, text=True)
    frames: list = []
    try:
        channel = grpc.insecure_channel(rig.host_address)
        grpc.channel_ready_future(channel).result(timeout=60)
        stub = host_pb2_grpc.HostServiceStub(channel)
        stream = stub.SubscribeFrames(host_pb2.SubscribeFramesRequest(subscriber="jsbsim-test"), timeout=120)

        def collect():
            try:
                for response in stream:
                    frames.append(response.frame)
            except grpc.RpcError:
                pass  # cancelled at the end of the test

        reader = threading.Thread(target=collect, daemon=True)
        reader.start()
        time.sleep(0.5)  # the subscription is registered before the first datagram
        log = _stream(fdm, END_S)
        time.sleep(2 * DELAY_S + 0.2)
        stream.cancel()
        reader.join(timeout=5)
        channel.close()
    finally:
        host.terminate()
        host.wait(timeout=30)
        output = log_path.read_text()
    assert frames, f"the host published nothing; its log:\n{output[-3000:]}"

    errors_m, errors_deg, heights = [], [], []
    for frame in frames:
        state = _interpolate(log, frame.publish_time_unix_s - DELAY_S)
        if state is None:
            continue  # before the first datagram's delay had passed, or after the last
        position, heading, pitch, roll = _expected(state, origin)
        ep = frame.eyepoint
        got = np.array([ep.x, ep.y, ep.z])
        errors_m.append(float(np.linalg.norm(got - position)))
        dh = (ep.heading_deg - heading + 180.0) % 360.0 - 180.0
        errors_deg.append(max(abs(dh), abs(ep.pitch_deg - pitch), abs(ep.roll_deg - roll)))
        heights.append(position[2])
    assert len(errors_m) > 0.8 * 60 * (END_S - START_S) / 2, f"only {len(errors_m)} frames compared"
    print(f"JSBSim -> ig host: {len(errors_m)} frames; eye rose {max(heights) - min(heights):.1f} m; position error "
          f"max {max(errors_m):.3f} m, median {float(np.median(errors_m)):.3f} m; attitude error max "
          f"{max(errors_deg):.3f} deg")
    # The window spans the lift-off: the eye rose by more than 10 m while it was followed.
    assert max(heights) - min(heights) > 10.0
    assert float(np.median(errors_m)) < POSITION_MEDIAN_M and max(errors_m) < POSITION_MAX_M
    assert float(np.median(errors_deg)) < ANGLE_MEDIAN_DEG and max(errors_deg) < ANGLE_MAX_DEG


def test_every_jsbsim_datagram_decodes_to_the_state_jsbsim_sent(tmp_path):
    """The receiver alone, datagram by datagram: each pose is JSBSim's state as it sent it,
    to float64 for the position (1e-9 degree, 1 mm) and float32 for the angles (1e-4 degree)."""
    from host_sim.simhost import open_simhost

    with open_simhost("fgfs://127.0.0.1:0", origin=(29.76, -95.17, 0.0)) as source:
        fdm = _jsbsim_at(24.0, source.address[1], tmp_path)
        arriving = source.stream.poses(timeout_s=2.0)
        log = _stream(fdm, 26.0)
        poses = list(arriving)
    # Every second step sent its state: 2 s at 60 Hz, none lost on the loopback.
    assert abs(len(poses) - len(log) / 2) <= 1 and len(poses) >= 110
    first = min((0, 1), key=lambda k: abs(poses[0].lat_deg - log[k][1][0]))
    for pose, (_wall, (lat, lon, h, phi, theta, psi)) in zip(poses, log[first::2], strict=False):
        assert pose.lat_deg == pytest.approx(lat, abs=1e-9) and pose.lon_deg == pytest.approx(lon, abs=1e-9)
        assert pose.alt_m == pytest.approx(h, abs=1e-3)
        assert (pose.heading_deg - psi + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-4)
        assert pose.pitch_deg == pytest.approx(theta, abs=1e-4)
        assert pose.roll_deg == pytest.approx(phi, abs=1e-4)
