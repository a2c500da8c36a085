"""JSBSim rests and rolls on the rig's terrain: the host's ground (host_sim.fdm.ground) asks a
real QueryService over the bundled terrain database, as `ig host --fdm jsbsim` asks the rig's
query worker, and the aircraft's wheels sit on that terrain, not on the runway's plane."""

from __future__ import annotations

from concurrent import futures
from pathlib import Path

import grpc
import numpy as np
import pytest

from channel_worker.pipeline.scene.load import load_scene
from channel_worker.query.heights import height_of_terrain
from channel_worker.query.service import add_query_service
from host_sim.fdm.ground import QueryGround
from host_sim.inputs.base import Controls
from services.rig.rigfile import CigiSpec

pytest.importorskip("jsbsim")

SCENE = Path(__file__).resolve().parents[2] / "channel_worker" / "data" / "airfield_terrain.json"
#: A field 1.5 km south-west of the runway, off the airfield's flattened pad (about 18 m below it).
FIELD_XY_M = (-1500.0, -1500.0)


@pytest.fixture(scope="module")
def terrain():
    database = load_scene(SCENE)
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    add_query_service(server, database)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    yield database, f"127.0.0.1:{port}"
    server.stop(0)


def hot(database, x: float, y: float) -> float:
    h = height_of_terrain(database, np.array([x]), np.array([y]), np.array([np.inf]))
    assert h.valid[0]
    return float(h.height_m[0])


def test_jsbsim_rests_and_rolls_on_the_terrain_the_worker_answers(terrain):
    from host_sim.fdm.jsbsim_model import JSBSimModel

    database, address = terrain
    ground_z = hot(database, *FIELD_XY_M)
    assert abs(ground_z) > 5.0  # off the pad: a runway-plane ground would be metres out
    m = JSBSimModel("c172x", origin=CigiSpec().origin, start_xy_m=FIELD_XY_M,
                    ground=QueryGround(address, start_xy_m=FIELD_XY_M))
    try:
        cg = m.world_cg()
        # At rest: the centre of gravity its height above the lowest wheel (c172x: 1.31 m) over
        # the terrain under it.
        assert cg[2] - hot(database, cg[0], cg[1]) == pytest.approx(1.31, abs=0.05)
        above = []
        for _ in range(12 * 120):  # 12 s at full throttle over the field: a roll across its relief
            m.step(Controls(throttle=1.0))
            cg = m.world_cg()
            above.append(cg[2] - hot(database, cg[0], cg[1]))
        assert m.on_ground() and np.hypot(cg[0] - FIELD_XY_M[0], cg[1] - FIELD_XY_M[1]) > 50.0
        # The terrain here is a slope of a few per cent: its dampers give a few centimetres (the
        # unit test's slope), never into the ground, never off it.
        assert min(above) > 1.0 and max(above) < 1.5
        assert m.ground.status()["failures"] == 0
    finally:
        m.close()
