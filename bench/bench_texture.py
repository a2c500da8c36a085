"""Textures (the texture patent *An image generator*, docs/textures.md): speed against error of
each texture filter at 1, 4 and 16 samples, and what textures and smooth shading cost the
bundled airfield (bench/README.md "Textures").

    python bench/bench_texture.py            # the full run (a few minutes, most of it compiling)
    python bench/bench_texture.py --quick    # smoke run; not a measurement
    python bench/bench_texture.py --replot   # redraw texture.png from texture.json

Error: a textured ground plane seen at a grazing angle (eye 3 m up, pitch -4 degrees, a 2 x 2
km face), against a 64-sample reference (the pixel centres of a raster eight times as fine, 8 x
8 box-filtered, faded at their own footprint of 1/8 pixel: the texture resolved wherever a pixel
could). A textured face is shaded once per pixel where one face covers it and per sample where
faces meet (like a GPU's multisampling), so more samples sharpen its edges, not its texture.
Two textures: the checkerboard (hard edges, all the aliasing a texture can show) and the
bundled grass photograph. RMSE and the 99th percentile of the absolute error over the ground
rows, linear RGB. Speed: render_frame on one core (numba on one thread), median of --repeats.

The airfield: the demo's channel (1024 x 768, rgss4) at three eyepoints along the bundled
flight, the demo's scene as shipped (the bundled airfield on the terrain, with haze, fog and
clouds; textured runway, taxiways, grass, brick and metal walls, barrel-roofed hangars and hills
shaded smoothly) against the same scene with every texture code and smooth flag stripped: the
cost of the looks, and the whole frame against the real-time one-core budget (33 ms).
Writes bench/results/texture.json and texture.png.
"""

from __future__ import annotations

import copy
import datetime as dt
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from common import bench_parser, finish, pin_to_one_cpu, replot  # bench/ is on the path as a script

FILTERS = ("fade", "mipmap", "both")
PATTERNS = ("centre", "rgss4", "d3d16")
SIZE = (320, 240)
EYE = (0.0, -200.0, 3.0, 0.0, -4.0, 0.0)
#: Rows of the SIZE raster below the horizon (pitch -4 on a 60 x 46 degree view), for errors.
GROUND_ROWS = slice(102, 240)
TEXTURES = {"checker": {"procedural": "checker", "size": 64}, "grass": {"bundled": "grass"}}
#: The bundled flight's eyepoints for the airfield timing (x, y, z, h, p, r).
AIRFIELD_EYES = ((0.0, -950.0, 3.0, 0.0, -2.0, 0.0), (0.0, -300.0, 40.0, 0.0, 8.0, 0.0),
                 (60.0, -700.0, 12.0, 20.0, -4.0, 0.0))


def ground_scene(texture: str) -> Any:
    from channel_worker.pipeline.scene.load import parse_scene
    h = 2000.0
    return parse_scene({
        "format": "ig-scene/1", "sky": {"colour": "#8090a0"}, "earth": {"colour": "#405030"},
        "lighting": {"ambient": 1.0},
        "textures": {"t": TEXTURES[texture]},
        "texture_codes": {"c": {"textures": ["t"], "scale_m": [4.0, 4.0], "intensity": 0.9,
                                "modulation": "colour"}},
        "models": {"g": {"vertices": [[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]],
                         "faces": [{"indices": [0, 1, 2, 3], "colour": "#a09080", "texture": "c"}]}},
        "instances": [{"model": "g", "position": [0, 0, 0]}]}, source=f"bench {texture}")


def timed(fn, repeats: int) -> float:
    fn()  # compile, warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def filter_errors(repeats: int, quick: bool) -> list[dict[str, Any]]:
    from channel_worker.pipeline.render import render_frame
    from services.rig.frame import ChannelSpec, Eyepoint
    from services.rig.options import RenderOptions
    w, h = SIZE
    eye = Eyepoint.of(*EYE)
    channel = ChannelSpec.symmetric("c", w, h, 60.0)
    fine = ChannelSpec.symmetric("c", 8 * w, 8 * h, 60.0)
    rows = []
    for texture in (("checker",) if quick else tuple(TEXTURES)):
        db = ground_scene(texture)
        ref = render_frame(db, fine, eye, RenderOptions(samples="centre", with_range=False)).rgb
        ref = ref.astype(np.float64).reshape(h, 8, w, 8, 3).mean(axis=(1, 3))
        out = np.empty((h, w, 3), np.float32)
        for name in FILTERS:
            for pattern in PATTERNS:
                opts = RenderOptions(samples=pattern, texture_filter=name, with_range=False)
                seconds = timed(lambda db=db, opts=opts, out=out: render_frame(db, channel, eye, opts, out=out),
                                repeats)
                err = np.abs(out[GROUND_ROWS].astype(np.float64) - ref[GROUND_ROWS])
                rows.append({"texture": texture, "filter": name, "samples": pattern,
                             "spp": RenderOptions(samples=pattern).sample_count,
                             "ms": seconds * 1e3, "rmse": float(np.sqrt(np.mean(err ** 2))),
                             "p99": float(np.quantile(err, 0.99))})
                print(f"  {texture:8s} {name:7s} {pattern:6s} {rows[-1]['ms']:7.1f} ms "
                      f"rmse {rows[-1]['rmse']:.4f}", file=sys.stderr, flush=True)
    return rows


def plain(doc: dict) -> dict:
    """The scene document without texture codes or smooth models."""
    doc = copy.deepcopy(doc)
    doc.pop("textures", None)
    doc.pop("texture_codes", None)
    for model in doc["models"].values():
        model.pop("smooth", None)
        for face in model["faces"]:
            face.pop("texture", None)
            face.pop("texture_plane", None)
    return doc


def airfield_costs(repeats: int, quick: bool) -> list[dict[str, Any]]:
    from channel_worker.pipeline.render import render_frame
    from channel_worker.pipeline.scene.load import demo_scene_path, parse_scene
    from services.rig.frame import ChannelSpec, Eyepoint
    from services.rig.options import RenderOptions
    path = demo_scene_path()
    doc = json.loads(path.read_text(encoding="utf-8"))
    scenes = {"textured": parse_scene(doc, source=str(path), base_dir=path.parent),
              "plain": parse_scene(plain(doc), source="plain airfield", base_dir=path.parent)}
    channel = ChannelSpec.symmetric("centre", 1024, 768, 60.0)
    opts = RenderOptions(with_range=False)
    out = np.empty((768, 1024, 3), np.float32)
    rows = []
    for k, eye in enumerate(AIRFIELD_EYES[:1] if quick else AIRFIELD_EYES):
        row: dict[str, Any] = {"eyepoint": list(eye)}
        for name, db in scenes.items():
            ep = Eyepoint.of(*eye)
            row[f"{name}_ms"] = timed(lambda db=db, ep=ep: render_frame(db, channel, ep, opts, out=out),
                                      repeats) * 1e3
        row["ratio"] = row["textured_ms"] / row["plain_ms"]
        print(f"  airfield eye {k}: textured {row['textured_ms']:.1f} ms, plain {row['plain_ms']:.1f} ms",
              file=sys.stderr, flush=True)
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = bench_parser(__doc__, "texture", "default 7; --quick 2",
                          "the checkerboard and one airfield eyepoint: checks the bench runs")
    args = parser.parse_args(argv)
    if replot(args, "texture", print_report, plot):
        return 0
    repeats = args.repeats if args.repeats is not None else (2 if args.quick else 7)
    cpu = pin_to_one_cpu(args.cpu)
    import numba
    numba.set_num_threads(1)
    from bench_render import machine
    from bench_terrain import git_state
    record: dict[str, Any] = {
        "benchmark": "textures: speed against error of each texture filter at 1, 4, 16 samples "
                     "on a grazing textured plane; the cost of the bundled airfield's looks",
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(), "git": git_state(),
        "one_core": {"cpu": cpu, "affinity": sorted(os.sched_getaffinity(0))
                     if hasattr(os, "sched_getaffinity") else None, "numba_threads": 1},
        "quick": args.quick, "repeats": repeats,
        "grazing": {"size": list(SIZE), "eyepoint": list(EYE), "scale_m": 4.0,
                    "reference": "pixel centres at 8x resolution, 8 x 8 box: 64 samples a pixel",
                    "error_rows": [GROUND_ROWS.start, GROUND_ROWS.stop]},
        "statistic": "ms: median wall-clock of render_frame; rmse, p99 over the ground rows",
    }
    record["filters"] = filter_errors(repeats, args.quick)
    record["airfield"] = airfield_costs(repeats, args.quick)
    finish(record, args.out, "texture", print_report, plot)
    return 0


def print_report(record: dict) -> None:
    print(f"\ntexture filters on the grazing plane, {record['grazing']['size']}, one core:")
    print(f"  {'texture':8s} {'filter':7s} {'samples':7s} {'ms':>7s} {'rmse':>7s} {'p99':>7s}")
    for r in record["filters"]:
        print(f"  {r['texture']:8s} {r['filter']:7s} {r['samples']:7s} {r['ms']:7.1f} "
              f"{r['rmse']:7.4f} {r['p99']:7.4f}")
    print("\nthe demo's scene, 1024 x 768 rgss4, one core (ms; the real-time budget is 33 ms):")
    print(f"  {'eyepoint':36s} {'textured':>9s} {'plain':>7s} {'ratio':>6s}")
    for r in record["airfield"]:
        print(f"  {r['eyepoint']!s:36s} {r['textured_ms']:9.1f} {r['plain_ms']:7.1f} {r['ratio']:6.2f}")
    m = record["machine"]
    print(f"\n{m.get('cpu', '?')}, {record['date']}")


def plot(record: dict, path: Path) -> bool:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    textures = sorted({r["texture"] for r in record["filters"]})
    fig, axes = plt.subplots(1, len(textures), figsize=(6 * len(textures), 4.5), squeeze=False)
    for ax, texture in zip(axes[0], textures, strict=True):
        for name, colour in zip(FILTERS, ("tab:blue", "tab:orange", "tab:green"), strict=True):
            pts = [r for r in record["filters"] if r["texture"] == texture and r["filter"] == name]
            ax.plot([r["rmse"] for r in pts], [1e3 / r["ms"] for r in pts], "o-", color=colour, label=name)
            for r in pts:
                ax.annotate(str(r["spp"]), (r["rmse"], 1e3 / r["ms"]), fontsize=8,
                            textcoords="offset points", xytext=(4, 4))
        ax.set_xlabel("RMSE against 64 samples (linear RGB)")
        ax.set_ylabel("frames per second, one core")
        ax.set_title(f"{texture}, grazing plane {record['grazing']['size']}")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


if __name__ == "__main__":
    sys.exit(main())
