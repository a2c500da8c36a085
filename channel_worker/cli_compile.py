"""`ig compile`: compile the render kernels a worker needs, once for every worker of this machine.

The kernels are cached per version of the pipeline's sources (channel_worker/pipeline/
kernel_cache.py), so every worker started afterwards loads them in a second or two instead of
compiling them itself; `ig demo` runs this before it starts the rig.
"""

from __future__ import annotations

import argparse
import sys
import time

from services.rig.cli_common import EXIT_BAD_INPUT, EXIT_OK, error, load_rig_or_report
from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import add_render_arguments, from_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig compile`."""
    parser.add_argument("--scene", default=None,
                        help="scene JSON the workers will render (its terrain, haze, fog and clouds "
                             "decide which kernels are needed); default: the bundled airfield")
    parser.add_argument("--rig", default=None,
                        help="rig file whose [render] table the workers read (default: the bundled rig)")
    add_render_arguments(parser, renderer=True, with_range=True)
    parser.add_argument("--prune", action="store_true",
                        help="also remove the cached kernels of other versions of the sources")


def run(args: argparse.Namespace) -> int:
    """Render one tiny frame with the workers' options; 0 ok, 2 bad input."""
    from .pipeline.kernel_cache import kernel_cache_dir, prune
    from .pipeline.render import render_frame
    from .pipeline.scene.load import SceneError, bundled_scene_path, load_scene

    rig = load_rig_or_report(args.rig, "compile")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        # As a worker renders: the rig's options under the flags, colour only.
        options = from_arguments(args, base=rig.render)
        if args.with_range is None:
            options = options.replace(with_range=False)
        database = load_scene(args.scene or bundled_scene_path())
    except (SceneError, ValueError) as exc:
        error("compile", exc)
        return EXIT_BAD_INPUT
    cache = kernel_cache_dir()
    print(f"ig compile: compiling the render kernels into {cache} (minutes the first time on a "
          f"new version of the sources, seconds once cached) ...", end="", flush=True)
    t0 = time.perf_counter()
    first = rig.channels[0].spec
    tiny = ChannelSpec("compile", 8, 6, first.left_deg, first.right_deg, first.bottom_deg,
                       first.top_deg)
    render_frame(database, tiny, Eyepoint.of(0.0, 0.0, 10.0, 0.0, 0.0, 0.0), options)
    print(f" done in {time.perf_counter() - t0:.1f} s", flush=True)
    if args.prune:
        for path in prune(cache):
            print(f"ig compile: removed {path}", file=sys.stderr)
    return EXIT_OK
