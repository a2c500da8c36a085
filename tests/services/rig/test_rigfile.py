"""Rig files."""

import tomllib

import pytest

from services.rig.options import RenderOptions
from services.rig.rigfile import RigError, WireSpec, channel_spec, default_rig_path, load_rig, parse_rig, rig_toml

ROOT = default_rig_path().parents[3]


def test_default_rig_is_three_60x45_channels():
    rig = load_rig(default_rig_path())
    assert rig.channel_names == ("left", "centre", "right")
    assert [c.spec.yaw_deg for c in rig.channels] == [-60.0, 0.0, 60.0]
    for c in rig.channels:
        s = c.spec
        assert (s.right_deg - s.left_deg, s.top_deg - s.bottom_deg) == (60.0, 45.0)
        assert (s.width, s.height) == (1024, 768)
        assert c.address.startswith("127.0.0.1:")
    assert rig.host_address.startswith("127.0.0.1:")


def test_deploy_copy_matches_package_copy():
    assert (ROOT / "deploy" / "rigs" / "default.toml").read_text() == default_rig_path().read_text()
    assert load_rig(ROOT / "deploy" / "rigs" / "three-machines.toml").channel_names == ("left", "centre", "right")


def doc():
    return {"host": {"address": "127.0.0.1:1"}, "compositor": {"address": "127.0.0.1:2"},
            "channels": [{"name": "c", "address": "127.0.0.1:3", "left_deg": -30.0, "right_deg": 30.0,
                          "bottom_deg": -20.0, "top_deg": 20.0, "width": 64, "height": 48}]}


@pytest.mark.parametrize("mutate,pattern", [
    (lambda d: d["channels"][0].update(width=0), r"channels\[0\].width: 0 is not a whole number"),
    (lambda d: d["channels"][0].update(left_deg=40.0), r"channels\[0\].left_deg: 40.0 is not < right_deg 30.0"),
    (lambda d: d["channels"][0].update(top_deg=95.0), r"channels\[0\].top_deg: 95.0 is outside"),
    (lambda d: d["channels"][0].update(fov=3), r"channels\[0\].fov: unknown key"),
    (lambda d: d["host"].update(address="nowhere"), r"host.address: 'nowhere' is not host:port"),
    (lambda d: d["channels"].append(dict(d["channels"][0])), r"channels\[1\].name: 'c' is used twice"),
    (lambda d: d["channels"][0].update(yaw_deg=float("nan")), r"channels\[0\].yaw_deg: nan is not a finite"),
    (lambda d: d["channels"][0].update(yaw_deg="left"), r"channels\[0\].yaw_deg: 'left' is not a finite"),
    (lambda d: d["channels"][0].pop("width"), r"channels\[0\]: missing key 'width'"),
    (lambda d: d["channels"].append(3), r"channels\[1\]: 3 is not a table"),
    (lambda d: d["channels"].append(dict(d["channels"][0], name="d", address="127.0.0.1:4", height=40)),
     r"channels\[1\].height: 40 differs from channels\[0\].height 48"),
    (lambda d: d["compositor"].update(address="127.0.0.1:1"),
     r"compositor.address: '127.0.0.1:1' is already used by host.address"),
    (lambda d: d["channels"][0].update(address="127.0.0.1:0"),
     r"channels\[0\].address: '127.0.0.1:0' is not host:port"),
    (lambda d: d.update(extra=1), r"extra: unknown key"),
    (lambda d: d.pop("channels"), r"channels: expected at least one"),
    (lambda d: d.update(render={"sample": 4}), r"r.toml: render.sample: unknown render option 'sample'"),
    (lambda d: d.update(render={"terrain_bias": 7}),
     r"r.toml: render.terrain_bias: expected an integer in -4..4, got 7"),
    (lambda d: d.update(render=4), r"r.toml: render: expected a table of render options"),
    (lambda d: d.update(sync={"pace": "fast"}), r"r.toml: sync.pace: 'fast' is not one of ticks, acks"),
    (lambda d: d.update(sync={"pase": "acks"}), r"sync.pase: unknown key \(known: .*max_pending_mib, pace\)"),
    (lambda d: d["compositor"].update(wire="rgb8"), r"r.toml: compositor.wire: 'rgb8' is not one of 'srgb8', 'half'"),
    (lambda d: d["compositor"].update(shared_memory="yes"), r"r.toml: compositor.shared_memory: 'yes' is not true"),
    (lambda d: d["compositor"].update(shm=True), r"r.toml: compositor.shm: unknown key \(known: address, wire"),
])
def test_bad_rig_names_key_and_value(mutate, pattern):
    d = doc()
    mutate(d)
    with pytest.raises(RigError, match=pattern):
        parse_rig(d, source="r.toml")


def test_channel_spec_of_a_rig_channel():
    d = doc()
    d["channels"][0].update(yaw_deg=60, pitch_deg=-5.0)
    spec = parse_rig(d).channels[0].spec
    assert spec == channel_spec("c", width=64, height=48, left_deg=-30.0, right_deg=30.0, bottom_deg=-20.0,
                                top_deg=20.0, yaw_deg=60.0, pitch_deg=-5.0)
    assert isinstance(spec.yaw_deg, float) and spec.roll_deg == 0.0


def test_with_size_changes_every_channel():
    rig = load_rig(default_rig_path()).with_size(160, 120)
    assert {(c.spec.width, c.spec.height) for c in rig.channels} == {(160, 120)}


def test_unknown_channel_name():
    rig = parse_rig(doc())
    with pytest.raises(RigError, match=r"channel_name: 'bogus' is not a channel of the rig \(c\)"):
        rig.channel("bogus")


def test_invalid_toml(tmp_path):
    p = tmp_path / "r.toml"
    p.write_text("[host\n")
    with pytest.raises(RigError, match="invalid TOML"):
        load_rig(p)


def test_the_render_table_sets_every_workers_options_and_round_trips():
    d = doc()
    assert parse_rig(d).render == RenderOptions()
    d["render"] = {"samples": 16, "filter": "tent", "haze": False, "terrain_bias": -1}
    rig = parse_rig(d, source="r.toml")
    assert rig.render == RenderOptions(samples="d3d16", filter="tent", haze=False, terrain_bias=-1)
    again = parse_rig(tomllib.loads(rig_toml(rig)))
    assert again == parse_rig(tomllib.loads(rig_toml(rig)))
    assert again.render == rig.render and again.channels == rig.channels
    assert "[render]" not in rig_toml(parse_rig(doc()))  # defaults are not written out


def test_the_sync_pace_defaults_to_ticks_and_round_trips():
    assert parse_rig(doc()).sync.pace == "ticks"
    d = doc()
    d["sync"] = {"pace": "acks", "frame_timeout_s": 0.1}
    rig = parse_rig(d)
    assert (rig.sync.pace, rig.sync.frame_timeout_s) == ("acks", 0.1)
    assert parse_rig(tomllib.loads(rig_toml(rig))).sync == rig.sync


def test_the_wire_keys_default_to_srgb8_in_shared_memory_and_survive_rig_toml():
    assert parse_rig(doc()).wire == WireSpec("srgb8", True)
    d = doc()
    d["compositor"].update(wire="half", shared_memory=False)
    rig = parse_rig(d)
    assert rig.wire == WireSpec("half", False)
    assert parse_rig(tomllib.loads(rig_toml(rig))).wire == rig.wire
    assert "wire" not in rig_toml(parse_rig(doc()))  # defaults are left out


def test_metrics_ports_default_to_none_and_survive_rig_toml():
    rig = parse_rig(doc())
    assert (rig.host_metrics_port, rig.compositor_metrics_port, rig.channels[0].metrics_port) == (0, 0, 0)
    assert "metrics_port" not in rig_toml(rig)
    d = doc()
    d["host"]["metrics_port"] = 9150
    d["compositor"]["metrics_port"] = 9151
    d["channels"][0]["metrics_port"] = 9161
    rig = parse_rig(d)
    assert (rig.host_metrics_port, rig.compositor_metrics_port, rig.channels[0].metrics_port) == (9150, 9151, 9161)
    assert parse_rig(tomllib.loads(rig_toml(rig))) == rig


def test_the_view_port_defaults_to_none_and_survives_rig_toml():
    assert parse_rig(doc()).compositor_view_port == 0 and "view_port" not in rig_toml(parse_rig(doc()))
    d = doc()
    d["compositor"]["view_port"] = 8080
    rig = parse_rig(d)
    assert rig.compositor_view_port == 8080 and parse_rig(tomllib.loads(rig_toml(rig))) == rig


@pytest.mark.parametrize("mutate,pattern", [
    (lambda d: d["compositor"].update(view_port=-1), r"compositor.view_port: -1 is not a port in \[1, 65535\]"),
    (lambda d: d["compositor"].update(metrics_port=9000, view_port=9000),
     r"compositor.view_port: '127.0.0.1:9000' is already used by compositor.metrics_port"),
    (lambda d: d["host"].update(metrics_port=70000),
     r"host.metrics_port: 70000 is not a port in \[1, 65535\], or 0 for none"),
    (lambda d: d["channels"][0].update(metrics_port="9161"), r"channels\[0\].metrics_port: '9161' is not a port"),
    (lambda d: d["compositor"].update(metrics_port=True), r"compositor.metrics_port: True is not a port"),
    # A metrics port is taken on the machine of its service: not another service's port there.
    (lambda d: d["host"].update(metrics_port=2),
     r"host.metrics_port: '127.0.0.1:2' is already used by compositor.address"),
    (lambda d: (d["host"].update(metrics_port=9000), d["channels"][0].update(metrics_port=9000)),
     r"channels\[0\].metrics_port: '127.0.0.1:9000' is already used by host.metrics_port"),
])
def test_bad_metrics_ports_name_key_and_value(mutate, pattern):
    d = doc()
    mutate(d)
    with pytest.raises(RigError, match=pattern):
        parse_rig(d)


def test_metrics_ports_of_services_on_other_machines_may_be_equal():
    d = doc()
    d["channels"].append(dict(d["channels"][0], name="d", address="10.0.0.12:3"))
    d["channels"][0].update(address="10.0.0.11:3", metrics_port=9161)
    d["channels"][1]["metrics_port"] = 9161
    assert [c.metrics_port for c in parse_rig(d).channels] == [9161, 9161]
