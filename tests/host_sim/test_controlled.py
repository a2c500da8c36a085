"""The flight model flown by control sources, as the publisher's eyepoint source."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host_sim import flight_model
from host_sim.controlled import STEP_HZ, ControlledFlight
from host_sim.inputs import canaerospace as ca
from host_sim.inputs import open_source
from host_sim.inputs.base import ControlSource

can = pytest.importorskip("can", reason="python-can is in the devices extra")

#: A take-off and a turn, as a cockpit would send it (log time s, signal, value).
SCRIPT = ([(0.0, "throttle_1_lever_position", 1.0), (0.0, "park_brake_lever_position", 0)]
          + [(t, "pitch_control_position", 0.0) for t in np.arange(0.0, 12.0, 0.05)]
          + [(12.0 + t, "pitch_control_position", 0.3) for t in np.arange(0.0, 3.0, 0.05)]
          + [(15.0, "pitch_control_position", 0.0), (16.0, "roll_control_position", -0.5),
             (18.0, "roll_control_position", 0.0)])


def write_log(path):
    with can.Logger(str(path)) as logger:
        for k, (t, name, value) in enumerate(sorted(SCRIPT, key=lambda r: r[0])):
            can_id, data = ca.encode(name, value, message_code=k)
            logger.on_message_received(can.Message(timestamp=t, arbitration_id=can_id, data=data,
                                                   is_extended_id=False))
    return path


def eyepoints(log, rate_hz, seconds):
    flight = ControlledFlight([open_source(f"canlog://{log}?stale_after=5")])
    out = {}
    for k in range(int(round(seconds * rate_hz)) + 1):
        e = flight.eyepoint_at(k / rate_hz)
        out[round(k / rate_hz, 9)] = (*e.position, e.heading_deg, e.pitch_deg, e.roll_deg)
    flight.close()
    return out, flight


def test_a_log_flies_the_same_at_every_frame_rate(tmp_path):
    log = write_log(tmp_path / "flight.asc")
    a, flight = eyepoints(log, 20.0, 20.0)
    b, _ = eyepoints(log, 50.0, 20.0)
    c, _ = eyepoints(log, 20.0, 20.0)
    assert a == c  # deterministic
    common = sorted(set(a) & set(b))
    assert len(common) == 201  # every 0.1 s
    for t in common:  # the model stepped at the same 100 Hz steps, whatever the frame rate
        assert np.allclose(a[t], b[t], rtol=0, atol=1e-9), t
    _, _, z, h, _, _ = a[20.0]
    assert z > flight.aircraft.eye_height_m + 10.0  # it took off
    assert 180.0 < h < 359.0  # and turned left
    assert flight.status()[1].steps == int(20.0 * STEP_HZ) + 1


def test_eyepoints_between_steps_are_interpolated():
    flight = ControlledFlight([], initial=flight_model.State(0.0, 0.0, 100.0, speed_mps=50.0, on_ground=False))
    e0 = flight.eyepoint_at(0.0)
    e1 = flight.eyepoint_at(0.005)  # half a step
    e2 = flight.eyepoint_at(0.01)
    assert e0.position[1] < e1.position[1] < e2.position[1]
    assert e1.position[1] - e0.position[1] == pytest.approx(e2.position[1] - e1.position[1], rel=1e-6)
    with pytest.raises(ValueError, match="t_s"):
        flight.eyepoint_at(math.nan)


class Scripted(ControlSource):
    """A source whose values and staleness the test sets."""

    def __init__(self, name, values, stale=False):
        super().__init__(name)
        self.values, self.is_stale = values, stale

    def _read(self, now_s):
        for k, v in self.values.items():
            self._accept(k, v)

    def status(self):
        s = super().status()
        s.stale = self.is_stale
        return s


def test_sources_merge_by_priority_and_a_stale_one_yields():
    first = Scripted("first", {"pitch_control_position": 0.5, "roll_control_position": 0.25})
    second = Scripted("second", {"pitch_control_position": -0.5, "throttle_1_lever_position": 0.75})
    flight = ControlledFlight([first, second])
    flight.eyepoint_at(0.0)
    c = flight.controls()
    assert (c.pitch, c.roll, c.throttle) == (0.5, 0.25, 0.75)
    first.is_stale = True
    c = flight.controls()
    assert (c.pitch, c.roll, c.throttle) == (-0.5, 0.25, 0.75)  # roll: only the stale one has it, held
    sources, model = flight.status()
    assert [s.name for s in sources] == ["first", "second"] and model.on_ground
