"""`ig render`: one frame of one channel to an image file."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from services.rig.cli_common import EXIT_BAD_INPUT, EXIT_FAILED, field_of_view, pixels
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import add_render_arguments, from_arguments
from services.rig.report import FrameReport

from .data import DEFAULT_SCENE, resolve_scene, scene_names_help

#: The image formats `ig render` writes, by suffix, and what each holds. A JPEG (which
#: OpenImageIO would write as readily) is refused: its lossy blocks smear exactly the edge
#: anti-aliasing and texture detail a frame grab of an IG is taken to inspect, and it cannot
#: hold the range channel.
FORMATS = {".exr": "linear float RGB + Z range in metres", ".png": "sRGB 8-bit"}


def output_image(text: str) -> Path:
    """argparse type of --out: a .exr or .png file in a directory that exists (a mistyped
    directory is an error, not a new folder somewhere)."""
    path = Path(text)
    if path.suffix.lower() not in FORMATS:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a {' or '.join(FORMATS)} file ({'; '.join(f'{k}: {v}' for k, v in FORMATS.items())})")
    parent = path.parent
    if not parent.exists():
        raise argparse.ArgumentTypeError(f"{text!r}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: {str(parent)!r} is not a directory")
    return path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig render`."""
    scene_help = (f"a scene JSON file (docs/scene-format.md) or a bundled scene's name: {scene_names_help()}; "
                  f"default: {DEFAULT_SCENE}")
    parser.add_argument("scene", nargs="?", default=None, metavar="SCENE", help=scene_help)
    parser.add_argument("--scene", dest="scene_option", default=None, metavar="SCENE",
                        help="the scene, as the SCENE argument takes it (give one or the other)")
    parser.add_argument("--eye", nargs=3, type=float, metavar=("X", "Y", "Z"), required=True,
                        help="eyepoint, world metres (x east, y north, z up)")
    parser.add_argument("--hpr", nargs=3, type=float, metavar=("H", "P", "R"), default=(0.0, 0.0, 0.0),
                        help="aircraft heading, pitch, roll in degrees (default 0 0 0)")
    parser.add_argument("--width", type=pixels, default=1024, help="pixels, 1..16384 (default 1024)")
    parser.add_argument("--height", type=pixels, default=768, help="pixels, 1..16384 (default 768)")
    parser.add_argument("--fov-h", type=field_of_view, default=60.0,
                        help="horizontal field of view, degrees in (0, 178] (default 60)")
    parser.add_argument("--fov-v", type=field_of_view, default=None,
                        help="vertical field of view, degrees in (0, 178] (default: square pixels)")
    parser.add_argument("--channel-hpr", nargs=3, type=float, metavar=("H", "P", "R"), default=(0.0, 0.0, 0.0),
                        help="channel yaw, pitch, roll offset from the aircraft nose, degrees")
    add_render_arguments(parser, renderer=True, with_range=True)
    parser.add_argument("--out", required=True, type=output_image,
                        help="output image in an existing directory: "
                             + " or ".join(f"{k} ({v})" for k, v in FORMATS.items()))
    parser.add_argument("--times", action="store_true", help="print the time of each pipeline stage")


def run(args: argparse.Namespace) -> int:
    """Render and write the frame; 0 on success, 2 on bad input."""
    # The pipeline (numba) and OpenImageIO are imported here, not at the top: `ig --help` builds
    # every subcommand's parser and should not wait for the renderer to load.
    from services.rig.image_io import write_image
    from services.rig.threads import size_thread_pool

    if args.scene is not None and args.scene_option is not None:
        print(f"ig render: error: the scene given twice: SCENE {args.scene!r} and --scene {args.scene_option!r}; "
              "give one", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        options = from_arguments(args)
        # Before the pipeline is imported: numba sizes its pool once (services/rig/threads.py).
        size_thread_pool(options.threads, setting="--threads")
    except ValueError as exc:
        print(f"ig render: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from .pipeline.render import render_frame
    from .pipeline.scene.load import SceneError, load_scene

    try:
        given = ("SCENE", args.scene) if args.scene is not None else ("--scene", args.scene_option)
        database = load_scene(resolve_scene(given[1], setting=given[0]))
        channel = ChannelSpec.symmetric("render", args.width, args.height, args.fov_h, args.fov_v,
                                        yaw_deg=args.channel_hpr[0], pitch_deg=args.channel_hpr[1],
                                        roll_deg=args.channel_hpr[2])
        eyepoint = Eyepoint.of(*args.eye, *args.hpr)
        report = FrameReport()
        t0 = time.perf_counter()
        image = render_frame(database, channel, eyepoint, options, report=report)
        elapsed = time.perf_counter() - t0
    except (SceneError, ValueError) as exc:
        print(f"ig render: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        # Within every limit, a big frame with many samples can still exceed this machine.
        print(f"ig render: error: out of memory rendering {args.width} x {args.height} pixels "
              f"({options.sample_count} samples each); ask for fewer", file=sys.stderr)
        return EXIT_FAILED
    attributes = {
        "eye_x": eyepoint.position[0], "eye_y": eyepoint.position[1], "eye_z": eyepoint.position[2],
        "heading_deg": eyepoint.heading_deg, "pitch_deg": eyepoint.pitch_deg, "roll_deg": eyepoint.roll_deg,
        "channel": channel.name,
        "channel_yaw_deg": channel.yaw_deg, "channel_pitch_deg": channel.pitch_deg,
        "channel_roll_deg": channel.roll_deg,
        "frustum_deg": f"{channel.left_deg} {channel.right_deg} {channel.bottom_deg} {channel.top_deg}",
        "samples": options.samples, "scene": str(database.source),
        "renderer": options.renderer, "filter": options.filter,
    }
    try:
        write_image(args.out, image.rgb, range_m=image.range_m, attributes=attributes)
    except OSError as exc:
        print(f"ig render: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if report.counters.get("terrain_eye_clamped"):
        print(f"ig render: warning: the eye {tuple(args.eye)} is below the terrain; the terrain is drawn from "
              "just above its surface, the polygons from the eye", file=sys.stderr)
    if args.times:
        for stage, seconds in report.stage_seconds.items():
            print(f"{stage:>10} {seconds * 1000:9.2f} ms")
        for name, value in report.counters.items():
            print(f"{name:>24} {value}")
    print(f"wrote {args.out} ({channel.width} x {channel.height}, {elapsed * 1000:.1f} ms)")
    return 0
