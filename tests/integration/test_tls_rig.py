"""The real rig over mutual TLS: host, two workers and the compositor as processes on localhost,
with a rig file whose [tls] table names certificates made by `ig certs` (docs/security.md).

One short run is shared by the tests of this module. While it runs, the fixture checks that every
process serves a client holding a certificate of the rig's CA, and that a plaintext client and a
client with another CA's certificate get nothing from the host.

Needs the services to take their security from the rig (services.rig.cli_common.security_of
passed to every make_channel, bind and check_health of the host, the worker and the compositor).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import grpc
import pytest

from services.demo import free_port
from services.rig.certs import write_certs
from services.rig.cli_common import security_of
from services.rig.grpc_util import Security, check_health
from services.rig.rigfile import load_rig

from .conftest import ROOT, kill_all, start, wait_all

pytestmark = pytest.mark.integration

W, H = 64, 48
RATE, DURATION = 20.0, 1.5

CHANNEL = """
[[channels]]
name = "{name}"
address = "127.0.0.1:{port}"
yaw_deg = {yaw}
left_deg = -30.0
right_deg = 30.0
bottom_deg = -22.5
top_deg = 22.5
width = {w}
height = {h}
"""


def rig_text() -> str:
    """A two-channel rig on free loopback ports, tiny channels, one sample a pixel."""
    text = (f'[host]\naddress = "127.0.0.1:{free_port()}"\n\n[compositor]\naddress = "127.0.0.1:{free_port()}"\n\n'
            f'[render]\nsamples = "centre"\n')
    for name, yaw in (("left", -30.0), ("right", 30.0)):
        text += CHANNEL.format(name=name, port=free_port(), yaw=yaw, w=W, h=H)
    return text


def wait_serving(address, proc, security, timeout_s=300.0):
    """The health status of a process once it is SERVING over TLS (a worker answers NOT_SERVING
    while its kernels compile); its last status after timeout_s, or EXITED if it died first."""
    deadline = time.monotonic() + timeout_s
    status = "UNREACHABLE"
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return f"EXITED {proc.returncode}"
        try:
            status = check_health(address, timeout_s=1.0, security=security)
            if status == "SERVING":
                return status
        except grpc.RpcError:
            pass
        time.sleep(0.1)
    return status


def refused(address, security):
    """The health status a check with security gets from address, or the status code of its
    failure ("UNAVAILABLE" for a refused handshake)."""
    try:
        return check_health(address, timeout_s=5.0, security=security)
    except grpc.RpcError as exc:
        return exc.code().name


@pytest.fixture(scope="module")
def tls_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tls-rig")
    rig_path = tmp / "rig.toml"
    rig_path.write_text(rig_text())
    # Every process of this rig is on one machine and reads one rig file: they share the host's
    # certificate (it names 127.0.0.1), as services sharing a machine do.
    write_certs(load_rig(rig_path), tmp / "certs", days=1)
    write_certs(load_rig(rig_path), tmp / "stranger", days=1)
    rig_path.write_text(rig_path.read_text() + '\n[tls]\nca = "certs/ca.pem"\ncert = "certs/host.pem"\n'
                                               'key = "certs/host-key.pem"\n')
    rig = load_rig(rig_path)
    security = security_of(rig)
    stranger = Security.from_files(str(tmp / "certs" / "ca.pem"), str(tmp / "stranger" / "left.pem"),
                                   str(tmp / "stranger" / "left-key.pem"))
    out = tmp / "out"
    logs, procs = {}, {}

    def launch(name, argv):
        logs[name] = open(tmp / f"{name}.log", "w")  # noqa: SIM115  (closed when the run ends)
        procs[name] = start(argv, logs[name])

    result = {"tmp": tmp, "rig": rig}
    try:
        launch("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--once"])
        for ch in rig.channels:
            launch(f"worker-{ch.name}", ["worker", "--rig", str(rig_path), "--channel", ch.name, "--once"])
        launch("host", ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", str(DURATION),
                        "--sync-timeout", "20"])
        # The host serves from its start while it waits for the workers (compiling their
        # kernels) and through the run: ask it first, then at once throw the strangers at it.
        # Plaintext is what this machine's client may use on the loopback, but the host's port
        # speaks TLS only: the handshake fails. So does a certificate of another CA. The host
        # serves the rig's client before and after (so the refusals are not those of a host gone).
        health = {"host": wait_serving(rig.host_address, procs["host"], security)}
        result["strangers"] = {"before": refused(rig.host_address, security),
                               "plaintext": refused(rig.host_address, Security()),
                               "another CA": refused(rig.host_address, stranger),
                               "after": refused(rig.host_address, security)}
        health.update({name: wait_serving(addr, procs[proc], security) for name, addr, proc in
                       [("compositor", rig.compositor_address, "compositor")]
                       + [(ch.name, ch.address, f"worker-{ch.name}") for ch in rig.channels]})
        result["health"] = health
        result["exit"] = wait_all(procs)
    finally:
        kill_all(procs, logs)
    result["logs"] = {name: (tmp / f"{name}.log").read_text() for name in logs}
    report = out / "latest" / "report.json"  # the compositor's newest run
    result["report"] = json.loads(report.read_text()) if report.exists() else {}
    return result


def test_every_process_serves_a_client_with_a_certificate_of_the_rigs_ca(tls_run):
    assert tls_run["health"] == dict.fromkeys(("host", "compositor", "left", "right"), "SERVING"), tls_run["logs"]


def test_frames_complete_over_tls(tls_run):
    assert tls_run["exit"] == dict.fromkeys(("compositor", "worker-left", "worker-right", "host"), 0), tls_run["logs"]
    report = tls_run["report"]
    assert report["frames_complete"] > 0, tls_run["logs"]
    assert not any(report["frames_incomplete"].values()), report["frames_incomplete"]


def test_a_plaintext_client_or_another_cas_certificate_gets_nothing_from_the_host(tls_run):
    assert tls_run["strangers"] == {"before": "SERVING", "plaintext": "UNAVAILABLE", "another CA": "UNAVAILABLE",
                                    "after": "SERVING"}, tls_run["logs"]["host"]


def test_a_host_without_tls_refuses_to_listen_off_the_loopback(tmp_path):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_text())
    proc = subprocess.run([sys.executable, "-m", "services.cli", "host", "--rig", str(rig_path), "--bind", "0.0.0.0",
                           "--duration", "0.1"], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert "plaintext is refused off the loopback" in proc.stderr
