"""`ig render` writes EXR (linear RGB + Z range) and PNG (sRGB) with the frame's metadata."""

import argparse
import json

import numpy as np

from channel_worker import cli_render
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
