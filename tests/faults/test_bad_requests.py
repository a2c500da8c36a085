"""Malformed, oversized and out-of-range requests to every RPC of a running rig, and a second
service started on a taken port.

Each request gets its status code (INVALID_ARGUMENT naming the message type for bytes that are
not the request, RESOURCE_EXHAUSTED for messages over the service's limit, OUT_OF_RANGE for frame
numbers never published), is counted, and leaves every service SERVING with frames completing.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from google.protobuf import json_format

from ig.v1 import compositor_pb2, frame_pb2, host_pb2
from services.rig.rigfile import SyncSpec

from .harness import (
    ROOT,
    SCENE,
    CompositeWatcher,
    RigProcs,
    compositor_report,
    env,
    health,
    host_status,
    poll,
    published_intervals,
    raw_call,
    record,
    start_rig,
    worker_status,
    write_rig,
)

pytestmark = pytest.mark.integration

W, H = 64, 48
RATE = 20.0
FRAME_TIMEOUT_S = 0.8

#: Not a protobuf message: field 31 with wire type 7, which does not exist.
MALFORMED = b"\xff\xff\xff\xff\x0f"

#: Every RPC of the rig's services: (process, service/method, request type, server streaming).
RPCS = [
    ("host", "ig.v1.HostService/SubscribeFrames", "SubscribeFramesRequest", True),
    ("host", "ig.v1.HostService/AckFrame", "AckFrameRequest", False),
    ("host", "ig.v1.HostService/GetHostStatus", "GetHostStatusRequest", False),
    ("compositor", "ig.v1.CompositorService/SubmitChannelImage", "SubmitChannelImageRequest", False),
    ("compositor", "ig.v1.CompositorService/GetCompositorReport", "GetCompositorReportRequest", False),
    ("compositor", "ig.v1.CompositorService/WatchComposites", "WatchCompositesRequest", True),
    ("left", "ig.v1.ChannelWorkerService/GetWorkerStatus", "GetWorkerStatusRequest", False),
]


@pytest.fixture(scope="module")
def rig(tmp_path_factory, kernels):
    tmp = tmp_path_factory.mktemp("bad-requests")
    rig_path = tmp / "rig.toml"
    rig = write_rig(rig_path, width=W, height=H, sync=SyncSpec(frame_timeout_s=FRAME_TIMEOUT_S))
    procs = RigProcs(tmp / "logs")
    watcher = None
    try:
        start_rig(procs, rig_path, rig, tmp / "out", compositor_args=("--record-every", "0"),
                  host_args=("--rate", str(RATE), "--duration", "100000"))
        watcher = CompositeWatcher(rig.compositor_address)
        poll(lambda: len(watcher.snapshot()) >= 10, what="10 complete frames")
        yield {"rig": rig, "procs": procs, "watcher": watcher, "rig_path": rig_path, "codes": {}}
    finally:
        if watcher is not None:
            watcher.close()
        procs.stop_all()


def _address(rig, process: str) -> str:
    return {"host": rig.host_address, "compositor": rig.compositor_address}.get(process) \
        or rig.channel(process).address


def _serving(rig) -> dict[str, str]:
    return {name: health(_address(rig["rig"], name)) for name in rig["procs"].procs}


@pytest.mark.parametrize("process, method, request_type, stream", RPCS, ids=[m.split("/")[1] for _, m, _, _ in RPCS])
def test_malformed_bytes_are_invalid_argument_naming_the_type(rig, process, method, request_type, stream):
    code, details = raw_call(_address(rig["rig"], process), f"/{method}", MALFORMED, stream=stream)
    rig["codes"][f"malformed {method}"] = code
    assert (code, request_type in details) == ("INVALID_ARGUMENT", True), details
    assert health(_address(rig["rig"], process)) == "SERVING"


@pytest.mark.parametrize("process", ["host", "compositor", "left"])
def test_malformed_health_check_is_invalid_argument(rig, process):
    code, details = raw_call(_address(rig["rig"], process), "/grpc.health.v1.Health/Check", MALFORMED)
    rig["codes"][f"malformed Health/Check ({process})"] = code
    assert code == "INVALID_ARGUMENT", details
    assert health(_address(rig["rig"], process)) == "SERVING"


def test_malformed_requests_are_counted(rig):
    r = rig["rig"]
    host = json_format.MessageToDict(host_status(r.host_address), preserving_proto_field_name=True)
    worker = json_format.MessageToDict(worker_status(r.channel("left").address), preserving_proto_field_name=True)
    report = compositor_report(r.compositor_address)
    counted = {"host": int(host.get("requests_refused", {}).get("malformed", 0)),
               "worker": int(worker.get("malformed_requests", 0)),
               "compositor": int(report.get("rejected_submissions", {}).get("malformed", 0))}
    record("bad_requests", malformed_counted=counted)
    assert counted["host"] >= 3 and counted["worker"] >= 1 and counted["compositor"] >= 1, counted


def _ack(rig, **fields) -> tuple[str, str]:
    return raw_call(rig["rig"].host_address, "/ig.v1.HostService/AckFrame",
                    host_pb2.AckFrameRequest(**fields).SerializeToString())


def test_ack_of_an_unpublished_frame_is_out_of_range_and_the_host_still_waits(rig):
    code, details = _ack(rig, channel_name="left", frame_number=2**64 - 1, ok=True)
    rig["codes"]["AckFrame frame 2**64-1"] = code
    assert code == "OUT_OF_RANGE", details
    # The host still waits for left: stopped for several frame timeouts, it is timed out.
    before = host_status(rig["rig"].host_address).ack_timeouts["left"]
    rig["procs"].signal("left", 19)  # SIGSTOP
    try:
        intervals = published_intervals(rig["rig"].host_address, 4 * FRAME_TIMEOUT_S)
    finally:
        rig["procs"].signal("left", 18)  # SIGCONT
    after = host_status(rig["rig"].host_address).ack_timeouts["left"]
    record("bad_requests", ack_timeouts_after_bogus_ack=after - before, intervals_while_stopped=intervals)
    assert after - before >= 2, (before, after)


def test_ack_of_an_unknown_channel_is_invalid_argument(rig):
    code, details = _ack(rig, channel_name="middle", frame_number=0, ok=True)
    rig["codes"]["AckFrame unknown channel"] = code
    assert code == "INVALID_ARGUMENT" and "middle" in details, details


def test_ack_with_an_overlong_error_is_invalid_argument(rig):
    code, details = _ack(rig, channel_name="left", frame_number=0, ok=False, error="x" * 1025)
    rig["codes"]["AckFrame error of 1025 characters"] = code
    assert code == "INVALID_ARGUMENT", details
    assert len(details) < 2048


@pytest.mark.parametrize("process, method", [
    ("host", "/ig.v1.HostService/AckFrame"),
    ("host", "/ig.v1.HostService/GetHostStatus"),
    ("left", "/ig.v1.ChannelWorkerService/GetWorkerStatus"),
], ids=["host-AckFrame", "host-GetHostStatus", "worker-GetWorkerStatus"])
def test_messages_over_64_kib_are_resource_exhausted(rig, process, method):
    # A valid message (an unknown length-delimited field 15 is skipped by a parser) of 70 KiB.
    size = 70 * 1024
    payload = b"\x7a" + _varint(size) + b"x" * size
    code, details = raw_call(_address(rig["rig"], process), method, payload)
    rig["codes"][f"70 KiB {method}"] = code
    assert code == "RESOURCE_EXHAUSTED", details
    assert health(_address(rig["rig"], process)) == "SERVING"


def _varint(n: int) -> bytes:
    out = bytearray()
    while n >= 0x80:
        out.append(n & 0x7F | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def test_host_status_stays_small(rig):
    size = host_status(rig["rig"].host_address).ByteSize()
    record("bad_requests", host_status_bytes=size)
    assert size < 8192


def _submit(rig, *, frame_number: int, width: int = W, height: int = H, pixels: bytes | None = None):
    status = host_status(rig["rig"].host_address)
    request = compositor_pb2.SubmitChannelImageRequest(
        frame_number=frame_number, channel_name="centre", width=width, height=height,
        pixel_format=compositor_pb2.PIXEL_FORMAT_RGB_F16,
        pixels=pixels if pixels is not None else bytes(width * height * 6),
        eyepoint=frame_pb2.Eyepoint(z=10.0), run_id=status.run_id)
    return raw_call(rig["rig"].compositor_address, "/ig.v1.CompositorService/SubmitChannelImage",
                    request.SerializeToString())


def test_image_of_the_wrong_size_is_invalid_argument(rig):
    published = host_status(rig["rig"].host_address).frames_published
    code, details = _submit(rig, frame_number=published - 1, width=W + 2)
    rig["codes"]["SubmitChannelImage wrong size"] = code
    assert code == "INVALID_ARGUMENT", details
    report = compositor_report(rig["rig"].compositor_address)
    assert report["rejected_submissions"].get("wrong_size") == 1, report["rejected_submissions"]


def test_image_of_an_unpublished_frame_is_out_of_range(rig):
    code, details = _submit(rig, frame_number=10**9)
    rig["codes"]["SubmitChannelImage frame 10**9"] = code
    assert code == "OUT_OF_RANGE", details
    report = compositor_report(rig["rig"].compositor_address)
    assert report["rejected_submissions"].get("unpublished_frame") == 1, report["rejected_submissions"]


def test_image_over_the_largest_channel_is_resource_exhausted(rig):
    code, details = _submit(rig, frame_number=0, pixels=bytes(4 * W * H * 6 + 256 * 1024))
    rig["codes"]["SubmitChannelImage 4x the largest image + 256 KiB"] = code
    assert code == "RESOURCE_EXHAUSTED", details


def test_every_service_serving_and_frames_complete_after_all_of_it(rig):
    record("bad_requests", codes=rig["codes"])
    assert _serving(rig) == dict.fromkeys(rig["procs"].procs, "SERVING")
    seen = len(rig["watcher"].snapshot())
    poll(lambda: len(rig["watcher"].snapshot()) >= seen + 10, what="10 more complete frames")


@pytest.mark.parametrize("service", ["compositor", "worker", "host"])
def test_second_service_on_a_taken_port_exits_1(rig, service):
    argv = {"compositor": ["compositor", "--out", str(rig["rig_path"].parent / "second")],
            "worker": ["worker", "--channel", "left", "--scene", str(SCENE)],
            "host": ["host"]}[service]
    proc = subprocess.run([sys.executable, "-m", "services.cli", *argv, "--rig", str(rig["rig_path"])],
                          capture_output=True, text=True, env=env(), cwd=ROOT, timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "cannot listen" in proc.stderr, proc.stderr
    assert _serving(rig) == dict.fromkeys(rig["procs"].procs, "SERVING")
