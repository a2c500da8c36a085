"""The rig file's [scene] table and cigi.initial_pose (issue 30)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from services.rig.rigfile import (
    DEFAULT_INITIAL_HEIGHT_M,
    RigError,
    default_rig_path,
    load_rig,
    parse_rig,
    rig_toml,
    scene_path,
)

BASE = default_rig_path().read_text()


def rig_with(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "rigs" / "rig.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(BASE + "\n" + extra)
    return path


def test_the_scene_path_is_relative_to_the_rig_file_and_survives_rig_toml(tmp_path):
    rig = load_rig(rig_with(tmp_path, '[scene]\npath = "../scenes/site.json"\n'))
    assert rig.scene == str(tmp_path / "rigs" / ".." / "scenes" / "site.json")
    assert load_rig(rig_with(tmp_path, "")).scene == ""  # no table: each command's own default
    copy = tmp_path / "copy.toml"
    copy.write_text(rig_toml(rig))
    assert load_rig(copy).scene == rig.scene  # absolute: the copy elsewhere finds the same file
    assert load_rig(rig_with(tmp_path, '[scene]\npath = "/srv/site.json"\n')).scene == "/srv/site.json"


@pytest.mark.parametrize("table, words", [('[scene]\npath = ""\n', "scene.path: '' is not a file path"),
                                          ("[scene]\npath = 3\n", "scene.path: 3 is not a file path"),
                                          ('[scene]\nfile = "a.json"\n', "scene.file: unknown key")])
def test_bad_scene_tables_are_named(tmp_path, table, words):
    with pytest.raises(RigError, match=words):
        load_rig(rig_with(tmp_path, table))


def test_the_flag_wins_over_the_rig_file_which_wins_over_the_default(tmp_path):
    rig = load_rig(rig_with(tmp_path, '[scene]\npath = "site.json"\n'))
    assert scene_path("flag.json", rig, "default.json") == "flag.json"
    assert scene_path(None, rig, "default.json") == str(tmp_path / "rigs" / "site.json")
    assert scene_path(None, load_rig(rig_with(tmp_path, "")), "default.json") == "default.json"


def test_worker_and_compile_load_the_rig_files_scene(tmp_path, capsys):
    # A scene that is not JSON: each command fails naming the rig's scene, before any kernel.
    from channel_worker import cli_compile, cli_worker

    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "broken.json").write_text("{not json")
    rig = rig_with(tmp_path, '[scene]\npath = "broken.json"\n')
    for module, argv in ((cli_worker, ["--rig", str(rig), "--channel-index", "0"]),
                         (cli_compile, ["--rig", str(rig)])):
        parser = argparse.ArgumentParser()
        module.add_arguments(parser)
        assert module.run(parser.parse_args(argv)) == 2
        assert "broken.json" in capsys.readouterr().err


def test_initial_pose_is_checked_and_defaults_above_the_origin():
    doc = {"host": {"address": "127.0.0.1:50051"}, "compositor": {"address": "127.0.0.1:50052"},
           "channels": [{"name": "c", "address": "127.0.0.1:50053", "left_deg": -30, "right_deg": 30,
                         "bottom_deg": -20, "top_deg": 20, "width": 64, "height": 48}]}
    rig = parse_rig({**doc, "cigi": {"origin": [46.5, 7.0, 600.0]}})
    assert rig.cigi.initial_pose is None
    assert rig.cigi.start_pose == (46.5, 7.0, 600.0 + DEFAULT_INITIAL_HEIGHT_M, 0.0, 0.0, 0.0)
    rig = parse_rig({**doc, "cigi": {"initial_pose": [46.6, 7.1, 1500, 270, -3, 10]}})
    assert rig.cigi.start_pose == (46.6, 7.1, 1500.0, 270.0, -3.0, 10.0)
    for bad in ([46.6, 7.1, 1500], [95, 7.1, 1500, 0, 0, 0], [46.6, 7.1, 1500, 0, 91, 0], "north"):
        with pytest.raises(RigError, match=r"cigi\.initial_pose"):
            parse_rig({**doc, "cigi": {"initial_pose": bad}})
