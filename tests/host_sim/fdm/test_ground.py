"""The ground under the host's flight model: patches of heights from a query service, bilinear
between posts, fetched ahead of the aircraft, and the runway plane when nothing answers."""

from __future__ import annotations

import logging
import math
import time

import numpy as np
import pytest

from host_sim.fdm.ground import POSTS, SPACING_M, Patch, Plane, QueryGround

from .analytic_ground import AnalyticGround, serving, sloped


@pytest.fixture
def service():
    servicer = AnalyticGround()
    with serving(servicer) as address:
        yield address, servicer


def wait_until(predicate, timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


def test_a_patch_is_bilinear_between_its_posts_and_none_outside():
    z = np.array([[0.0, 1.0], [2.0, 4.0]])  # z[j, i] at (x0 + i s, y0 + j s)
    p = Patch(10.0, 20.0, 5.0, z)
    assert p.height(10.0, 20.0) == 0.0 and p.height(15.0, 20.0) == 1.0 and p.height(10.0, 25.0) == 2.0
    assert p.height(15.0, 25.0) == 4.0
    assert p.height(12.5, 22.5) == pytest.approx((0 + 1 + 2 + 4) / 4)
    assert p.centre == (12.5, 22.5)
    for x, y in ((9.99, 22.0), (15.01, 22.0), (12.0, 19.99), (12.0, 25.01), (math.nan, 22.0)):
        assert p.height(x, y) is None


def test_the_ground_follows_the_query_service_and_moves_its_patch_ahead_of_the_aircraft(service):
    address, servicer = service
    g = QueryGround(address, start_xy_m=(0.0, -950.0))
    try:
        assert servicer.requests == 1 and g.status()["patches"] == 1
        # Flying north 0.5 m a step (60 m/s at 120 Hz), 600 m: every look-up exact, the patch
        # re-centred every half half-width or so, never a look-up off the patch (the next patch
        # is asked for 124 steps before it is needed; each step waits 2 ms here).
        half = 0.5 * (POSTS - 1) * SPACING_M
        for k in range(1200):
            y = -950.0 + 0.5 * k
            assert g(0.0, y) == pytest.approx(sloped(0.0, y), abs=1e-9)
            time.sleep(0.002)
        s = g.status()
        assert s["outside"] == 0 and s["failures"] == 0
        assert 600.0 / half <= s["patches"] <= 2 + 600.0 / (0.5 * half)
        for x, y in ((0.0, -350.0), (-100.0, -400.0), (123.4, -270.6)):
            assert g(x, y) == pytest.approx(sloped(x, y), abs=1e-9)
    finally:
        g.close()


def test_a_look_up_off_every_patch_holds_the_last_height_until_the_next_patch_comes(service):
    address, _ = service
    g = QueryGround(address, start_xy_m=(0.0, 0.0), posts=2, spacing_m=8.0)
    try:
        here = g(1.0, 1.0)
        assert here == pytest.approx(sloped(1.0, 1.0))
        assert g(100.0, 100.0) == here  # a jump no patch covers yet: the last height, counted
        assert g.status()["outside"] >= 1
        assert wait_until(lambda: g(100.0, 100.0) == pytest.approx(sloped(100.0, 100.0)))
    finally:
        g.close()


def test_where_the_database_has_no_surface_the_ground_is_the_fallback_plane(service):
    address, _ = service
    g = QueryGround(address, start_xy_m=(400.0, 0.0), fallback_z_m=-3.0)
    try:
        assert g(380.0, 0.0) == pytest.approx(sloped(380.0, 0.0))
        assert g(450.0, 0.0) == -3.0
        # Between the last valid post (x = 400 - a fraction of a spacing) and the first invalid
        # one the ground blends from the terrain to the plane over one spacing.
        assert min(sloped(400.0, 0.0), -3.0) <= g(403.0, 0.0) <= max(sloped(400.0, 0.0), -3.0)
    finally:
        g.close()


def test_a_silent_query_service_leaves_the_plane_said_once_and_counted(caplog):
    caplog.set_level(logging.INFO, logger="ig.host.ground")
    with socket_bound() as port:  # a port nobody answers on
        g = QueryGround(f"127.0.0.1:{port}", start_xy_m=(0.0, 0.0), first_wait_s=0.2, timeout_s=0.1)
        try:
            assert g(0.0, 0.0) == 0.0 and g(500.0, 500.0) == 0.0
            assert wait_until(lambda: g.status()["failures"] >= 2, timeout_s=5.0)
        finally:
            g.close()
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert f"127.0.0.1:{port}" in warnings[0].getMessage() and "z = 0 m" in warnings[0].getMessage()
    assert any("request(s) failed" in r.getMessage() for r in caplog.records if r.levelno == logging.INFO)


def test_a_query_service_that_comes_up_late_takes_over_from_the_plane():
    port = free_port()
    g = QueryGround(f"127.0.0.1:{port}", start_xy_m=(0.0, 0.0), first_wait_s=0.1, timeout_s=0.2)
    try:
        assert g(0.0, 0.0) == 0.0
        with serving(AnalyticGround(), port):
            assert wait_until(lambda: g(1.0, 2.0) == pytest.approx(sloped(1.0, 2.0)), timeout_s=15.0)
    finally:
        g.close()


def test_bad_patch_settings_are_named():
    with pytest.raises(ValueError, match="spacing_m: 0"):
        QueryGround("127.0.0.1:1", start_xy_m=(0, 0), spacing_m=0.0)
    with pytest.raises(ValueError, match="posts: 40"):
        QueryGround("127.0.0.1:1", start_xy_m=(0, 0), posts=40)


def test_the_plane():
    p = Plane(2.5)
    assert p(1e6, -1e6) == 2.5
    p.close()


def free_port() -> int:
    """A TCP port on the loopback that nothing listens on (bound once by the OS, then freed)."""
    with socket_bound() as port:
        return port


class socket_bound:
    """A TCP port bound (not listening) for the with block: connections to it are refused."""

    def __enter__(self) -> int:
        import socket
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        return self.sock.getsockname()[1]

    def __exit__(self, *exc) -> None:
        self.sock.close()
