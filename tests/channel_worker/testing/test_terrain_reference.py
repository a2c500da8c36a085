"""The exact terrain reference (channel_worker/testing/terrain_reference.py) against analytic
answers and an independent brute-force march.

Expectations are computed here without the module's code: rays from the conventions' screen
formula (docs/conventions.md), surfaces from the node grids with numpy, sRGB decoded with the
scene parser's srgb_to_linear.
"""

import math

import numpy as np
import pytest

from channel_worker.pipeline.geometry.view import make_view
from channel_worker.pipeline.scene.terrain.database import Pattern, TerrainDatabase
from channel_worker.testing.terrain_reference import (
    SRGB_TO_LINEAR,
    first_root,
    reference_rays,
    reference_terrain,
    single_level_database,
)
from services.rig.colour import srgb_to_linear
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

CHANNEL = ChannelSpec.symmetric("c", 40, 30, 60.0)
RGSS4 = RenderOptions(samples="rgss4").sample_offsets()
RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)


def lin(srgb) -> np.ndarray:
    return srgb_to_linear(np.asarray(srgb, np.float64) / 255.0)


def uniform_colours(shape, srgb=(200, 120, 40)) -> np.ndarray:
    out = np.zeros(tuple(shape) + (3,), np.uint8)
    out[...] = srgb
    return out


def plane_db(a: float, b: float, c: float, *, n: int = 64, spacing: float = 2.0,
             origin=(0.0, 0.0, 0.0), srgb=(200, 120, 40)) -> TerrainDatabase:
    """Heights a x + b y + c (x, y metres from the origin) on an n x n voxel grid."""
    x = np.arange(n + 1) * spacing
    h = (a * x[None, :] + b * x[:, None] + c).astype(np.float32)
    assert np.array_equal(h.astype(np.float64), a * x[None, :] + b * x[:, None] + c)  # exact
    return single_level_database(h, uniform_colours(h.shape, srgb), spacing, np.array(origin))


def sample_directions(view, offsets) -> np.ndarray:
    """(H, W, S, 3) unit world directions by the conventions' screen formula."""
    sx = np.arange(view.width)[None, :, None] + offsets[None, None, :, 0]
    sy = np.arange(view.height)[:, None, None] + offsets[None, None, :, 1]
    tx = view.tan_left + sx / view.width * (view.tan_right - view.tan_left)
    ty = view.tan_top - sy / view.height * (view.tan_top - view.tan_bottom)
    eye = np.stack(np.broadcast_arrays(tx, ty, np.ones_like(tx)), axis=-1)
    world = eye @ view.world_to_eye  # = world_to_eye.T @ eye per sample
    return world / np.linalg.norm(world, axis=-1, keepdims=True)


def analytic_plane(eye_rel, d, a, b, c, extent, max_range=200_000.0):
    """First point of the solid {0 <= x, y <= extent, z <= a x + b y + c} on each ray.

    Returns (hit, range). A ray that enters the footprint below the plane hits the edge wall.
    """
    p = np.asarray(eye_rel, np.float64)
    t0 = np.zeros(d.shape[:-1])
    t1 = np.full(d.shape[:-1], max_range)
    for axis in (0, 1):
        with np.errstate(divide="ignore", invalid="ignore"):
            ta = (0.0 - p[axis]) / d[..., axis]
            tb = (extent - p[axis]) / d[..., axis]
        lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
        flat = d[..., axis] == 0.0
        inside = 0.0 <= p[axis] <= extent
        lo = np.where(flat, -np.inf if inside else np.inf, lo)
        hi = np.where(flat, np.inf if inside else -np.inf, hi)
        t0, t1 = np.maximum(t0, lo), np.minimum(t1, hi)

    def below(t):
        q = p + t[..., None] * d
        return q[..., 2] - (a * q[..., 0] + b * q[..., 1] + c)

    slope = d[..., 2] - a * d[..., 0] - b * d[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_plane = -(p[2] - (a * p[0] + b * p[1] + c)) / slope
    wall = (t0 <= t1) & (below(t0) <= 0.0)
    crossing = (t0 <= t1) & (slope < 0.0) & (t_plane >= t0) & (t_plane <= t1)
    hit = wall | crossing
    rng = np.where(wall, t0, np.where(crossing, t_plane, np.inf))
    return hit, rng


def bilinear_nodes(nodes, spacing, x, y):
    """Bilinear interpolation of a node grid ([j, i], ...) at origin-relative x, y; NaN outside."""
    nyn, nxn = nodes.shape[:2]
    i = np.clip(np.floor(x / spacing).astype(int), 0, nxn - 2)
    j = np.clip(np.floor(y / spacing).astype(int), 0, nyn - 2)
    u, v = x / spacing - i, y / spacing - j
    if nodes.ndim == 3:
        u, v = u[..., None], v[..., None]
    out = (nodes[j, i] * (1 - u) * (1 - v) + nodes[j, i + 1] * u * (1 - v)
           + nodes[j + 1, i] * (1 - u) * v + nodes[j + 1, i + 1] * u * v)
    inside = (x >= 0) & (x <= (nxn - 1) * spacing) & (y >= 0) & (y <= (nyn - 1) * spacing)
    if nodes.ndim == 3:
        inside = inside[..., None]
    return np.where(inside, out, np.nan)


def hill_nodes(n=40, spacing=2.0):
    """A rotated elliptic paraboloid (it has an xy term, so voxels are twisted) and colours."""
    x = np.arange(n + 1) * spacing
    dx, dy = x[None, :] - 45.0, x[:, None] - 40.0
    h = (30.0 - (dx ** 2 + dy ** 2 + 0.8 * dx * dy) / 40.0).astype(np.float32)
    rng = np.random.default_rng(7)
    colours = rng.integers(0, 256, size=h.shape + (3,), dtype=np.uint8)
    return h, colours


def view_of(eye, h, p, r, channel=CHANNEL):
    return make_view(channel, Eyepoint.of(*eye, h, p, r))


# ----------------------------------------------------------------------------- flat and tilted


ATTITUDES = [(0, -30, 0), (37, -60, 15), (200, -89, -40), (90, -10, 0), (300, -90, 0),
             (45, -90, 70), (10, -20, 90), (130, -25, 180), (0, -40, 90), (250, -5, -90)]


@pytest.mark.parametrize("hpr", ATTITUDES)
def test_flat_plane_range_and_colour_are_analytic(hpr):
    h, origin, eye_rel = 12.5, np.array([100.0, -50.0, 3.0]), np.array([60.0, 70.0, 52.0])
    db = plane_db(0.0, 0.0, h, origin=origin)
    view = view_of(origin + eye_rel, *hpr)
    ref = reference_terrain(db, view, RGSS4)
    hit, rng = analytic_plane(eye_rel, sample_directions(view, RGSS4), 0.0, 0.0, h, 128.0)
    assert ref.hit.any()
    np.testing.assert_array_equal(ref.hit, hit)
    np.testing.assert_allclose(ref.range_m[hit], rng[hit], rtol=1e-9, atol=0)
    assert np.all(np.isinf(ref.range_m[~hit]))
    np.testing.assert_allclose(ref.rgb[hit], np.broadcast_to(lin((200, 120, 40)), (hit.sum(), 3)),
                               rtol=1e-12)
    assert np.all(ref.rgb[~hit] == 0.0)


@pytest.mark.parametrize("hpr", [(0, -30, 0), (135, -45, 20), (270, -35, -10), (20, -90, 0)])
def test_tilted_plane_range_is_analytic(hpr):
    a, b, c = 0.25, -0.125, 20.0  # dyadic: the float32 node heights are exact
    eye_rel = np.array([64.0, 64.0, 70.0])
    db = plane_db(a, b, c)
    view = view_of(eye_rel, *hpr)
    ref = reference_terrain(db, view, RGSS4)
    hit, rng = analytic_plane(eye_rel, sample_directions(view, RGSS4), a, b, c, 128.0)
    assert ref.hit.sum() > 100
    np.testing.assert_array_equal(ref.hit, hit)
    np.testing.assert_allclose(ref.range_m[hit], rng[hit], rtol=1e-9, atol=0)


def test_roll_90_puts_the_ground_on_the_right():
    view = view_of((3200.0, 3200.0, 30.0), 0, 0, 90)  # right wing down: eye right = world down
    db = plane_db(0.0, 0.0, 0.0, spacing=100.0)  # 6.4 km: the shallowest rays hit at 2.1 km
    ref = reference_terrain(db, view, RenderOptions(samples="centre").sample_offsets())
    assert ref.hit[:, view.width // 2:].all()
    assert not ref.hit[:, :view.width // 2].any()


def test_roll_180_is_the_image_turned_half_round():
    h, colours = hill_nodes()
    db = single_level_database(h, colours, 2.0, np.zeros(3))
    centre = RenderOptions(samples="centre").sample_offsets()
    upright = reference_terrain(db, view_of((5.0, 8.0, 45.0), 40, -20, 0), centre)
    turned = reference_terrain(db, view_of((5.0, 8.0, 45.0), 40, -20, 180), centre)
    assert upright.hit.any() and not upright.hit.all()
    np.testing.assert_array_equal(turned.hit, upright.hit[::-1, ::-1])
    hit = upright.hit[..., 0]
    np.testing.assert_allclose(turned.range_m[::-1, ::-1][hit], upright.range_m[hit], rtol=1e-9)
    np.testing.assert_allclose(turned.rgb[::-1, ::-1][hit], upright.rgb[hit], atol=1e-9)


# ----------------------------------------------------------------------------- grazing, edges


@pytest.mark.parametrize("clearance", [1e-2, 1e-4, 1e-6])
def test_grazing_rays_along_a_plane(clearance):
    h = 12.5
    db = plane_db(0.0, 0.0, h, n=200, spacing=1.0)
    eye_rel = np.array([3.0, 3.0, h + clearance])
    depression = np.array([1e-4, 3e-4, 1e-3, 1e-2, 0.3])  # radians below the horizon
    azimuth = np.radians([10.0, 33.0, 45.0, 60.0, 80.0])
    d = np.stack([np.cos(depression) * np.sin(azimuth), np.cos(depression) * np.cos(azimuth),
                  -np.sin(depression)], -1)
    d = np.concatenate([d, [[0.6, 0.8, 0.0]]])  # parallel to the plane, above it: never hits
    _rgb, rng, hit = reference_rays(db, eye_rel, d)
    expect_hit, expect = analytic_plane(eye_rel, d, 0.0, 0.0, h, 200.0)
    np.testing.assert_array_equal(hit, expect_hit)
    assert not hit[-1]
    np.testing.assert_allclose(rng[hit], expect[hit], rtol=1e-9, atol=0)


def test_grazing_rays_along_a_tilted_plane():
    a, b, c = 0.25, -0.125, 20.0
    db = plane_db(a, b, c)
    eye_rel = np.array([10.0, 100.0, a * 10.0 + b * 100.0 + c + 1e-3])
    # Directions in the plane (up its slope, across it), then tipped into it by a tiny angle.
    along = np.array([[1.0, 0.0, a], [0.0, -1.0, -b], [1.0, -1.0, a - b], [2.0, 1.0, 2 * a + b]])
    normal = np.array([-a, -b, 1.0]) / math.sqrt(a * a + b * b + 1.0)
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    d = along - 1e-4 * normal
    _, rng, hit = reference_rays(db, eye_rel, d)
    expect_hit, expect = analytic_plane(eye_rel, d / np.linalg.norm(d, axis=1, keepdims=True),
                                        a, b, c, 128.0)
    assert hit.all()
    np.testing.assert_array_equal(hit, expect_hit)
    np.testing.assert_allclose(rng, expect, rtol=1e-9, atol=0)


def test_rays_from_outside_enter_the_database_and_hit_plane_or_edge_wall():
    h = 12.5
    db = plane_db(0.0, 0.0, h)
    eye_rel = np.array([-40.0, 64.0, 16.0])  # west of the database, 3.5 m above its surface
    view = view_of(eye_rel, 90, -5, 0)  # looking east
    ref = reference_terrain(db, view, RGSS4)
    hit, rng = analytic_plane(eye_rel, sample_directions(view, RGSS4), 0.0, 0.0, h, 128.0)
    d = sample_directions(view, RGSS4)
    entry = (0.0 - eye_rel[0]) / d[..., 0]
    walls = hit & np.isclose(rng, entry, rtol=1e-12)
    assert walls.sum() > 10 and (hit & ~walls).sum() > 10  # both the edge wall and the top
    assert (~hit).sum() > 10  # and rays that pass over and leave without hitting
    np.testing.assert_array_equal(ref.hit, hit)
    np.testing.assert_allclose(ref.range_m[hit], rng[hit], rtol=1e-9, atol=0)
    np.testing.assert_allclose(ref.rgb[walls],
                               np.broadcast_to(lin((200, 120, 40)), (walls.sum(), 3)), rtol=1e-12)


def test_max_range_turns_farther_hits_into_misses():
    db = plane_db(0.0, 0.0, 0.0)
    d = np.array([[0.0, 0.0, -1.0], [0.6, 0.0, -0.8]])
    _, rng, hit = reference_rays(db, np.array([10.0, 10.0, 8.0]), d, max_range=9.0)
    assert hit[0] and rng[0] == 8.0
    assert not hit[1] and rng[1] == np.inf  # the hit is 10 m away


def test_step_between_voxels_is_a_wall_coloured_by_the_voxel_entered():
    n = 20
    h = np.zeros((n + 1, n + 1), np.float32)
    db = single_level_database(h, uniform_colours(h.shape), 4.0, np.zeros(3), page_size=8)
    page, vy, vx = 1 * 3 + 1, 10 - 8, 10 - 8  # voxel (10, 10): page (1, 1) of a 3 x 3 table
    db.z[page, vy, vx, :] = 5.0  # a 5 m block over [40, 44] x [40, 44], neighbours stay at 0
    db.rgb[page, vy, vx, :, :] = BLUE
    eye = np.array([2.0, 42.0, 2.0])
    rgb, rng, hit = reference_rays(db, eye, np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.1]]))
    assert hit[0] and rng[0] == pytest.approx(38.0, rel=1e-12)
    np.testing.assert_allclose(rgb[0], lin(BLUE), atol=1e-15)
    assert not hit[1]  # climbs over the block: 5.8 m high at x = 40


# ----------------------------------------------------------------------------- the hill


def brute_force(nodes, colours, spacing, eye_rel, d, t_end, step=0.01):
    """First t where the ray is at or below the bilinear surface: 1 cm steps, then bisection."""
    lin_nodes = srgb_to_linear(colours.astype(np.float64) / 255.0)
    t = np.arange(0.0, t_end, step)
    hit = np.zeros(len(d), bool)
    rng = np.full(len(d), np.inf)
    rgb = np.zeros((len(d), 3))

    def f(tt, dd):
        q = eye_rel + tt[..., None] * dd
        return q[..., 2] - bilinear_nodes(nodes.astype(np.float64), spacing, q[..., 0], q[..., 1])

    for n in range(len(d)):
        below = f(t, d[n]) <= 0.0  # NaN (off the database) is never below
        if not below.any():
            continue
        k = int(np.argmax(below))
        assert k > 0  # the eye is above the surface
        lo, hi = t[k - 1], t[k]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if f(np.array(mid), d[n]) <= 0.0:
                hi = mid
            else:
                lo = mid
        hit[n], rng[n] = True, hi
        q = eye_rel + hi * d[n]
        rgb[n] = bilinear_nodes(lin_nodes, spacing, np.array(q[0]), np.array(q[1]))
    return hit, rng, rgb


def test_hill_matches_a_brute_force_march():
    h, colours = hill_nodes()
    assert np.abs(h[:-1, :-1] - h[:-1, 1:] - h[1:, :-1] + h[1:, 1:]).min() > 0.01  # twisted voxels
    db = single_level_database(h, colours, 2.0, np.zeros(3))
    eye_rel = np.array([30.0, 24.0, 45.0])  # over a node
    rng_gen = np.random.default_rng(3)
    count = 300
    azimuth = rng_gen.uniform(0.0, 2 * np.pi, count)
    depression = rng_gen.uniform(np.radians(20.0), np.radians(80.0), count)
    d = np.stack([np.cos(depression) * np.sin(azimuth), np.cos(depression) * np.cos(azimuth),
                  -np.sin(depression)], -1)
    # Diagonals from a node: through a grid corner at every step (the DDA's x/y ties).
    diagonal = np.array([[1.0, 1.0, -0.9], [-1.0, 1.0, -0.7], [1.0, -1.0, -1.3], [2.0, 2.0, -1.0]])
    d = np.concatenate([d, diagonal / np.linalg.norm(diagonal, axis=1, keepdims=True)])
    rgb, rng, hit = reference_rays(db, eye_rel, d)
    b_hit, b_rng, b_rgb = brute_force(h, colours, 2.0, eye_rel, d, t_end=160.0)
    assert b_hit.sum() > 80 and (~b_hit).sum() > 80  # both, a fair share each
    np.testing.assert_array_equal(hit, b_hit)
    np.testing.assert_allclose(rng[hit], b_rng[hit], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rgb[hit], b_rgb[hit], rtol=0, atol=1e-6)


def test_hill_seen_straight_down_and_up():
    h, colours = hill_nodes()
    db = single_level_database(h, colours, 2.0, np.zeros(3))
    points = np.array([[45.0, 40.0], [13.3, 71.9], [0.0, 0.0], [80.0, 80.0], [40.0, 7.0]])
    lin_nodes = srgb_to_linear(colours.astype(np.float64) / 255.0)
    for x, y in points:
        eye_rel = np.array([x, y, 60.0])
        rgb, rng, hit = reference_rays(db, eye_rel, np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]))
        ground = float(bilinear_nodes(h.astype(np.float64), 2.0, np.array(x), np.array(y)))
        assert hit[0] and not hit[1]
        assert rng[0] == pytest.approx(60.0 - ground, rel=1e-12)
        np.testing.assert_allclose(rgb[0], bilinear_nodes(lin_nodes, 2.0, np.array(x), np.array(y)),
                                   atol=1e-12)


def test_far_from_the_world_origin_gives_the_same_result():
    h, colours = hill_nodes()
    shift = np.array([1_000_000.25, -1_000_000.5, 850.0])
    near = single_level_database(h, colours, 2.0, np.zeros(3))
    far = single_level_database(h, colours, 2.0, shift)
    eye_rel = np.array([8.3, 12.1, 34.7])
    for hpr in [(40, -25, 5), (210, -60, -30)]:
        a = reference_terrain(near, view_of(eye_rel, *hpr), RGSS4)
        b = reference_terrain(far, view_of(shift + eye_rel, *hpr), RGSS4)
        assert a.hit.any()
        np.testing.assert_array_equal(a.hit, b.hit)
        np.testing.assert_allclose(b.range_m[a.hit], a.range_m[a.hit], rtol=0, atol=1e-6)
        np.testing.assert_allclose(b.rgb, a.rgb, rtol=0, atol=1e-6)


# ----------------------------------------------------------------------------- patterns

BANDS = Pattern("mast", np.array([3.0, 7.0, 12.0], np.float32),
                np.array([RED, GREEN, BLUE], np.uint8))


def pattern_db():
    """20 x 20 voxels of 4 m, ground 0.5 y (rising north), voxel (10, 10) carries BANDS."""
    n = 20
    y = np.arange(n + 1) * 4.0
    h = np.broadcast_to((0.5 * y)[:, None], (n + 1, n + 1)).astype(np.float32)
    mask = np.zeros((n, n), np.uint8)
    mask[10, 10] = 1
    return single_level_database(h, uniform_colours(h.shape), 4.0, np.zeros(3), pattern_mask=mask,
                                 patterns=(BANDS,))


def test_pattern_side_is_banded_by_height_above_the_ground():
    db = pattern_db()
    top = 0.5 * 44.0 + 12.0  # highest corner (north edge) + last band top
    eye = np.array([4.0, 42.0, 30.0])
    targets, bands = [], []
    for y in (40.5, 42.0, 43.5):
        ground = 0.5 * y
        for above, band in ((0.5, 0), (2.9, 0), (3.1, 1), (6.9, 1), (7.1, 2), (11.9, 2)):
            targets.append((40.0, y, ground + above))
            bands.append(band)
    targets.append((40.0, 40.5, 0.5 * 40.5 + 13.0))  # above the last band, under the box top
    bands.append(2)
    targets = np.array(targets)
    assert targets[:, 2].max() < top
    d = targets - eye
    rgb, rng, hit = reference_rays(db, eye, d)
    assert hit.all()
    np.testing.assert_allclose(rng, np.linalg.norm(d, axis=1), rtol=1e-12)
    np.testing.assert_allclose(rgb, lin(np.array([RED, GREEN, BLUE])[bands]), atol=1e-15)
    # Just over the box top: the ray passes over the box.
    _, over, over_hit = reference_rays(db, eye, np.array([[40.0, 42.0, top + 0.01]]) - eye)
    assert not over_hit[0] or over[0] > np.linalg.norm([36.0, 0.0, top + 0.01 - 30.0]) + 4.0


def test_pattern_top_has_the_last_band_colour():
    db = pattern_db()
    top = 0.5 * 44.0 + 12.0
    rgb, rng, hit = reference_rays(db, np.array([42.0, 42.0, 50.0]), np.array([[0.0, 0.0, -1.0]]))
    assert hit[0] and rng[0] == pytest.approx(50.0 - top, rel=1e-12)
    np.testing.assert_allclose(rgb[0], lin(BLUE), atol=1e-15)
    eye = np.array([20.0, 20.0, 60.0])
    target = np.array([41.0, 43.0, top])
    rgb, rng, hit = reference_rays(db, eye, (target - eye)[None])
    assert hit[0] and rng[0] == pytest.approx(np.linalg.norm(target - eye), rel=1e-12)
    np.testing.assert_allclose(rgb[0], lin(BLUE), atol=1e-15)


def test_pattern_seen_through_a_view():
    db = pattern_db()
    view = view_of((6.0, 42.0, 25.0), 90, 0, 0)  # looking east at the box's west side
    ref = reference_terrain(db, view, RenderOptions(samples="centre").sample_offsets())
    band_hits = np.zeros(3, int)
    for b, srgb in enumerate((RED, GREEN, BLUE)):
        band_hits[b] = np.all(np.isclose(ref.rgb[..., 0, :], lin(srgb), atol=1e-12), axis=-1).sum()
    assert np.all(band_hits > 0)  # every band is seen
    d = sample_directions(view, RenderOptions(samples="centre").sample_offsets())[..., 0, :]
    on_side = np.any([np.all(np.isclose(ref.rgb[..., 0, :], lin(c), atol=1e-12), axis=-1)
                      for c in (RED, GREEN, BLUE)], axis=0)
    side_range = (40.0 - 6.0) / d[..., 0]
    np.testing.assert_allclose(ref.range_m[..., 0][on_side], side_range[on_side], rtol=1e-12)


# ----------------------------------------------------------------------------- colours, levels


def test_colours_are_decoded_then_interpolated_in_linear():
    np.testing.assert_allclose(SRGB_TO_LINEAR, srgb_to_linear(np.arange(256) / 255.0), rtol=1e-15)
    h = np.zeros((2, 2), np.float32)
    colours = np.array([[[0, 0, 0], [255, 255, 255]], [[0, 0, 0], [255, 255, 255]]], np.uint8)
    db = single_level_database(h, colours, 10.0, np.zeros(3))
    rgb, _, hit = reference_rays(db, np.array([5.0, 5.0, 3.0]), np.array([[0.0, 0.0, -1.0]]))
    assert hit[0]
    np.testing.assert_allclose(rgb[0], [0.5, 0.5, 0.5], rtol=1e-15)  # not decode(127.5) = 0.212


def two_level_database(coarse_heights, coarse_colours, spacing, missing_fine_pages):
    """Level 0 = the exact refinement of the coarse bilinear surface, coloured RED; level 1 =
    the coarse grid; level-0 pages in missing_fine_pages are absent from the table."""
    hc = np.asarray(coarse_heights, np.float64)
    fine = np.zeros((2 * hc.shape[0] - 1, 2 * hc.shape[1] - 1))
    fine[::2, ::2] = hc
    fine[1::2, ::2] = 0.5 * (hc[:-1] + hc[1:])
    fine[:, 1::2] = 0.5 * (fine[:, :-2:2] + fine[:, 2::2])
    fine32 = fine.astype(np.float32)
    assert np.array_equal(fine32, fine)  # the refinement is exact in float32
    level0 = single_level_database(fine32, uniform_colours(fine.shape, RED), spacing,
                                   np.zeros(3), page_size=4)
    level1 = single_level_database(hc.astype(np.float32), coarse_colours, 2 * spacing,
                                   np.zeros(3), page_size=4)
    table0 = level0.page_table.copy()
    for px, py in missing_fine_pages:
        table0[py * level0.pages_x[0] + px] = -1
    n0 = level0.z.shape[0]
    db = TerrainDatabase(
        spacing_m=spacing, origin=np.zeros(3), nx=level0.nx, ny=level0.ny, page_size=4, levels=2,
        pages_x=np.array([level0.pages_x[0], level1.pages_x[0]]),
        pages_y=np.array([level0.pages_y[0], level1.pages_y[0]]),
        table_offset=np.array([0, table0.size]),
        page_table=np.concatenate([table0, level1.page_table + n0]).astype(np.int32),
        z=np.concatenate([level0.z, level1.z]), rgb=np.concatenate([level0.rgb, level1.rgb]),
        pattern=np.concatenate([level0.pattern, level1.pattern]),
        z_min=level0.z_min, z_max=level0.z_max)
    return db, level0


def test_missing_level0_pages_fall_back_to_the_coarser_level():
    rng_gen = np.random.default_rng(11)
    hc = rng_gen.integers(0, 80, size=(9, 9)) * 0.25  # 8 x 8 coarse voxels of 4 m
    colours = rng_gen.integers(0, 256, size=(9, 9, 3), dtype=np.uint8)
    missing = [(1, 1), (2, 1), (3, 3), (0, 2)]  # level-0 pages of 4 x 4 voxels (8 m)
    db, fine_only = two_level_database(hc, colours, 2.0, missing)
    view = view_of((16.0, -6.0, 40.0), 20, -45, 0)
    ref = reference_terrain(db, view, RGSS4)
    fine = reference_terrain(fine_only, view, RGSS4)
    assert ref.hit.sum() > 1000
    np.testing.assert_array_equal(ref.hit, fine.hit)  # the same surface
    np.testing.assert_allclose(ref.range_m[ref.hit], fine.range_m[ref.hit], rtol=1e-12)
    # Colours: RED where the level-0 page exists, else the coarse voxel's colours.
    d = sample_directions(view, RGSS4)[ref.hit]
    q = np.array([16.0, -6.0, 40.0]) + ref.range_m[ref.hit][:, None] * d
    page = np.stack([np.floor(q[:, 0] / 8.0), np.floor(q[:, 1] / 8.0)], -1).astype(int)
    from_coarse = np.array([tuple(p) in missing for p in page])
    interior = np.all(np.abs(q[:, :2] / 8.0 - np.round(q[:, :2] / 8.0)) > 1e-6, axis=1)
    assert from_coarse[interior].sum() > 100 and (~from_coarse[interior]).sum() > 100
    expected = np.where(from_coarse[:, None],
                        bilinear_nodes(srgb_to_linear(colours / 255.0), 4.0, q[:, 0], q[:, 1]),
                        lin(RED)[None, :])
    np.testing.assert_allclose(ref.rgb[ref.hit][interior], expected[interior], atol=1e-9)


def test_a_coarsest_level_lacking_a_page_is_rejected():
    db, _ = two_level_database(np.zeros((9, 9)), uniform_colours((9, 9)), 2.0, [])
    db.page_table[-1] = -1
    with pytest.raises(ValueError, match=r"coarsest level 1 lacks page \(1, 1\)"):
        reference_rays(db, np.array([1.0, 1.0, 5.0]), np.array([[0.0, 0.0, -1.0]]))


# ----------------------------------------------------------------------------- eye, API


def test_eye_below_the_surface_or_inside_a_box_is_an_error():
    db = plane_db(0.0, 0.0, 12.5, origin=(0.0, 0.0, 100.0))
    with pytest.raises(ValueError, match=r"eye height 110.0 m is not above the terrain "
                                         r"surface 112.5 m"):
        reference_rays(db, np.array([5.0, 5.0, 110.0]), np.array([[0.0, 0.0, -1.0]]))
    with pytest.raises(ValueError, match="not above"):  # exactly on it
        reference_rays(db, np.array([5.0, 5.0, 112.5]), np.array([[0.0, 0.0, -1.0]]))
    with pytest.raises(ValueError, match=r"inside a pattern box"):
        reference_rays(pattern_db(), np.array([42.0, 42.0, 25.0]), np.array([[0.0, 0.0, -1.0]]))
    # Below the surface's height but outside the footprint is fine: it sees the edge wall.
    _, rng, hit = reference_rays(db, np.array([-3.0, 5.0, 105.0]), np.array([[1.0, 0.0, 0.0]]))
    assert hit[0] and rng[0] == 3.0


def test_pixel_helpers_average_samples_over_a_background():
    db = plane_db(0.0, 0.0, 0.0)
    view = view_of((64.0, 64.0, 10.0), 0, 0, 0)  # the horizon crosses the middle rows
    ref = reference_terrain(db, view, RGSS4)
    partial = ref.hit.any(axis=2) & ~ref.hit.all(axis=2)
    assert partial.any()
    bg = np.array([0.1, 0.2, 0.9])
    px = ref.pixel_rgb(bg)
    y, x = np.argwhere(partial)[0]
    expected = np.mean([ref.rgb[y, x, s] if ref.hit[y, x, s] else bg for s in range(4)], axis=0)
    np.testing.assert_allclose(px[y, x], expected, rtol=1e-15)
    np.testing.assert_array_equal(ref.pixel_range(), ref.range_m.min(axis=2))


def test_bad_arguments_are_named():
    db = plane_db(0.0, 0.0, 0.0)
    view = view_of((1.0, 1.0, 5.0), 0, -30, 0)
    with pytest.raises(ValueError, match="offsets"):
        reference_terrain(db, view, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="max_range"):
        reference_terrain(db, view, RGSS4, max_range=0.0)
    with pytest.raises(ValueError, match=r"directions\[1\]"):
        reference_rays(db, np.array([1.0, 1.0, 5.0]), np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0]]))


# ----------------------------------------------------------------------------- the quadratic


@pytest.mark.parametrize(("f0", "f1", "f2", "length", "expected"), [
    (1.0, -1e8, 1.0, 1.0, 1e-8),        # catastrophic cancellation in the textbook formula
    (1.0, -2.0, 1e-30, 10.0, 0.5),      # nearly linear: the far root is 2e30
    (1.0, -2.0, -1e-30, 10.0, 0.5),
    (1.0, -2.0, 0.0, 10.0, 0.5),        # linear
    (1.0, -2.0, 0.0, 0.4, -1.0),        # linear, root beyond the segment
    (1.0, 2.0, 0.0, 10.0, -1.0),        # linear, moving away
    (2.0, -3.0, 1.0, 10.0, 1.0),        # roots 1 and 2: the smaller
    (2.0, -3.0, 1.0, 0.5, -1.0),        # both beyond the segment
    (1.0, 0.0, -1.0, 10.0, 1.0),        # f1 = 0, roots -1 and 1
    (1.0, 0.0, 1.0, 10.0, -1.0),        # no real root
    (1.0, 3.0, 1.0, 10.0, -1.0),        # both roots negative
    (1.0, -2.0, 1.0, 10.0, 1.0),        # double root (tangent): a hit
    (1e-300, -1.0, 1.0, 1.0, 1e-300),   # starts on the surface to within underflow
])
def test_first_root(f0, f1, f2, length, expected):
    got = first_root(f0, f1, f2, length)
    if expected < 0:
        assert got == -1.0
    else:
        assert got == pytest.approx(expected, rel=1e-12)
