"""`ig render` writes EXR (linear RGB + Z range) and PNG (sRGB) with the frame's metadata."""

import argparse
import json

import numpy as np
import pytest

from channel_worker import cli_render
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import parse_scene
from services.rig.frame import MAX_CHANNEL_PIXELS, ChannelSpec, Eyepoint, check_channel
from services.rig.image_io import read_image


def run(argv):
    parser = argparse.ArgumentParser()
    cli_render.add_arguments(parser)
    return cli_render.run(parser.parse_args(argv))


SCENE = {
    "format": "ig-scene/1", "sky": {"colour": "#8899aa"}, "earth": {"colour": "#335522"},
    "models": {"tri": {"vertices": [[-5, 0, 0], [5, 0, 0], [0, 0, 8]],
                       "faces": [{"indices": [0, 1, 2], "colour": "#ff0000"}]}},
    "instances": [{"model": "tri", "position": [0, 40, 0]}],
}


def test_render_exr_and_png(tmp_path):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(SCENE))
    exr = tmp_path / "f.exr"
    assert run([str(scene), "--eye", "0", "0", "2", "--hpr", "0", "0", "0", "--width", "64", "--height", "48",
                "--fov-h", "60", "--samples", "4", "--out", str(exr)]) == 0
    pixels, attrs = read_image(exr)
    assert attrs["channelnames"] == "R,G,B,Z"
    assert pixels.shape == (48, 64, 4)
    assert np.isinf(pixels[0, 0, 3])  # sky
    assert 35 < pixels[24, 32, 3] < 45  # the triangle, ~40 m ahead
    assert float(attrs["eye_z"]) == 2.0 and attrs["channel"] == "render"
    png = tmp_path / "f.png"
    assert run([str(scene), "--eye", "0", "0", "2", "--width", "64", "--height", "48", "--fov-h", "60",
                "--fov-v", "40", "--channel-hpr", "10", "0", "0", "--out", str(png)]) == 0
    pixels, attrs = read_image(png)
    assert pixels.shape == (48, 64, 3)
    assert attrs["channel_yaw_deg"] == "10.0"


def test_render_bad_input_exits_2_with_a_named_error(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**SCENE, "sky": {"colour": "sky blue"}}))
    assert run([str(bad), "--eye", "0", "0", "2", "--out", str(tmp_path / "x.png")]) == 2
    assert "sky.colour" in capsys.readouterr().err
    good = tmp_path / "s.json"
    good.write_text(json.dumps(SCENE))
    assert run([str(good), "--eye", "0", "nan", "2", "--out", str(tmp_path / "x.png")]) == 2
    assert "eyepoint.position[1]: nan" in capsys.readouterr().err


@pytest.mark.parametrize("option,value,message", [
    ("--width", "100000", "argument --width: 100000 is not in [1, 16384] pixels"),
    ("--width", "16385", "argument --width: 16385 is not in [1, 16384] pixels"),
    ("--height", "-5", "argument --height: -5 is not in [1, 16384] pixels"),
    ("--height", "0", "argument --height: 0 is not in [1, 16384] pixels"),
    ("--fov-h", "nan", "argument --fov-h: nan is not in (0, 178] degrees"),
    ("--fov-h", "-10", "argument --fov-h: -10 is not in (0, 178] degrees"),
    ("--fov-v", "1e9", "argument --fov-v: 1e9 is not in (0, 178] degrees"),
])
def test_render_size_errors_exit_2_in_one_line(option, value, message, capsys):
    parser = argparse.ArgumentParser(prog="ig render")
    cli_render.add_arguments(parser)
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args(["--eye", "0", "0", "2", option, value, "--out", "x.png"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"ig render: error: {message}" in err and "Traceback" not in err


def test_render_options_out_of_range_exit_2_in_one_line(tmp_path, capsys):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(SCENE))
    for flag, value, message in (("--subarea", "100000", "subarea: expected an integer in 1..64, got 100000"),
                                 ("--threads", "-1", "threads: expected an integer in 0..1024, got -1"),
                                 ("--samples", "1000", "samples: 1000 has no pattern")):
        assert run([str(scene), "--eye", "0", "0", "2", flag, value, "--out", str(tmp_path / "x.png")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"ig render: error: {message}") and err.count("\n") == 1


def test_render_refuses_a_face_beyond_the_limit_naming_its_path(tmp_path, capsys):
    n = 100_000
    ring = [[5 * np.cos(2 * np.pi * i / n), 40.0, 5 + 5 * np.sin(2 * np.pi * i / n)] for i in range(n)]
    doc = {**SCENE, "models": {"disc": {"vertices": ring,
                                        "faces": [{"indices": list(range(n)), "colour": "#ff0000"}]}},
           "instances": [{"model": "disc", "position": [0, 0, 0]}]}
    scene = tmp_path / "disc.json"
    scene.write_text(json.dumps(doc))
    assert run([str(scene), "--eye", "0", "0", "2", "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err == (f"ig render: error: {scene}: models.disc.faces[0].indices: 100000 vertices, more than the "
                   f"64 a face may have (docs/scene-format.md, Limits)\n")
    assert not (tmp_path / "x.png").exists()


def test_render_frame_refuses_a_channel_beyond_16384_pixels_a_side():
    check_channel(ChannelSpec.symmetric("big", MAX_CHANNEL_PIXELS, 1, 60.0))
    with pytest.raises(ValueError, match=r"channel 'big': width 16385 is more than the 16384 pixels"):
        check_channel(ChannelSpec.symmetric("big", 16385, 1, 60.0))
    with pytest.raises(ValueError, match=r"channel 'tall': height 100000 is more than the 16384 pixels"):
        render_frame(parse_scene(SCENE), ChannelSpec.symmetric("tall", 8, 100_000, 10.0), Eyepoint.of(0, 0, 2, 0, 0, 0))


def test_an_eye_below_the_terrain_is_said_in_one_warning_line(tmp_path, capsys):
    from channel_worker.pipeline.scene.load import demo_scene_path

    png = tmp_path / "below.png"
    assert run([str(demo_scene_path()), "--eye", "0", "0", "-100", "--width", "48", "--height", "36",
                "--samples", "1", "--out", str(png), "--times"]) == 0
    captured = capsys.readouterr()
    warnings = [line for line in captured.err.splitlines() if "warning" in line]
    assert warnings == ["ig render: warning: the eye (0.0, 0.0, -100.0) is below the terrain; the terrain is "
                        "drawn from just above its surface, the polygons from the eye"]
    assert "terrain_eye_clamped 1" in " ".join(captured.out.split())
    assert run([str(demo_scene_path()), "--eye", "0", "0", "100", "--width", "48", "--height", "36",
                "--samples", "1", "--out", str(png)]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize("name,message", [
    ("x.jpg", "argument --out: '{out}' is not a .exr or .png file (.exr: linear float RGB + Z range in metres; "
              ".png: sRGB 8-bit)"),
    ("x.tif", "argument --out: '{out}' is not a .exr or .png file"),
    ("x", "argument --out: '{out}' is not a .exr or .png file"),
    ("missing/dir/x.png", "argument --out: '{out}': directory '{dir}' does not exist"),
    ("file.txt/x.png", "argument --out: '{out}': '{dir}' is not a directory"),
])
def test_an_out_that_cannot_be_written_as_asked_exits_2_naming_it(tmp_path, name, message, capsys):
    """A JPEG is refused rather than written (help and behaviour agree: .exr or .png), and a
    directory that is not there is named rather than created."""
    (tmp_path / "file.txt").write_text("")
    out = tmp_path / name
    parser = argparse.ArgumentParser(prog="ig render")
    cli_render.add_arguments(parser)
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args(["--eye", "0", "0", "2", "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"ig render: error: {message.format(out=out, dir=out.parent)}" in err
    assert not (tmp_path / "missing").exists() and not out.exists()


def test_the_out_suffix_is_matched_whatever_its_case(tmp_path):
    parser = argparse.ArgumentParser(prog="ig render")
    cli_render.add_arguments(parser)
    args = parser.parse_args(["--eye", "0", "0", "2", "--out", str(tmp_path / "X.PNG")])
    assert args.out == tmp_path / "X.PNG"


@pytest.mark.parametrize("scene_args,expected", [
    ([], "airfield_terrain.json"),  # no scene: the demo's world
    (["--scene", "airfield"], "airfield.json"),  # the flat airfield, by name
    (["airfield"], "airfield.json"),  # the name as the positional SCENE
    (["--scene", "airfield-terrain"], "airfield_terrain.json"),
])
def test_the_scene_is_the_demos_world_unless_named(tmp_path, scene_args, expected):
    from channel_worker.data import SCENES
    from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path

    # The table's files are the loader's own bundled scenes.
    assert {f for f, _ in SCENES.values()} == {bundled_scene_path().name, demo_scene_path().name}
    png = tmp_path / "s.png"
    assert run([*scene_args, "--eye", "0", "-1500", "300", "--width", "16", "--height", "12", "--samples", "1",
                "--out", str(png)]) == 0
    _, attrs = read_image(png)
    assert attrs["scene"] == str(demo_scene_path().with_name(expected))


def test_a_scene_given_twice_or_unknown_exits_2_naming_it(tmp_path, capsys):
    out = str(tmp_path / "x.png")
    assert run(["airfield", "--scene", "airfield-terrain", "--eye", "0", "0", "2", "--out", out]) == 2
    assert ("ig render: error: the scene given twice: SCENE 'airfield' and --scene 'airfield-terrain'; give one"
            in capsys.readouterr().err)
    assert run(["--scene", "airfeild", "--eye", "0", "0", "2", "--out", out]) == 2
    assert ("ig render: error: --scene: 'airfeild' is neither a bundled scene (airfield-terrain, airfield) nor a "
            "file") in capsys.readouterr().err
    assert run([str(tmp_path / "none.json"), "--eye", "0", "0", "2", "--out", out]) == 2
    assert f"ig render: error: SCENE: '{tmp_path / 'none.json'}' is neither" in capsys.readouterr().err
