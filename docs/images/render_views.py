"""Render the README's and docs' views of the bundled world, so that anyone can regenerate them
and see a regression: `make images` (or `python docs/images/render_views.py [OUT_DIR]`).

Each view is one `ig render` of the bundled terrain scene (channel_worker/data/
airfield_terrain.json) at the default 1024 x 768, written as PNG into docs/images/ (or OUT_DIR):

    approach.png     2.5 km final for runway 36, 250 m up, the airfield ahead
    forest-pass.png  a low pass, 60 m over the ground, along the forest south of the airfield
    cloud-deck.png   at 1500 m, between the cloud deck's base (1100 m) and its tops (1800 m)
    near-forest.png  75 m up, 300 m from a stand: near trees in front, voxel stands beyond
    tree-switch.png  the stand from 650, 575, 500 and 425 m, across the near trees' cross-fade
                     (611 to 428 m on this channel): crops of four renders, top to bottom
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "channel_worker" / "data" / "airfield_terrain.json"

#: name -> (eye x y z, heading pitch roll)
VIEWS = {
    "approach": ((0.0, -3500.0, 250.0), (0.0, -5.0, 0.0)),
    "forest-pass": ((600.0, -1700.0, 60.0), (200.0, -4.0, 0.0)),
    "cloud-deck": ((0.0, -9000.0, 1500.0), (20.0, 0.0, 0.0)),
    "near-forest": ((480.0, -1640.0, 75.0), (117.0, -6.0, 0.0)),
}
#: The switch strip: a forest voxel at (765, -1785) approached along heading 117, 40 m up.
SWITCH_TARGET = (765.0, -1785.0)
SWITCH_DISTANCES = (650.0, 575.0, 500.0, 425.0)
SWITCH_CROP = (362, 662, 290, 370)  # x0, x1, y0, y1 of each 1024 x 768 render, shown twice the size


def render(name: str, out_dir: Path) -> Path:
    (x, y, z), (h, p, r) = VIEWS[name]
    out = out_dir / f"{name}.png"
    subprocess.run([sys.executable, "-m", "services.cli", "render", str(SCENE), "--eye", str(x), str(y), str(z),
                    "--hpr", str(h), str(p), str(r), "--out", str(out)], cwd=ROOT, check=True)
    return out


def switch_strip(out_dir: Path) -> Path:
    """tree-switch.png: the same stand at four ranges across the cross-fade."""
    import math
    import tempfile

    import OpenImageIO as oiio

    heading = math.radians(117.0)
    x0, x1, y0, y1 = SWITCH_CROP
    w, h = 2 * (x1 - x0), 2 * (y1 - y0)
    strip = oiio.ImageBuf(oiio.ImageSpec(w, h * len(SWITCH_DISTANCES), 3, oiio.UINT8))
    with tempfile.TemporaryDirectory() as tmp:
        for k, d in enumerate(SWITCH_DISTANCES):
            eye = (SWITCH_TARGET[0] - d * math.sin(heading), SWITCH_TARGET[1] - d * math.cos(heading), 40.0)
            VIEWS[f"switch-{k}"] = (eye, (117.0, -3.0, 0.0))
            frame = oiio.ImageBuf(str(render(f"switch-{k}", Path(tmp))))
            crop = oiio.ImageBufAlgo.cut(frame, oiio.ROI(x0, x1, y0, y1))
            big = oiio.ImageBufAlgo.resize(crop, filtername="box", roi=oiio.ROI(0, w, 0, h))
            oiio.ImageBufAlgo.paste(strip, 0, h * k, 0, 0, big)
            del VIEWS[f"switch-{k}"]
    out = out_dir / "tree-switch.png"
    strip.write(str(out))
    return out


def main(argv: list[str]) -> int:
    out_dir = Path(argv[0]) if argv else ROOT / "docs" / "images"
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in VIEWS:
        print(render(name, out_dir))
    print(switch_strip(out_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
