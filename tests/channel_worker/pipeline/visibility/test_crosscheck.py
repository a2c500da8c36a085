"""Cross-check: the sub-area renderer (EP 0611020) and the scan-line renderer (ARL Systems Note 77) see the
same feature at every pixel centre of opaque scenes without the tie cases of docs/scanline.md.

The scenes are boxes floating in depth slabs that do not overlap along the view direction, so
the scan-line priority list (centroid depth) is a correct visibility order, plus runway-style
markings declared on their base face (shared plane, decided by layer in both renderers).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import parse_scene
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

from ..conftest import box_model, scene_doc

CH = ChannelSpec.symmetric("c", 96, 64, 70.0)


def seen_features(database, eyepoint: Eyepoint, renderer: str, channel: ChannelSpec = CH) -> np.ndarray:
    """(H, W) feature id at each pixel centre, or the SKY_ID / EARTH_ID background."""
    trace: dict = {}
    render_frame(database, channel, eyepoint, RenderOptions(samples="centre", renderer=renderer), trace=trace)
    opaque = trace["buffer"].opaque[..., 0]
    if trace["screen"].polygon_count == 0:
        return opaque
    ids = trace["screen"].feature_id[np.maximum(opaque, 0)]
    return np.where(opaque >= 0, ids, opaque)


def box_scene(origin: np.ndarray, heading: float, pitch: float, boxes: list) -> tuple:
    """Boxes in slabs along the view direction, 40 m apart (box k centred 35 + 40 k m ahead,
    at most 10 m deep), offset from the view axis by (radius as a fraction of that distance,
    angle in degrees): radius <= 0.35 keeps the centre inside the field of view at any roll."""
    h, p = np.radians(heading), np.radians(pitch)
    fwd = np.array([np.sin(h) * np.cos(p), np.cos(h) * np.cos(p), np.sin(p)])
    right = np.array([np.cos(h), -np.sin(h), 0.0])
    up = np.cross(right, fwd)
    models, instances = {}, []
    for k, (radius, angle, size, spin) in enumerate(boxes):
        lateral, vertical = radius * np.cos(np.radians(angle)), radius * np.sin(np.radians(angle))
        distance = 35.0 + 40.0 * k
        centre = origin + fwd * distance + (right * lateral + up * vertical) * distance
        name = f"b{k}"
        models[name] = box_model(size, size, size, f"#{(40 * k + 30) % 256:02x}8040")
        instances.append({"model": name, "position": list(centre - np.array([0, 0, size / 2])),
                          "hpr": [spin, 0.0, 0.0]})
    doc = scene_doc(models, instances, earth_height=origin[2] - 500.0)
    return parse_scene(doc, source="<crosscheck>")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    far=st.sampled_from([0.0, 1.0e6]),
    heading=st.floats(0.0, 360.0),
    pitch=st.floats(-60.0, 60.0),
    roll=st.sampled_from([0.0, 33.0, 90.0, 180.0, -120.0]),
    boxes=st.lists(st.tuples(st.floats(0.0, 0.35), st.floats(0.0, 360.0), st.floats(4.0, 7.0),
                             st.floats(0.0, 90.0)), min_size=1, max_size=5),
)
@example(far=0.0, heading=0.0, pitch=0.0, roll=-120.0, boxes=[(0.35, 210.0, 4.0, 0.0)])
@example(far=1.0e6, heading=359.0, pitch=60.0, roll=180.0,
         boxes=[(0.35, 90.0, 7.0, 45.0), (0.0, 0.0, 4.0, 0.0), (0.35, 270.0, 5.0, 10.0)])
def test_renderers_agree_at_pixel_centres_on_separated_boxes(far, heading, pitch, roll, boxes):
    origin = np.array([far, -far / 2.0, 1000.0])
    database = box_scene(origin, heading, pitch, boxes)
    eye = Eyepoint(origin, heading, pitch, roll)
    a = seen_features(database, eye, "subarea")
    b = seen_features(database, eye, "scanline")
    assert (a >= 0).any()
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("distance", [60.0, 900.0, 12000.0])
def test_renderers_agree_on_markings_declared_on_their_base(distance):
    z = 0.02
    v = [[-30, -300, z], [30, -300, z], [30, 300, z], [-30, 300, z]]
    faces = [{"indices": [0, 1, 2, 3], "colour": "#303030"}]
    for k in range(8):  # threshold bars on the runway, and a patch on the first bar
        x = -26 + 7 * k
        base = len(v)
        v += [[x, -290, z], [x + 3, -290, z], [x + 3, -250, z], [x, -250, z]]
        faces.append({"indices": [base, base + 1, base + 2, base + 3], "colour": "#f0f0f0", "on": 0})
    base = len(v)
    v += [[-26, -280, z], [-23, -280, z], [-23, -270, z], [-26, -270, z]]
    faces.append({"indices": [base, base + 1, base + 2, base + 3], "colour": "#ff0000", "on": 1, "layer": 2})
    database = parse_scene(scene_doc({"rwy": {"vertices": v, "faces": faces}},
                                     [{"model": "rwy", "position": [0, 0, 0]}]))
    # Looking 8 degrees down at the bars, a field of view that keeps them a few pixels tall.
    eye = Eyepoint.of(0.0, -270.0 - distance, distance * np.tan(np.radians(8.0)), 0.0, -8.0, 0.0)
    channel = ChannelSpec.symmetric("c", 96, 64, float(np.degrees(2.0 * np.arctan(40.0 / distance))))
    a = seen_features(database, eye, "subarea", channel)
    b = seen_features(database, eye, "scanline", channel)
    np.testing.assert_array_equal(a, b)
    assert {0, 1, 2, 9} <= set(np.unique(a[a >= 0]).tolist())  # runway, two bars, the patch


def test_scanline_renderer_takes_only_the_pixel_centre():
    database = box_scene(np.zeros(3), 0.0, 0.0, [(0.0, 0.0, 5.0, 0.0)])  # one box 35 m ahead
    with pytest.raises(ValueError, match="samples: the scanline renderer samples pixel centres only"):
        render_frame(database, CH, Eyepoint.of(0, 0, 0, 0, 0, 0), RenderOptions(samples=4, renderer="scanline"))
    with pytest.raises(ValueError, match="renderer: unknown renderer 'zbuffer'"):
        render_frame(database, CH, Eyepoint.of(0, 0, 0, 0, 0, 0), RenderOptions(renderer="zbuffer"))
