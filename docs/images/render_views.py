"""Render the README's and docs' views of the bundled world, so that anyone can regenerate them
and see a regression: `make images` (or `python docs/images/render_views.py [OUT_DIR]`).

Each view is one `ig render` of the bundled terrain scene (channel_worker/data/
airfield_terrain.json) at the default 1024 x 768, written as PNG into docs/images/ (or OUT_DIR):

    approach.png     2.5 km final for runway 36, 250 m up, the airfield ahead
    forest-pass.png  a low pass, 60 m over the ground, along the forest south of the airfield
    cloud-deck.png   at 1500 m, between the cloud deck's base (1100 m) and its tops (1800 m)
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
}


def render(name: str, out_dir: Path) -> Path:
    (x, y, z), (h, p, r) = VIEWS[name]
    out = out_dir / f"{name}.png"
    subprocess.run([sys.executable, "-m", "services.cli", "render", str(SCENE), "--eye", str(x), str(y), str(z),
                    "--hpr", str(h), str(p), str(r), "--out", str(out)], cwd=ROOT, check=True)
    return out


def main(argv: list[str]) -> int:
    out_dir = Path(argv[0]) if argv else ROOT / "docs" / "images"
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in VIEWS:
        print(render(name, out_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
