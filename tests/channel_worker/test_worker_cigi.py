"""What an external host (CIGI) sets in a Frame besides the eyepoint, as the worker renders it:
this channel's view and the environment; a bad one is refused like a bad eyepoint."""

import dataclasses

import numpy as np

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.environment import with_environment
from channel_worker.worker import ChannelWorker
from ig.v1 import frame_pb2
from services.rig.environment import Environment, environment_to_proto
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions
from services.rig.rigfile import WireSpec

from .test_worker_acks import RecordingStub

SPEC = ChannelSpec.symmetric("centre", 32, 24, 60.0)
EYE = Eyepoint.of(0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
OPTIONS = RenderOptions(samples=1, with_range=False)


def worker(make_scene, box_model_factory, stub):
    # A red box 45 deg right of the nose, a grey one dead ahead: a yaw of 45 deg swaps them.
    db = make_scene({"b": box_model_factory(10, 10, 10)},
                    [{"model": "b", "position": [100.0, 100.0, 0.0]}, {"model": "b", "position": [0.0, 300.0, 0.0]}],
                    sky="#2050c0", earth="#406020")
    # Half floats inline: the stub reads the renders' values from the request itself.
    w = ChannelWorker(db, SPEC, host_address="127.0.0.1:1", compositor_address="127.0.0.1:1", options=OPTIONS,
                      wire=WireSpec("half", shared_memory=False))
    w.host_stub = w.compositor_stub = stub
    return w


def frame(n, *, views=(), environment=None):
    msg = frame_pb2.Frame(frame_number=n, eyepoint=frame_pb2.Eyepoint(z=3.0), run_id="run", views=list(views))
    if environment is not None:
        msg.environment.CopyFrom(environment)
    return msg


def submitted(stub) -> np.ndarray:
    """The last submitted image as float32 (its pixels are the worker's buffer: read at once)."""
    s = stub.submits[-1]
    return np.frombuffer(bytes(s.pixels), "<f2").reshape(s.height, s.width, 3).astype(np.float32)


def expected(db, spec) -> np.ndarray:
    return render_frame(db, spec, EYE, OPTIONS).rgb.astype("<f2").astype(np.float32)


def test_a_view_for_this_channel_renders_with_its_yaw(make_scene, box_model_factory):
    stub = RecordingStub()
    w = worker(make_scene, box_model_factory, stub)
    w._handle(frame(0, views=[frame_pb2.ChannelView(channel="left", yaw_deg=-45.0)]))  # not ours
    np.testing.assert_array_equal(submitted(stub), expected(w.database, SPEC))
    w._handle(frame(1, views=[frame_pb2.ChannelView(channel="centre", yaw_deg=45.0)]))
    yawed = submitted(stub)
    assert (stub.submits[-1].width, stub.submits[-1].height) == (32, 24)  # the size is the rig file's
    np.testing.assert_array_equal(yawed, expected(w.database, dataclasses.replace(SPEC, yaw_deg=45.0)))
    assert not np.array_equal(yawed, expected(w.database, SPEC))
    assert w.channel.yaw_deg == 0.0  # the next frame without a view gets the rig file's again
    assert w.counters.frames_rendered == 2 and w.counters.frames_refused == 0


def test_a_bad_view_is_refused_and_counted(make_scene, box_model_factory):
    stub = RecordingStub()
    w = worker(make_scene, box_model_factory, stub)
    w._handle(frame(0, views=[frame_pb2.ChannelView(channel="centre", left_deg=40.0)]))  # left >= right
    (ack,) = stub.acks
    assert not ack.ok and "left_deg 40.0 is not < right_deg 30.0" in ack.error
    assert w.counters.frames_refused == 1 and not stub.submits
    assert "frame 0 refused" in w.counters.last_error


def test_the_environment_is_rendered_and_built_once(make_scene, box_model_factory):
    stub = RecordingStub()
    w = worker(make_scene, box_model_factory, stub)
    env = Environment(visibility_m=400.0, sun=(0.0, 0.6, 0.8))
    w._handle(frame(0, environment=environment_to_proto(env)))
    np.testing.assert_array_equal(submitted(stub), expected(with_environment(w.database, env), SPEC))
    assert not np.array_equal(submitted(stub), expected(w.database, SPEC))
    built = w._environments.get(w.database, env)
    w._handle(frame(1, environment=environment_to_proto(env)))
    assert w._environments.get(w.database, env) is built
    w._handle(frame(2))  # no environment: the scene's own
    np.testing.assert_array_equal(submitted(stub), expected(w.database, SPEC))


def test_a_bad_environment_is_refused_and_counted(make_scene, box_model_factory):
    stub = RecordingStub()
    w = worker(make_scene, box_model_factory, stub)
    w._handle(frame(0, environment=frame_pb2.Environment(visibility_m=-1.0)))
    (ack,) = stub.acks
    assert not ack.ok and "environment.visibility_m: -1.0" in ack.error
    assert w.counters.frames_refused == 1 and not stub.submits


def test_a_cigi_rigs_worker_warms_up_under_a_hosts_weather_and_loads_the_query_kernels():
    from channel_worker.pipeline.scene.environment import WARM_UP_ENVIRONMENT
    from channel_worker.pipeline.scene.load import bundled_scene_path, load_scene
    from channel_worker.worker import ChannelWorker
    from services.rig.frame import ChannelSpec

    database = load_scene(bundled_scene_path())
    worker = ChannelWorker(database, ChannelSpec.symmetric("centre", 32, 24, 60.0), host_address="127.0.0.1:1",
                           compositor_address="127.0.0.1:2", cigi=True)
    try:
        worker.warm_up()
        assert worker.ready
        # The warm-up rendered under the host's weather (its database is in the cache).
        assert list(worker._environments._results) == [WARM_UP_ENVIRONMENT]
    finally:
        worker._host.close()
        worker._compositor.close()
