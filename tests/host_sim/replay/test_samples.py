"""The bundled sample flights: what the generator writes, each read without a problem, over the
bundled world and never into it."""

from __future__ import annotations

import numpy as np
import pytest

from host_sim.replay import FORMATS, load_track
from host_sim.replay import build_samples as build
from host_sim.replay.samples import FLIGHTS_DIR, SAMPLES, sample_path
from services.rig.rigfile import CigiSpec

#: The bundled airfield's geodetic origin: the rig's database origin, which `ig demo --replay`
#: gives the replay.
ORIGIN = CigiSpec().origin


def test_the_checked_in_logs_are_what_the_generator_writes():
    assert set(build.BUILDERS) == set(SAMPLES)
    for name in SAMPLES:
        assert sample_path(name).read_bytes() == build.build(name).encode("ascii"), (
            f"{sample_path(name).name} is stale: run python -m host_sim.replay.build_samples")
    assert build.main(["--check"]) == 0


def test_the_check_finds_a_stale_log(tmp_path, capsys):
    assert build.main(["--out", str(tmp_path)]) == 0
    (tmp_path / SAMPLES["circuit"][0]).write_text("edited\n")
    assert build.main(["--check", "--out", str(tmp_path)]) == 1
    assert "circuit.igc" in capsys.readouterr().err


@pytest.mark.parametrize("name", list(SAMPLES))
def test_each_sample_is_a_short_flight_read_without_a_problem(name):
    path = sample_path(name)
    assert path.parent == FLIGHTS_DIR and path.stat().st_size < 32_000
    track, fmt = load_track(path, origin=ORIGIN)
    assert path.suffix in FORMATS[fmt][1]
    assert {cause: n for cause, n in track.problems.items() if n} == {}
    assert not track.notes
    assert 60.0 <= track.duration_s <= 180.0
    assert track.records_read == len(track.t_s) >= 100


def test_the_formats_show_what_their_recorders_write():
    csv_track, _ = load_track(sample_path("departure"), origin=ORIGIN)
    # The CSV's cells are missing column by column: every other row has no position, a few
    # no height, one second no attitude; each column is filled from its own neighbours.
    assert 0.3 < csv_track.coverage["position"] < 0.6
    assert csv_track.interpolated["position"] > 90 and csv_track.interpolated["heading_deg"] >= 1
    assert not csv_track.attitude_estimated
    igc_track, _ = load_track(sample_path("circuit"), origin=ORIGIN)
    assert igc_track.attitude_estimated  # IGC has no attitude
    assert "ground" in set(igc_track.attitude_source)  # it ends with the landing roll
    fdr_track, _ = load_track(sample_path("low-pass"), origin=ORIGIN)
    assert not fdr_track.attitude_estimated and fdr_track.coverage["heading_deg"] == 1.0


def _runway(position: np.ndarray) -> np.ndarray:
    """Whether world positions are over runway 36 (45 m wide, from y = -1000 to +1000) or the
    last 300 m of its approach, where a landing is low."""
    return (np.abs(position[:, 0]) < 30.0) & (position[:, 1] > -1300.0) & (position[:, 1] < 1000.0)


@pytest.mark.parametrize("name,ends", [("departure", ((0.0, -960.0), (1310.0, 951.0))),
                                       ("circuit", ((-780.0, 200.0), (0.0, -570.0))),
                                       ("low-pass", ((0.0, -4600.0), (550.0, 2250.0)))])
def test_each_sample_flies_over_the_bundled_airfield_and_never_into_the_world(name, ends):
    from channel_worker.pipeline.scene.load import demo_scene_path, load_scene
    from channel_worker.query.heights import height_of_terrain

    track, _ = load_track(sample_path(name), origin=ORIGIN)
    times = np.arange(0.0, track.duration_s, 0.2)
    position = np.array([track.sample(t).position for t in times])
    for end, expected in zip((position[0], position[-1]), ends, strict=True):
        np.testing.assert_allclose(end[:2], expected, atol=60.0)
    # The highest surface under each eyepoint: terrain, trees, buildings, the hedge, the pylons.
    ground = height_of_terrain(load_scene(demo_scene_path()), position[:, 0], position[:, 1],
                               np.full(len(times), np.inf))
    assert ground.valid.all()
    clearance = position[:, 2] - ground.height_m
    assert clearance.min() > 0.5  # on the runway the eye is above it, never in it
    away = ~_runway(position)
    assert clearance[away].min() > 20.0  # off the runway it flies, well clear of what is there
