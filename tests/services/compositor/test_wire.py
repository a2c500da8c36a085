"""The images between worker and compositor: sRGB bytes as the PNGs hold them, or half floats;
inline or in the worker's shared memory; stitched in one format; counted and timed per image."""

import json

import grpc
import numpy as np
import pytest

from channel_worker.submit import ImageSender, SubmitStub, serialize_submission
from ig.v1 import compositor_pb2, compositor_pb2_grpc, frame_pb2
from services.compositor.gather import ChannelImage, CompleteFrame, FrameGatherer
from services.compositor.server import Compositor, CompositorServicer
from services.compositor.stitch import FrameRecorder, compose, stitch
from services.compositor.watch import row_profile
from services.rig.colour import decode_srgb8, linear_to_srgb8
from services.rig.frame import ChannelSpec
from services.rig.grpc_util import make_channel, make_server
from services.rig.image_io import read_image, write_image
from services.rig.rigfile import WireSpec
from services.rig.shared_images import SharedImageRing, shared_memory_supported

W, H = 40, 30
EYE = frame_pb2.Eyepoint(x=1.0, y=2.0, z=3.0)
needs_shm = pytest.mark.skipif(not shared_memory_supported(), reason="no /dev/shm")


def linear_image(seed=0):
    """Linear RGB over the whole range and beyond: negatives, above one, NaN."""
    rgb = np.random.default_rng(seed).uniform(-0.1, 1.2, (H, W, 3)).astype(np.float32)
    rgb[0, 0] = np.nan
    return rgb


def head(n, channel="a"):
    return compositor_pb2.SubmitChannelImageRequest(
        frame_number=n, channel_name=channel, width=W, height=H, eyepoint=EYE, run_id="r",
        render_end_unix_s=100.0 + n, render_start_unix_s=99.0 + n, frame_received_unix_s=98.0 + n)


class Capture:
    """A stub that keeps what a real channel would send (the serialised request, parsed)."""

    def __init__(self):
        self.requests = []

    def SubmitChannelImage(self, submission, timeout):
        self.requests.append(compositor_pb2.SubmitChannelImageRequest.FromString(serialize_submission(submission)))


def test_srgb8_on_the_wire_is_the_png_bit_for_bit(tmp_path):
    rgb = linear_image()
    sender = ImageSender(ChannelSpec.symmetric("a", W, H, 60.0), compositor_address="192.0.2.1:1",
                         wire=WireSpec("srgb8", True))
    assert not sender.shared  # the compositor is not on this machine: inline
    stub = Capture()
    sender.submit(stub, head(0), rgb)
    sent = stub.requests[0]
    assert sent.pixel_format == compositor_pb2.PIXEL_FORMAT_RGB_SRGB8 and len(sent.pixels) == W * H * 3
    write_image(tmp_path / "f.png", rgb)
    png, _ = read_image(tmp_path / "f.png")
    np.testing.assert_array_equal(np.frombuffer(sent.pixels, np.uint8).reshape(H, W, 3),
                                  np.round(png * 255).astype(np.uint8))
    # And the PNG of an 8-bit composite is those bytes, unchanged.
    write_image(tmp_path / "g.png", np.frombuffer(sent.pixels, np.uint8).reshape(H, W, 3))
    again, _ = read_image(tmp_path / "g.png")
    np.testing.assert_array_equal(again, png)


def test_half_on_the_wire_is_numpys_rounding():
    rgb = linear_image()
    stub = Capture()
    ImageSender(ChannelSpec.symmetric("a", W, H, 60.0), compositor_address="192.0.2.1:1",
                wire=WireSpec("half", False)).submit(stub, head(0), rgb)
    sent = stub.requests[0]
    assert sent.pixel_format == compositor_pb2.PIXEL_FORMAT_RGB_F16 and not sent.HasField("shared")
    np.testing.assert_array_equal(np.frombuffer(sent.pixels, "<f2").reshape(H, W, 3), rgb.astype("<f2"))


def image(channel, rgb):
    return ChannelImage(channel, rgb, (1.0, 2.0, 3.0, 0.0, 0.0, 0.0), 0.01, 100.0, 0)


def frame(*rgbs):
    return CompleteFrame(0, 0.0, (1.0, 2.0, 3.0, 0.0, 0.0, 0.0), 100.0,
                         tuple(image(c, rgb) for c, rgb in zip("abc", rgbs, strict=False)))


def test_channels_are_stitched_in_their_format_and_mixed_ones_in_the_rigs():
    rgb = np.abs(linear_image()).clip(0, 1)
    rgb[0, 0] = 0.5
    srgb, half = linear_to_srgb8(rgb), rgb.astype(np.float16)
    out = stitch(frame(srgb, srgb))
    assert out.dtype == np.uint8 and out.shape == (H, 2 * W, 3)
    np.testing.assert_array_equal(out[:, W:], srgb)
    assert stitch(frame(half, half)).dtype == np.float16
    mixed = stitch(frame(srgb, half), prefer="srgb8")
    assert mixed.dtype == np.uint8
    np.testing.assert_array_equal(mixed[:, W:], linear_to_srgb8(half))
    mixed = stitch(frame(srgb, half), prefer="half")
    assert mixed.dtype == np.float16
    np.testing.assert_array_equal(mixed[:, :W], decode_srgb8(srgb).astype(np.float16))


def test_an_8bit_composite_records_its_bytes_and_a_quantised_exr(tmp_path):
    srgb = linear_to_srgb8(np.abs(linear_image()).clip(0, 1))
    recorder = FrameRecorder(tmp_path, record_every=1, exr_every=1)
    recorder.offer(compose(frame(srgb, srgb)))
    recorder.close()
    assert recorder.snapshot().written == 1
    png, attrs = read_image(tmp_path / "frame_000000.png")
    np.testing.assert_array_equal(np.round(png * 255).astype(np.uint8)[:, :W], srgb)
    assert attrs["wire"] == "srgb8"
    exr, attrs = read_image(tmp_path / "frame_000000.exr")
    np.testing.assert_array_equal(exr[:, :W], decode_srgb8(srgb).astype(np.float16).astype(np.float32))
    assert attrs["wire"] == "srgb8"


def test_row_profiles_of_bytes_are_those_of_their_linear_values():
    srgb = linear_to_srgb8(np.abs(linear_image()).clip(0, 1))
    np.testing.assert_allclose(row_profile(srgb), row_profile(decode_srgb8(srgb)), rtol=1e-6)


@pytest.fixture
def served(tmp_path, request):
    wire = getattr(request, "param", WireSpec())
    comp = Compositor(("a",), tmp_path, record_every=0, exr_every=0, sizes={"a": (W, H)}, wire=wire)
    server = make_server()
    compositor_pb2_grpc.add_CompositorServiceServicer_to_server(CompositorServicer(comp), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    for n in range(8):
        comp.on_published(frame_pb2.Frame(frame_number=n, eyepoint=EYE, run_id="r"))
    yield comp, f"127.0.0.1:{port}"
    server.stop(0).wait()
    comp.finish(grace_s=0.0)


def delivered(comp):
    composites = []
    comp.watchers.add("test", []).put = composites.append  # what every watcher is handed
    return composites


@needs_shm
def test_shared_memory_round_trip_through_the_compositor(served):
    comp, address = served
    composites = delivered(comp)
    sender = ImageSender(ChannelSpec.symmetric("a", W, H, 60.0), compositor_address=address)
    assert sender.shared
    with make_channel(address) as channel:
        stub = SubmitStub(channel)
        for n in range(3):
            sender.submit(stub, head(n), linear_image(n))
    name = sender.ring.name
    sender.close()
    assert [c.frame.frame_number for c in composites] == [0, 1, 2]
    for n, c in enumerate(composites):
        assert c.rgb.dtype == np.uint8
        np.testing.assert_array_equal(c.rgb, linear_to_srgb8(linear_image(n)))
    report = comp.report()
    wire = report["wire"]
    assert wire["channels"]["a"] == {"srgb8": 3, "half": 0, "shared_memory": 3, "inline": 0,
                                     "bytes_per_image": W * H * 3}
    assert wire["composites"] == {"srgb8": 3} and wire["format"] == "srgb8" and wire["shared_memory"]
    for key in ("render_end_to_compositor_receive", "encode", "transfer"):
        assert wire[key]["count"] == 3 and wire[key]["p99_ms"] is not None
    assert not (comp.out_dir / name).exists()


@needs_shm
@pytest.mark.parametrize("served", [WireSpec("half", shared_memory=False)], indirect=True)
def test_a_compositor_that_cannot_open_the_segment_gets_the_image_inline(served, caplog):
    comp, address = served
    composites = delivered(comp)
    sender = ImageSender(ChannelSpec.symmetric("a", W, H, 60.0), compositor_address=address,
                         wire=WireSpec("half", True))
    assert sender.shared  # offered: the address is local
    with make_channel(address) as channel:
        stub = SubmitStub(channel)
        for n in range(2):
            sender.submit(stub, head(n), linear_image(n))
    assert not sender.shared and "cannot open the segment" in sender.inline_because
    assert sum("images go inline from now on" in r.message for r in caplog.records) == 1  # logged once
    assert [c.frame.frame_number for c in composites] == [0, 1]
    np.testing.assert_array_equal(composites[1].rgb, linear_image(1).astype(np.float16))
    report = comp.report()
    assert report["rejected_submissions"] == {"shared_memory_unavailable": 1}
    assert report["wire"]["channels"]["a"]["inline"] == 2 and report["wire"]["composites"] == {"half": 2}


@needs_shm
def test_a_stale_or_missing_segment_is_refused_counted_and_the_channel_goes_on(served):
    comp, address = served
    composites = delivered(comp)
    ring = SharedImageRing("a", W * H * 3, slots=2)
    try:
        slot, seq, pixels = ring.reserve((H, W, 3), np.uint8)
        pixels[:] = 7
        ring.commit(slot, seq)
        with make_channel(address) as channel:
            stub = compositor_pb2_grpc.CompositorServiceStub(channel)

            def shared(n, **ref):
                request = head(n)
                request.pixel_format = compositor_pb2.PIXEL_FORMAT_RGB_SRGB8
                request.shared.CopyFrom(compositor_pb2.SharedImage(**ref))
                return stub.SubmitChannelImage(request, timeout=5)

            with pytest.raises(grpc.RpcError) as err:
                shared(0, segment=ring.name, slot=slot, sequence=seq + 2)
            assert err.value.code() == grpc.StatusCode.INVALID_ARGUMENT
            assert f"shared.sequence: {seq + 2}, but slot {slot}" in err.value.details()
            with pytest.raises(grpc.RpcError) as err:  # a dead worker's segment, removed
                shared(0, segment="ig-a-999999-00000000", slot=0, sequence=1)
            assert err.value.code() == grpc.StatusCode.FAILED_PRECONDITION
            assert err.value.details().startswith("shared.segment: 'ig-a-999999-00000000' cannot be opened")
            shared(0, segment=ring.name, slot=slot, sequence=seq)  # the rig keeps running
    finally:
        ring.close()
    assert [c.frame.frame_number for c in composites] == [0] and np.all(composites[0].rgb == 7)
    report = comp.report()
    assert report["rejected_submissions"] == {"shared_memory_unavailable": 1, "stale_shared_image": 1}
    assert "shared.segment" in report["last_rejection"]


def test_an_inline_image_of_the_wrong_size_for_its_format_is_refused():
    g = FrameGatherer(("a",), lambda f: None)
    request = head(0)
    request.pixel_format = compositor_pb2.PIXEL_FORMAT_RGB_SRGB8
    request.pixels = bytes(W * H * 6)  # half floats' size
    with pytest.raises(ValueError, match=rf"pixels: {W * H * 6} bytes, expected {W * H * 3} for {W} x {H} RGB srgb8"):
        g.submit(request)
    assert json.loads(json.dumps(g.report()))["rejected_submissions"] == {"bad_pixels": 1}


def test_ig_demo_prints_the_wire_and_the_hop(tmp_path):
    from services.demo import format_report

    comp = Compositor(("a",), tmp_path, record_every=0, exr_every=0)
    comp.on_published(frame_pb2.Frame(frame_number=0, eyepoint=EYE, run_id="r"))
    request = head(0)
    request.submit_unix_s = request.render_end_unix_s + 0.002
    request.pixel_format = compositor_pb2.PIXEL_FORMAT_RGB_SRGB8
    request.pixels = bytes(W * H * 3)
    comp.submit(request)
    text = format_report(comp.finish(grace_s=0.0))
    assert f"1 srgb8; 0 in shared memory, 1 inline; {W * H * 3 / 1e6:.2f} MB an image" in text
    line = next(line for line in text.splitlines() if "encode (render end -> submit)" in line)
    assert line.split()[-4:] == ["2.0"] * 4  # p50, p95, p99, max of the one image
