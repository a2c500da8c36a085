"""The rig's gRPC helpers: checked services (malformed bytes, overlong text, oversized messages),
exclusive ports, plaintext only on the loopback, clipped text. Servers in-process on port 0."""

import re
import types

import grpc
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ig.v1 import compositor_pb2, compositor_pb2_grpc
from services.rig.grpc_util import (
    MALFORMED,
    MAX_TEXT_CHARS,
    TEXT_TOO_LONG,
    PlaintextRefused,
    Security,
    add_service,
    bind,
    clip,
    is_loopback,
    make_channel,
    make_server,
)

SERVICE = compositor_pb2.DESCRIPTOR.services_by_name["CompositorService"]
SUBMIT = "/ig.v1.CompositorService/SubmitChannelImage"
WATCH = "/ig.v1.CompositorService/WatchComposites"
MAX_RECEIVE = 4096
#: Bytes that are not a protobuf message: field 1, length-delimited, 127 bytes announced, 1 given.
MALFORMED_BYTES = b"\x0a\x7f\x00"


class FakeCompositor(compositor_pb2_grpc.CompositorServiceServicer):
    """Answers every request and remembers what reached it."""

    def __init__(self):
        self.requests = []

    def SubmitChannelImage(self, request, context):
        self.requests.append(request)
        return compositor_pb2.SubmitChannelImageResponse()

    def GetCompositorReport(self, request, context):
        return compositor_pb2.GetCompositorReportResponse(report_json="{}")

    def WatchComposites(self, request, context):
        self.requests.append(request)
        yield compositor_pb2.WatchCompositesResponse(frame_number=7)


@pytest.fixture
def served():
    servicer = FakeCompositor()
    refusals = []
    server = make_server(max_receive_bytes=MAX_RECEIVE)
    add_service(server, servicer, SERVICE, refused=lambda cause, message: refusals.append((cause, message)))
    port = bind(server, "127.0.0.1:0")
    server.start()
    channel = make_channel(f"127.0.0.1:{port}")
    yield channel, servicer, refusals, port
    channel.close()
    server.stop(0).wait()


def raw(channel, path, payload, *, stream=False):
    """Send payload bytes as they are to path; the response bytes (a list for a stream)."""
    if stream:
        call = channel.unary_stream(path, request_serializer=lambda b: b, response_deserializer=lambda b: b)
        return list(call(payload, timeout=5))
    call = channel.unary_unary(path, request_serializer=lambda b: b, response_deserializer=lambda b: b)
    return call(payload, timeout=5)


def good_request(**kw):
    return compositor_pb2.SubmitChannelImageRequest(frame_number=3, channel_name="centre", **kw)


def assert_still_answers(channel, servicer):
    stub = compositor_pb2_grpc.CompositorServiceStub(channel)
    stub.SubmitChannelImage(good_request(), timeout=5)
    assert servicer.requests[-1].channel_name == "centre"


def test_a_good_request_passes_as_raw_bytes_too(served):
    channel, servicer, refusals, _ = served
    assert raw(channel, SUBMIT, good_request().SerializeToString()) == b""
    assert servicer.requests[-1].frame_number == 3 and refusals == []
    replies = raw(channel, WATCH, compositor_pb2.WatchCompositesRequest(watcher="w").SerializeToString(),
                  stream=True)
    assert [compositor_pb2.WatchCompositesResponse.FromString(r).frame_number for r in replies] == [7]


@pytest.mark.parametrize("path,type_name,stream", [
    (SUBMIT, "ig.v1.SubmitChannelImageRequest", False),
    (WATCH, "ig.v1.WatchCompositesRequest", True),
])
def test_malformed_bytes_are_invalid_argument_naming_the_message_type(served, path, type_name, stream):
    channel, servicer, refusals, _ = served
    with pytest.raises(grpc.RpcError) as err:
        raw(channel, path, MALFORMED_BYTES, stream=stream)
    assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert err.value.details().startswith(f"malformed {type_name}: ")
    assert [cause for cause, _ in refusals] == [MALFORMED]
    assert refusals[0][1] == err.value.details()
    assert servicer.requests == []  # the method never ran
    assert_still_answers(channel, servicer)


@pytest.mark.parametrize("field", ["channel_name", "run_id"])
def test_a_text_field_over_the_limit_is_refused_naming_it(served, field):
    channel, servicer, refusals, _ = served
    stub = compositor_pb2_grpc.CompositorServiceStub(channel)
    stub.SubmitChannelImage(compositor_pb2.SubmitChannelImageRequest(**{field: "x" * MAX_TEXT_CHARS}), timeout=5)
    assert refusals == []  # exactly the limit is taken
    with pytest.raises(grpc.RpcError) as err:
        stub.SubmitChannelImage(compositor_pb2.SubmitChannelImageRequest(**{field: "x" * (MAX_TEXT_CHARS + 1)}),
                                timeout=5)
    assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    expected = (f"ig.v1.SubmitChannelImageRequest.{field}: {MAX_TEXT_CHARS + 1} characters, more than the "
                f"{MAX_TEXT_CHARS} allowed")
    assert err.value.details() == expected
    assert refusals == [(TEXT_TOO_LONG, expected)]
    assert len(servicer.requests) == 1
    assert_still_answers(channel, servicer)


def test_overlong_text_of_a_streaming_request_is_refused(served):
    channel, servicer, refusals, _ = served
    stub = compositor_pb2_grpc.CompositorServiceStub(channel)
    with pytest.raises(grpc.RpcError) as err:
        list(stub.WatchComposites(compositor_pb2.WatchCompositesRequest(watcher="w" * 2000), timeout=5))
    assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert "ig.v1.WatchCompositesRequest.watcher: 2000 characters" in err.value.details()
    assert [cause for cause, _ in refusals] == [TEXT_TOO_LONG] and servicer.requests == []


def test_a_message_over_the_servers_limit_is_resource_exhausted(served):
    channel, servicer, _, _ = served
    stub = compositor_pb2_grpc.CompositorServiceStub(channel)
    with pytest.raises(grpc.RpcError) as err:
        stub.SubmitChannelImage(good_request(pixels=b"\0" * (2 * MAX_RECEIVE)), timeout=5)
    assert err.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED
    assert servicer.requests == []
    assert_still_answers(channel, servicer)


def test_client_streaming_methods_are_refused_at_registration():
    up = types.SimpleNamespace(name="Up", client_streaming=True, server_streaming=False,
                               input_type=SERVICE.methods[0].input_type, output_type=SERVICE.methods[0].output_type)
    service = types.SimpleNamespace(full_name="x.Svc", methods=[up])
    servicer = types.SimpleNamespace(Up=lambda request, context: None)
    with pytest.raises(ValueError, match=r"x\.Svc\.Up: client streaming is not used by the rig"):
        add_service(make_server(), servicer, service, refused=lambda c, m: None)


def test_a_second_server_cannot_bind_a_port_in_use(served):
    _, _, _, port = served
    other = make_server()
    try:
        with pytest.raises(OSError, match=f"cannot listen on 127.0.0.1:{port}"):
            bind(other, f"127.0.0.1:{port}")
    finally:
        other.stop(0).wait()


@pytest.mark.parametrize("address,loopback", [
    ("127.0.0.1:50051", True),
    ("127.1.2.3:50051", True),
    ("::1:50051", True),
    ("[::1]:50051", True),
    ("localhost:50051", True),
    ("0.0.0.0:50051", False),
    ("10.0.0.5:50051", False),
    ("[::]:50051", False),
    ("ig-host.example:50051", False),
    ("127.0.0.1.example:50051", False),
])
def test_is_loopback(address, loopback):
    assert is_loopback(address) is loopback


@pytest.mark.parametrize("address", ["0.0.0.0:0", "10.0.0.5:50051", "[::]:0", "ig-host.example:50051"])
def test_plaintext_off_the_loopback_is_refused(address):
    server = make_server()
    try:
        with pytest.raises(PlaintextRefused, match=re.escape(f"listening on {address}: plaintext is refused")):
            bind(server, address)
    finally:
        server.stop(0).wait()
    with pytest.raises(PlaintextRefused, match=re.escape(f"connecting to {address}: plaintext is refused")):
        make_channel(address)
    with pytest.raises(PlaintextRefused):
        make_channel(address, Security())


def test_plaintext_off_the_loopback_when_allowed():
    allowed = Security(allow_plaintext=True)
    server = make_server()
    try:
        assert bind(server, "0.0.0.0:0", allowed) > 0
    finally:
        server.stop(0).wait()
    make_channel("10.0.0.5:50051", allowed).close()  # no connection is made until a call
    other = make_server()
    try:
        # Allowed, but not an address of this machine: an OSError, not a refusal.
        with pytest.raises(OSError) as err:
            bind(other, "10.255.255.254:0", allowed)
        assert not isinstance(err.value, PlaintextRefused)
    finally:
        other.stop(0).wait()


def test_clip_keeps_short_text_and_says_how_much_was_cut():
    assert clip("") == ""
    assert clip("x" * MAX_TEXT_CHARS) == "x" * MAX_TEXT_CHARS
    assert clip("x" * (MAX_TEXT_CHARS + 5)) == "x" * MAX_TEXT_CHARS + "... (5 more characters)"
    assert clip("abcdef", 3) == "abc... (3 more characters)"
    assert len(clip("e" * 10_000_000)) <= MAX_TEXT_CHARS + 40


@given(text=st.text(max_size=300), limit=st.integers(0, 200))
def test_clip_is_a_prefix_and_bounded(text, limit):
    out = clip(text, limit)
    if len(text) <= limit:
        assert out == text
    else:
        assert out.startswith(text[:limit]) and out == f"{text[:limit]}... ({len(text) - limit} more characters)"
