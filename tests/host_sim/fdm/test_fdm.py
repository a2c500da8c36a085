"""--fdm parsing, the missing extra, and the point-mass model behind the FlightModel interface."""

from __future__ import annotations

import builtins
import subprocess
import sys
from pathlib import Path

import pytest

from host_sim.controlled import ControlledFlight
from host_sim.fdm import FdmSpec, open_model, parse_fdm
from host_sim.fdm.jsbsim_model import import_jsbsim
from host_sim.fdm.point_mass import PointMass
from host_sim.fdm.takeoff import ScriptedTakeoff

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize("text, spec", [
    ("point-mass", FdmSpec("point-mass")),
    ("jsbsim", FdmSpec("jsbsim", "c172x")),
    ("jsbsim:c310", FdmSpec("jsbsim", "c310")),
    (" jsbsim:f16 ", FdmSpec("jsbsim", "f16")),
])
def test_parse_fdm(text, spec):
    assert parse_fdm(text) == spec


@pytest.mark.parametrize("text, fragment", [
    ("yasim", "'yasim' is not one of"),
    ("point-mass:c172x", "takes no aircraft"),
    ("jsbsim:../etc", "is not a JSBSim aircraft name"),
])
def test_parse_fdm_refuses(text, fragment):
    with pytest.raises(ValueError, match="--fdm") as info:
        parse_fdm(text)
    assert fragment in str(info.value)


def test_missing_jsbsim_is_one_line_naming_the_flag_and_the_extra(monkeypatch):
    real_import = builtins.__import__

    def no_jsbsim(name, *args, **kwargs):
        if name == "jsbsim":
            raise ImportError("No module named 'jsbsim'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_jsbsim)
    with pytest.raises(ValueError) as info:
        open_model(parse_fdm("jsbsim"), origin=(36.6089, -84.1708, 349.2))
    message = str(info.value)
    assert "\n" not in message and "--fdm jsbsim" in message and "pip install 'ig-rig[jsbsim]'" in message
    with pytest.raises(ValueError):
        import_jsbsim()


def test_cli_host_reports_missing_jsbsim_in_one_line(tmp_path):
    # A fresh interpreter where `import jsbsim` fails, whether or not the extra is installed.
    shadow = tmp_path / "jsbsim.py"
    shadow.write_text("raise ImportError('jsbsim hidden by the test')\n")
    env_path = f"{tmp_path}:{ROOT}:{ROOT / 'proto'}"
    proc = subprocess.run([sys.executable, "-m", "services.cli", "host", "--fdm", "jsbsim", "--duration", "1"],
                          capture_output=True, text=True, cwd=ROOT, env={"PYTHONPATH": env_path}, timeout=120)
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert lines == ["ig host: error: --fdm jsbsim: the jsbsim package is not installed; "
                     "pip install 'ig-rig[jsbsim]'"]


def test_fdm_with_replay_is_refused(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "services.cli", "host", "--fdm", "point-mass", "--replay", "x.csv"],
                          capture_output=True, text=True, cwd=ROOT,
                          env={"PYTHONPATH": f"{ROOT}:{ROOT / 'proto'}"}, timeout=120)
    assert proc.returncode == 2
    assert "--fdm only applies with --controls or alone" in proc.stderr


def test_point_mass_behind_the_interface_flies_the_scripted_take_off():
    model = open_model(parse_fdm("point-mass"), origin=(0.0, 0.0, 0.0))
    assert isinstance(model, PointMass)
    flight = ControlledFlight([ScriptedTakeoff(model, runway_heading_deg=0.0, centreline_xy_m=(0.0, 0.0))],
                              model=model)
    start = flight.eyepoint_at(0.0)
    end = flight.eyepoint_at(40.0)
    assert not model.on_ground() and end.position[2] > start.position[2] + 10.0
    assert end.position[1] > start.position[1] + 500.0


def test_model_and_point_mass_parameters_are_exclusive():
    with pytest.raises(ValueError, match="model"):
        ControlledFlight([], model=PointMass(), step_hz=50.0)
