"""Issue 30: the rig renders from the initial pose until the first ownship message, `ig status`
names the state, and a query database without terrain is reported once."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from host_sim.cigi import packets as pk
from host_sim.cigi.session import OWNSHIP_FOLLOWING, OWNSHIP_WAITING
from ig.v1 import host_pb2

from .test_session import ORIGIN, ig_control, ownship, send, session

#: 300 m above the origin, heading 90, pitch -5: none of it the ownship's (30, 2, -5).
START = (ORIGIN[0], ORIGIN[1], ORIGIN[2] + 300.0, 90.0, -5.0, 0.0)


def hot() -> pk.HatHotRequest:
    return pk.HatHotRequest(request_id=1, request_type=1, lat_x=ORIGIN[0], lon_y=ORIGIN[1], alt_z=0.0)


def test_the_initial_pose_is_published_before_the_host_speaks_and_while_it_only_asks():
    s, _ = session(initial_pose=START)
    frame, _ = s.begin_frame()
    e = frame.eyepoint
    assert e is not None
    np.testing.assert_allclose(e.position, [0.0, 0.0, 300.0], atol=1e-6)
    assert (e.heading_deg, e.pitch_deg, e.roll_deg) == pytest.approx((90.0, -5.0, 0.0), abs=1e-9)
    assert s.status()["ownship"] == OWNSHIP_WAITING + " (rendering the initial pose)"
    # A host that only sends requests (or a CIGI 4.0 host without Entity Position).
    send(s, ig_control(1), hot())
    frame, jobs = s.begin_frame()
    assert frame.eyepoint == e and len(jobs) == 1
    # The ownship arrives: the eyepoint follows it from that frame on.
    send(s, ig_control(2), ownship())
    frame, _ = s.begin_frame()
    assert (frame.eyepoint.heading_deg, frame.eyepoint.pitch_deg) == pytest.approx((30.0, 2.0), abs=1e-9)
    assert s.status()["ownship"] == OWNSHIP_FOLLOWING


def test_a_restarted_host_that_sends_no_ownship_gets_the_initial_pose_again():
    s, _ = session(initial_pose=START)
    send(s, ig_control(500), ownship())
    assert s.begin_frame()[0].eyepoint.heading_deg == pytest.approx(30.0)
    send(s, ig_control(0))  # the frame counter went back: a new host, entities forgotten
    frame, _ = s.begin_frame()
    assert frame.new_run and frame.eyepoint.heading_deg == pytest.approx(90.0)
    assert s.status()["ownship"].startswith(OWNSHIP_WAITING)


def test_reset_mode_still_publishes_nothing_and_without_an_initial_pose_nothing_waits():
    s, _ = session(initial_pose=START)
    send(s, ig_control(1, mode=0))
    assert s.begin_frame()[0].eyepoint is None
    bare, _ = session()
    assert bare.begin_frame()[0].eyepoint is None
    assert bare.status()["ownship"] == OWNSHIP_WAITING + " (no frame)"


def test_a_query_database_without_terrain_is_logged_once_and_in_the_status(caplog):
    s, _ = session()
    with caplog.at_level(logging.WARNING, logger="ig.host.cigi"):
        for _ in range(3):
            s.query_database_is("the query worker w:1's scene database holds no terrain")
    assert len([r for r in caplog.records if "holds no terrain" in r.getMessage()]) == 1
    status = host_pb2.CigiStatus(**s.status())
    assert "holds no terrain" in status.query_database and status.ownship.startswith(OWNSHIP_WAITING)


def test_start_of_frame_keeps_the_old_hosts_version_until_the_new_host_speaks():
    from host_sim.cigi.codec import V4_0, decode

    s, _ = session(initial_pose=START)
    send(s, ig_control(500), ownship())
    s.begin_frame()
    assert decode(s.start_of_frame([])[0], sender="ig").version.major == 3
    s.begin_frame()  # the old host gone, the new one not yet heard: still 3.3
    assert decode(s.start_of_frame([])[0], sender="ig").version.major == 3
    send(s, ig_control(0), version=V4_0)  # a 4.0 host starting over
    s.begin_frame()
    assert decode(s.start_of_frame([])[0], sender="ig").version == V4_0
