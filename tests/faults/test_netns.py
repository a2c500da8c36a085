"""Across machines: host and compositor in one network namespace, the workers in another, joined
by a veth pair with 10.x addresses, as two machines on a rig network (plaintext allowed by the
rig file's [tls] allow_plaintext). Every frame completes.

Needs root (CAP_NET_ADMIN) for `ip netns add`; skipped with the reason otherwise. The namespaces
(and with them the veth pair) are deleted in the fixture's finalizer, whatever happened.
"""

from __future__ import annotations

import os
import subprocess

import pytest

from services.rig.rigfile import TlsSpec

from .harness import SCENE, RigProcs, final_report, record, write_rig

pytestmark = pytest.mark.integration

RATE = 20.0
DURATION = 1.0
EXPECTED = int(RATE * DURATION) + 1


def _ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def namespaces():
    """Two namespaces, "host" (10.199.N.1) and "render" (10.199.N.2), linked by a veth pair."""
    tag = f"igf{os.getpid() % 100000}"
    names = {"host": f"{tag}h", "render": f"{tag}r"}
    subnet = f"10.199.{os.getpid() % 250}"
    made: list[str] = []
    try:
        for ns in names.values():
            proc = _ip("netns", "add", ns)
            if proc.returncode != 0:
                pytest.skip(f"ip netns add failed (needs root / CAP_NET_ADMIN): {proc.stderr.strip()}")
            made.append(ns)
        steps = [("link", "add", f"{tag}a", "type", "veth", "peer", "name", f"{tag}b"),
                 ("link", "set", f"{tag}a", "netns", names["host"]),
                 ("link", "set", f"{tag}b", "netns", names["render"]),
                 ("-n", names["host"], "addr", "add", f"{subnet}.1/24", "dev", f"{tag}a"),
                 ("-n", names["render"], "addr", "add", f"{subnet}.2/24", "dev", f"{tag}b")]
        steps += [("-n", ns, "link", "set", dev, "up") for ns in names.values() for dev in ("lo",)]
        steps += [("-n", names["host"], "link", "set", f"{tag}a", "up"),
                  ("-n", names["render"], "link", "set", f"{tag}b", "up")]
        for step in steps:
            proc = _ip(*step)
            assert proc.returncode == 0, f"ip {' '.join(step)}: {proc.stderr}"
        yield names, subnet
    finally:
        # Deleting a namespace deletes the veth end inside it, and with it its peer; a veth
        # still in this namespace (a step failed after creating it) is deleted by name.
        for ns in made:
            _ip("netns", "del", ns)
        _ip("link", "del", f"{tag}a")


def test_frames_complete_across_namespaces(tmp_path, namespaces, kernels):
    names, subnet = namespaces
    host_ip, render_ip = f"{subnet}.1", f"{subnet}.2"
    rig_path = tmp_path / "rig.toml"
    rig = write_rig(rig_path, tls=TlsSpec(allow_plaintext=True),
                    addresses={"host": f"{host_ip}:50150", "compositor": f"{host_ip}:50151",
                               "left": f"{render_ip}:50161", "centre": f"{render_ip}:50162",
                               "right": f"{render_ip}:50163"})
    out = tmp_path / "out"
    procs = RigProcs(tmp_path / "logs")
    in_host = ("ip", "netns", "exec", names["host"])
    in_render = ("ip", "netns", "exec", names["render"])
    try:
        procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--once"], prefix=in_host)
        for ch in rig.channels:
            procs.start(ch.name, ["worker", "--rig", str(rig_path), "--channel", ch.name, "--scene", str(SCENE),
                                  "--once"], prefix=in_render)
        procs.start("host", ["host", "--rig", str(rig_path), "--rate", str(RATE), "--duration", str(DURATION),
                             "--start-timeout", "60"], prefix=in_host)
        codes = {n: procs.wait(n, timeout_s=240) for n in procs.procs}
    finally:
        procs.stop_all()
    report = final_report(out)
    record("netns", addresses=[host_ip, render_ip], exit_codes=codes,
           frames_published=report.get("frames_published"), frames_complete=report.get("frames_complete"))
    assert codes == dict.fromkeys(procs.procs, 0), procs.logs_tail()
    assert report["frames_published"] == report["frames_complete"] == EXPECTED, report
