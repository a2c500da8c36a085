"""The ground under a host flight model's wheels (docs/host-flight-model.md, "The ground").

JSBSim asks at every step (120 Hz) for the terrain elevation under the aircraft. The rig's
terrain and runway live in the channel workers' scene databases, which the host does not load
(the host renders nothing: no numba in its imports). A worker answers height of terrain through
ig.v1.QueryService, the service that answers a CIGI host's HAT/HOT requests, so the host asks
the same one. A round trip inside every step would tie the flight model's rate to the network,
so the host holds a patch of heights around the aircraft instead: POSTS x POSTS posts SPACING_M
apart from one request, interpolated bilinearly between posts, and a background thread fetches
the next patch, centred on the aircraft, once the aircraft is RECENTRE_FRACTION of the patch's
half-width from its centre. At take-off speed (60 m/s) that is a second before the patch runs
out; a 1024-post request takes about 0.5 ms to answer.

What the worker counts as ground is CIGI's height of terrain: the highest surface (terrain,
runway and other polygons, the top of a tree or building voxel). A post the databases do not
cover (valid = False) reads as the fallback plane, the earth plane beyond them.

If the worker cannot be reached, the ground is the fallback plane (the bundled airfield's
runway, world z = 0), said once in the log with the reason, counted, and retried every
RETRY_S; a look-up outside every patch fetched so far (the next one late) holds the last
height returned. The counters are in `status()`; the host logs them when the flight ends.
"""

from __future__ import annotations

import logging
import math
import threading
from dataclasses import dataclass
from typing import Protocol

import grpc
import numpy as np

from ig.v1 import query_pb2, query_pb2_grpc
from services.rig.grpc_util import Security, make_channel

log = logging.getLogger("ig.host.ground")

#: Posts along each side of a patch (POSTS^2 = 1024: one QueryService request's limit).
POSTS = 32
#: Distance between posts, metres. The bundled terrain's posts are 30 m apart and bilinear
#: between them, so 8 m posts follow it within centimetres on its slopes; a runway's edge is a
#: step the patch smooths over 8 m.
SPACING_M = 8.0
#: A new patch is fetched once the aircraft is this fraction of the half-width from the centre.
RECENTRE_FRACTION = 0.5
#: Seconds between tries while the query service does not answer.
RETRY_S = 1.0
#: Deadline of the first request, seconds, which waits for the worker to come up (`ig demo`
#: starts the host while its workers finish warming up).
FIRST_WAIT_S = 5.0


class Ground(Protocol):
    """World z (metres) of the ground under world (x, y)."""

    def __call__(self, x_m: float, y_m: float) -> float: ...

    def close(self) -> None: ...


class Plane:
    """Flat ground at world z = z_m: the bundled airfield's runway and pad lie at z = 0."""

    def __init__(self, z_m: float = 0.0) -> None:
        self.z_m = float(z_m)

    def __call__(self, x_m: float, y_m: float) -> float:
        return self.z_m

    def close(self) -> None:
        """Nothing to release."""


@dataclass(frozen=True)
class Patch:
    """Heights on a square of posts: z[j, i] at (x0 + i * spacing, y0 + j * spacing)."""

    x0: float
    y0: float
    spacing: float
    z: np.ndarray

    @property
    def centre(self) -> tuple[float, float]:
        half = 0.5 * (self.z.shape[1] - 1) * self.spacing
        return self.x0 + half, self.y0 + half

    def height(self, x_m: float, y_m: float) -> float | None:
        """Bilinear height at (x, y); None outside the patch."""
        n = self.z.shape[0] - 1
        u, v = (x_m - self.x0) / self.spacing, (y_m - self.y0) / self.spacing  # spacing > 0 (constructor)
        if not (0.0 <= u <= n and 0.0 <= v <= n):
            return None
        i, j = min(int(u), n - 1), min(int(v), n - 1)
        fu, fv = u - i, v - j
        z = self.z
        return float((z[j, i] * (1 - fu) + z[j, i + 1] * fu) * (1 - fv)
                     + (z[j + 1, i] * (1 - fu) + z[j + 1, i + 1] * fu) * fv)


def patch_request(cx: float, cy: float, posts: int = POSTS, spacing: float = SPACING_M
                  ) -> tuple[query_pb2.HeightOfTerrainRequest, float, float]:
    """The request for a patch centred on (cx, cy), and the patch's corner (x0, y0)."""
    half = 0.5 * (posts - 1) * spacing
    x0, y0 = cx - half, cy - half
    xs = x0 + spacing * np.arange(posts)
    ys = y0 + spacing * np.arange(posts)
    gx, gy = np.meshgrid(xs, ys)
    return (query_pb2.HeightOfTerrainRequest(x=gx.ravel().tolist(), y=gy.ravel().tolist(),
                                             z_max=[math.inf] * (posts * posts)), x0, y0)


class QueryGround:
    """The ground from a channel worker's QueryService (module doc).

    Args:
        address: the worker's host:port (the rig's query channel).
        start_xy_m: where the first patch is centred (the aircraft's start).
        security: the rig's TLS settings.
        fallback_z_m: the ground where the databases have none or the worker does not answer.
        timeout_s: deadline of each request after the first.
        channel: a ready channel (tests); else one is made to address.
    """

    def __init__(self, address: str, *, start_xy_m: tuple[float, float], security: Security | None = None,
                 fallback_z_m: float = 0.0, timeout_s: float = 1.0, first_wait_s: float = FIRST_WAIT_S,
                 posts: int = POSTS, spacing_m: float = SPACING_M, channel: grpc.Channel | None = None) -> None:
        if not (spacing_m > 0.0 and math.isfinite(spacing_m)):
            raise ValueError(f"spacing_m: {spacing_m} must be a finite number > 0")
        if not 2 <= posts <= 32:
            raise ValueError(f"posts: {posts} must be within 2 .. 32 (one request holds at most 1024 queries)")
        self.address = address
        self.fallback_z_m = float(fallback_z_m)
        self.timeout_s = float(timeout_s)
        self.posts, self.spacing = int(posts), float(spacing_m)
        self._channel = channel or make_channel(address, security)
        self._stub = query_pb2_grpc.QueryServiceStub(self._channel)
        self._patch: Patch | None = None
        self._last = self.fallback_z_m
        self._lock = threading.Lock()
        self._want: tuple[float, float] | None = None
        self._busy = False  # a fetch asked for is pending or in flight: no second one
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._warned = False
        self.patches = 0
        self.failures = 0
        self.outside = 0
        self.database_warning = ""
        self._fetch(float(start_xy_m[0]), float(start_xy_m[1]), timeout_s=first_wait_s, wait=True)
        self._thread = threading.Thread(target=self._run, name="ground-patches", daemon=True)
        self._thread.start()

    def _fetch(self, cx: float, cy: float, *, timeout_s: float, wait: bool = False) -> bool:
        request, x0, y0 = patch_request(cx, cy, self.posts, self.spacing)
        try:
            answer = self._stub.HeightOfTerrain(request, timeout=timeout_s, wait_for_ready=wait)
        except grpc.RpcError as exc:
            with self._lock:
                self.failures += 1
                first = not self._warned
                self._warned = True
            if first:
                log.warning("the ground under the aircraft: the query service at %s did not answer (%s); the "
                            "wheels roll on the plane z = %g m until it does (retried every %g s)", self.address,
                            exc.code().name, self.fallback_z_m, RETRY_S)
            return False
        z = np.where(np.asarray(answer.valid, dtype=bool), np.asarray(answer.height_m, dtype=np.float64),
                     self.fallback_z_m).reshape(self.posts, self.posts)
        if answer.database_warning and not self.database_warning:
            log.warning("the ground under the aircraft: the query worker %s's scene database %s; elsewhere the "
                        "ground is the plane z = %g m", self.address, answer.database_warning, self.fallback_z_m)
        with self._lock:
            self.database_warning = answer.database_warning
            self._patch = Patch(x0, y0, self.spacing, z)
            self.patches += 1
        return True

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(RETRY_S)
            self._wake.clear()
            with self._lock:
                want = self._want
            if want is None or self._stop.is_set():
                continue
            if self._fetch(*want, timeout_s=self.timeout_s):
                with self._lock:
                    self._want, self._busy = None, False
            else:
                self._stop.wait(RETRY_S)  # the same patch again: the aircraft is still near it

    def __call__(self, x_m: float, y_m: float) -> float:
        with self._lock:
            patch = self._patch
        if patch is None:
            self._ask(x_m, y_m)
            return self.fallback_z_m
        z = patch.height(x_m, y_m)
        cx, cy = patch.centre
        half = 0.5 * (self.posts - 1) * self.spacing
        if max(abs(x_m - cx), abs(y_m - cy)) > RECENTRE_FRACTION * half:
            self._ask(x_m, y_m)
        if z is None:
            with self._lock:
                self.outside += 1
            return self._last
        self._last = z
        return z

    def _ask(self, x_m: float, y_m: float) -> None:
        with self._lock:
            if not self._busy:
                self._want, self._busy = (x_m, y_m), True
                self._wake.set()

    def status(self) -> dict[str, int | str]:
        """Patches fetched, requests failed, look-ups outside every patch (the last height held)."""
        with self._lock:
            return {"address": self.address, "patches": self.patches, "failures": self.failures,
                    "outside": self.outside}

    def close(self) -> None:
        """Stop fetching and close the channel; says the counters in the log."""
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=2.0)
        self._channel.close()
        s = self.status()
        log.info("the ground under the aircraft: %d patch(es) from %s, %d request(s) failed, %d look-up(s) "
                 "outside every patch", s["patches"], s["address"], s["failures"], s["outside"])

