"""The IG's CIGI session without sockets: frame sync, the ownship, restarts, staleness,
requests, views and environment, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host_sim.cigi import packets as pk
from host_sim.cigi.codec import V3_3, V4_0, decode, encode
from host_sim.cigi.session import SYNC_BACKLOG, CigiSession
from services.rig.frame import ChannelSpec

ORIGIN = (36.6089, -84.1708, 349.2)
CHANNELS = {0: ChannelSpec.symmetric("left", 64, 48, 60.0, yaw_deg=-60.0),
            1: ChannelSpec.symmetric("centre", 64, 48, 60.0),
            2: ChannelSpec.symmetric("right", 64, 48, 60.0, yaw_deg=60.0)}
HOST = ("127.0.0.1", 9999)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def session(**kw) -> tuple[CigiSession, Clock]:
    clock = Clock()
    return CigiSession(origin=ORIGIN, channels=CHANNELS, clock=clock, wall=lambda: 1e9 + clock.t, **kw), clock


def ig_control(frame: int, mode: int = 1, **kw) -> pk.IGControl:
    return pk.IGControl(ig_mode=mode, host_frame=frame, **kw)


def ownship(lat=ORIGIN[0], lon=ORIGIN[1], alt=ORIGIN[2] + 300.0, yaw=30.0, pitch=2.0, roll=-5.0) -> pk.EntityControl:
    return pk.EntityControl(entity_id=0, entity_state=1, lat_x=lat, lon_y=lon, alt_z=alt, yaw=yaw, pitch=pitch,
                            roll=roll)


def send(s: CigiSession, *packets, version=V3_3, order="<") -> bool:
    return s.receive(encode(list(packets), version, order), HOST)


def test_nothing_is_published_and_no_start_of_frame_sent_before_the_host_speaks():
    s, _ = session()
    frame, jobs = s.begin_frame()
    assert frame.eyepoint is None and jobs == []
    assert s.start_of_frame([]) == []


def test_the_ownship_is_the_eyepoint_and_the_start_of_frame_answers_in_the_hosts_byte_order():
    s, _ = session()
    for order in ("<", ">"):
        send(s, ig_control(7), ownship(), order=order)
        frame, _ = s.begin_frame()
        e = frame.eyepoint
        np.testing.assert_allclose(e.position, [0.0, 0.0, 300.0], atol=1e-6)
        assert (e.heading_deg, e.pitch_deg, e.roll_deg) == pytest.approx((30.0, 2.0, -5.0), abs=1e-9)
        assert frame.host_frame_number == 7
        [datagram] = s.start_of_frame([])
        message = decode(datagram, sender="ig")
        assert message.byte_order == order and message.version == V3_3
        sof = message.packets[0]
        assert isinstance(sof, pk.StartOfFrame)
        assert sof.last_host_frame == 7 and sof.ig_frame == s.ig_frame and sof.ig_mode == 1
        s.begin_frame()  # nothing waiting: the same eyepoint is held


def test_a_synchronous_frame_uses_at_most_one_host_message_the_oldest():
    s, _ = session()
    for n in (1, 2, 3):
        send(s, ig_control(n), ownship(alt=ORIGIN[2] + 100.0 * n))
    used = [s.begin_frame()[0].host_frame_number for _ in range(4)]
    assert used == [1, 2, 3, 3]  # the last frame holds host frame 3 (nothing new)
    for n in range(10, 10 + SYNC_BACKLOG + 3):
        send(s, ig_control(n), ownship())
    assert s.counters.messages_dropped == 3
    assert s.begin_frame()[0].host_frame_number == 13


def test_asynchronous_frames_take_every_message_and_extrapolate_the_ownship():
    s, clock = session(mode="async")
    east = ORIGIN[1] + 0.001  # about 89 m east of the origin
    send(s, ig_control(1, timestamp_valid=True, extrapolation=True, timestamp=0), ownship(yaw=90.0))
    clock.t += 0.05
    send(s, ig_control(2, timestamp_valid=True, extrapolation=True, timestamp=5000),
         ownship(lon=east, yaw=90.0))  # 50 ms later by the host's 10 us clock
    frame, _ = s.begin_frame()
    assert frame.host_frame_number == 2
    at_second = frame.eyepoint.position.copy()
    clock.t += 0.025  # half a host step later: half the step further on
    ahead = s.begin_frame()[0].eyepoint.position
    step = at_second[0] / 1.0  # the first pose was at x = 0
    assert ahead[0] == pytest.approx(at_second[0] + 0.5 * step, rel=1e-6)
    clock.t += 10.0  # never more than MAX_EXTRAPOLATION_S ahead, and not at all once stale
    assert s.begin_frame()[0].eyepoint.position[0] == pytest.approx(at_second[0], rel=1e-9)


def test_a_host_that_restarts_its_frame_counter_starts_a_new_run_but_not_at_the_wrap():
    s, _ = session()
    send(s, ig_control(500), ownship())
    assert not s.begin_frame()[0].new_run
    send(s, ig_control(0), ownship())
    assert s.begin_frame()[0].new_run and s.counters.restarts == 1
    s2, _ = session()
    send(s2, ig_control(2**32 - 1), ownship())
    s2.begin_frame()
    send(s2, ig_control(0), ownship())
    assert not s2.begin_frame()[0].new_run


def test_a_silent_host_is_reported_stale_and_its_last_eyepoint_held():
    s, clock = session(stale_after_s=0.5)
    send(s, ig_control(1), ownship())
    first = s.begin_frame()[0].eyepoint
    clock.t += 0.6
    frame, _ = s.begin_frame()
    assert s.stale and s.counters.stale_events == 1
    np.testing.assert_array_equal(frame.eyepoint.position, first.position)
    send(s, ig_control(2), ownship())
    s.begin_frame()
    assert not s.stale


def test_silent_for_counts_from_the_hosts_last_message():
    s, clock = session()
    assert s.silent_for() is None  # the host has not spoken: nothing to count from
    send(s, ig_control(1), ownship())
    s.begin_frame()
    clock.t += 2.5
    assert s.silent_for() == pytest.approx(2.5)
    send(s, ig_control(2), ownship())
    s.begin_frame()
    assert s.silent_for() == pytest.approx(0.0)


def test_reset_mode_publishes_nothing_and_forgets_the_entities():
    s, _ = session()
    send(s, ig_control(1), ownship())
    assert s.begin_frame()[0].eyepoint is not None
    send(s, ig_control(2, mode=0))
    frame, _ = s.begin_frame()
    assert frame.eyepoint is None and s.entities == {}


def test_garbage_is_refused_counted_and_changes_nothing():
    s, _ = session()
    send(s, ig_control(1), ownship())
    s.begin_frame()
    assert not s.receive(b"\x02\x30" + bytes(46), HOST)  # an Entity Control first
    assert not s.receive(b"", HOST)
    assert sum(s.counters.refused.values()) == 2
    assert s.begin_frame()[0].host_frame_number == 1


def test_height_requests_become_jobs_once_or_every_n_frames():
    s, _ = session()
    hot = pk.HatHotRequest(request_id=3, request_type=1, coord_system=0, update_period=0, entity_id=0,
                           lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=0.0)
    send(s, ig_control(1), ownship(), hot)
    _, jobs = s.begin_frame()
    assert len(jobs) == 1 and jobs[0].lsn == 1
    assert s.begin_frame()[1] == []
    periodic = pk.HatHotRequest(request_id=4, request_type=0, coord_system=0, update_period=3, entity_id=0,
                                lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=ORIGIN[2] + 50.0)
    send(s, ig_control(2), periodic)
    counts = [len(s.begin_frame()[1]) for _ in range(7)]
    assert counts == [1, 0, 0, 1, 0, 0, 1]
    send(s, ig_control(3), pk.HatHotRequest(request_id=4, request_type=0, update_period=0, lat_x=ORIGIN[0],
                                            lon_y=ORIGIN[1], alt_z=0.0))
    counts = [len(s.begin_frame()[1]) for _ in range(4)]
    assert counts == [1, 0, 0, 0]  # replaced by a one-shot request of the same id


def test_an_entity_relative_request_of_an_unknown_entity_is_a_job_answered_invalid():
    s, _ = session()
    req = pk.HatHotRequest(request_id=1, request_type=1, coord_system=1, entity_id=240)
    send(s, ig_control(1), ownship(), req)
    _, [job] = s.begin_frame()
    assert job.known is False


def test_view_control_and_definition_move_the_channel_named_by_view_id():
    s, _ = session()
    send(s, ig_control(1), ownship(),
         pk.ViewControl(view_id=2, entity_id=0, yaw_enable=True, yaw=45.0),
         pk.ViewDefinition(view_id=2, left_enable=True, left=-20.0, right_enable=True, right=25.0))
    frame, _ = s.begin_frame()
    [view] = frame.views
    assert view.channel == "right" and view.yaw_deg == 45.0 and (view.left_deg, view.right_deg) == (-20.0, 25.0)
    assert not view.HasField("top_deg")
    # An impossible frustum is refused, counted, and the view stays.
    send(s, ig_control(2), pk.ViewDefinition(view_id=2, left_enable=True, left=40.0))
    frame, _ = s.begin_frame()
    assert s.counters.refused.get("bad_value") == 1 and frame.views[0].left_deg == -20.0
    # A view id no channel has is accepted but unused.
    send(s, ig_control(3), pk.ViewControl(view_id=9, yaw_enable=True, yaw=1.0))
    s.begin_frame()
    assert sum(s.counters.unused.values()) == 1


def test_weather_atmosphere_and_sun_become_the_environment():
    calls = []

    def solar(**kw):
        calls.append(kw)
        return (0.0, 0.6, 0.8)

    s, _ = session(solar=solar)
    send(s, ig_control(1), ownship(),
         pk.AtmosphereControl(visibility=8000.0),
         pk.WeatherControl(layer_id=0, weather_enable=True, scope=0, visibility=300.0, coverage=100.0,
                           base_elevation=ORIGIN[2] - 10.0, thickness=60.0),
         pk.WeatherControl(layer_id=1, weather_enable=True, scope=0, cloud_type=3, visibility=50.0, coverage=40.0,
                           base_elevation=ORIGIN[2] + 1500.0, thickness=400.0),
         pk.WeatherControl(layer_id=2, weather_enable=True, scope=1, visibility=50.0),  # regional: unused
         pk.CelestialSphereControl(hour=14, minute=30, sun_enable=True, date_valid=True, date=6212026))
    env = s.begin_frame()[0].environment
    assert env.visibility_m == 8000.0 and env.sun == (0.0, 0.6, 0.8)
    fog, cloud = env.layers
    # float32 on the wire: the base elevation 339.2 comes back within its rounding.
    assert (fog.base_m, fog.thickness_m, fog.visibility_m, fog.coverage) == pytest.approx((-10.0, 60.0, 300.0, 1.0),
                                                                                          abs=1e-4)
    assert not fog.cloud
    assert (cloud.base_m, cloud.coverage, cloud.cloud) == (pytest.approx(1500.0, abs=1e-3), pytest.approx(0.4), True)
    assert calls[0]["month"] == 6 and calls[0]["day"] == 21 and calls[0]["year"] == 2026
    assert calls[0]["lat_deg"] == ORIGIN[0]
    assert any("Weather" in name for name in s.counters.unused)
    send(s, ig_control(2), pk.WeatherControl(layer_id=0, weather_enable=False, scope=0))
    assert len(s.begin_frame()[0].environment.layers) == 1


def test_packets_the_rig_does_not_use_are_counted_by_name():
    s, _ = session()
    send(s, ig_control(1), ownship(), pk.ComponentControl(component_id=5), pk.ShortComponentControl())
    s.begin_frame()
    assert sum(s.counters.unused.values()) == 2
    assert s.counters.packets  # IG Control and Entity Control are used


def test_cigi_4_hosts_give_the_ownship_through_entity_position():
    s, _ = session()
    send(s, ig_control(1), pk.EntityPosition(entity_id=0, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=ORIGIN[2] + 10.0,
                                              yaw=180.0), version=V4_0)
    frame, _ = s.begin_frame()
    assert frame.eyepoint.position[2] == pytest.approx(10.0, abs=1e-6)
    assert frame.eyepoint.heading_deg == pytest.approx(180.0)
    [datagram] = s.start_of_frame([])
    assert decode(datagram, sender="ig").version == V4_0


def test_responses_that_do_not_fit_one_datagram_wait_for_the_next_frame():
    from host_sim.cigi.session import MAX_REPLY_BYTES

    s, _ = session()
    send(s, ig_control(1), ownship())
    s.begin_frame()
    many = [pk.HatHotResponse(request_id=i, valid=True, response_type=1, height=1.0) for i in range(1000)]
    [first] = s.start_of_frame(many)
    assert len(first) <= MAX_REPLY_BYTES
    sent = len(decode(first, sender="ig").packets) - 1
    s.begin_frame()
    [second] = s.start_of_frame([])
    assert sent + len(decode(second, sender="ig").packets) - 1 == 1000
    assert s.counters.responses_deferred > 0
    assert math.isfinite(sent)


def test_a_host_asking_more_than_the_datagrams_carry_does_not_grow_the_wait_without_end():
    from host_sim.cigi.session import MAX_PENDING_REPLIES

    s, _ = session()
    send(s, ig_control(1), ownship())
    s.begin_frame()
    for _ in range(10):
        s.start_of_frame([pk.HatHotResponse(request_id=i, valid=True, height=1.0) for i in range(1000)])
    assert len(s._pending_replies) <= MAX_PENDING_REPLIES
    assert s.counters.responses_dropped > 0
