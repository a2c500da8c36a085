"""The rig file's [cigi] table and channel view ids (docs/rig-format.md)."""

from __future__ import annotations

import pytest

from services.rig.rigfile import RigError, default_rig_path, load_rig, rig_toml


def test_a_cigi_table_marks_the_rig_as_following_a_cigi_host_and_survives_a_round_trip(tmp_path):
    from services.rig.rigfile import CigiSpec

    base = load_rig(default_rig_path())
    assert not base.cigi.configured and base.cigi == CigiSpec()
    text = rig_toml(base) + '\n[cigi]\n'
    path = tmp_path / "cigi.toml"
    path.write_text(text)
    rig = load_rig(path)
    assert rig.cigi.configured and rig.cigi.origin == CigiSpec().origin
    again = tmp_path / "again.toml"
    again.write_text(rig_toml(rig))
    assert load_rig(again).cigi == rig.cigi
    # The default origin is the bundled airfield's.
    from channel_worker.pipeline.scene.terrain.bundled import AIRFIELD_ORIGIN
    assert CigiSpec().origin == AIRFIELD_ORIGIN


@pytest.mark.parametrize(("table", "message"), [
    ("listen = 'x'", "cigi.listen"), ("host_port = 0", "cigi.host_port"), ("origin = [91, 0, 0]", "cigi.origin"),
    ("query_channel = 'nose'", "cigi.query_channel"), ("mode = 'lockstep'", "cigi.mode"),
    ("stale_after_s = 0", "cigi.stale_after_s"), ("host = ''", "cigi.host"), ("colour = 1", "cigi.colour")])
def test_bad_cigi_keys_are_named(tmp_path, table, message):
    path = tmp_path / "bad.toml"
    path.write_text(rig_toml(load_rig(default_rig_path())) + f"\n[cigi]\n{table}\n")
    with pytest.raises(RigError, match=message):
        load_rig(path)


def test_view_ids_default_to_the_channel_order_and_must_be_unique(tmp_path):
    rig = load_rig(default_rig_path())
    assert [c.view_id for c in rig.channels] == [0, 1, 2]
    text = rig_toml(rig).replace("view_id = 2", "view_id = 0")
    path = tmp_path / "dup.toml"
    path.write_text(text)
    with pytest.raises(RigError, match=r"channels\[2\].view_id: 0 is used twice"):
        load_rig(path)
