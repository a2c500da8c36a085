"""`ig compile`: compile the render kernels a worker needs, once for every worker of this machine.

The kernels are cached per version of the pipeline's sources (channel_worker/pipeline/
kernel_cache.py), so every worker started afterwards loads them in a second or two instead of
compiling them itself; `ig demo` runs this before it starts the rig. On a cold cache the kernels
compile in a process per group at once (channel_worker/compile_jobs.py), and the progress shows
while they do: which group compiles which kernel, seconds so far, groups done. A request
compiled before (same sources, scene and options) only loads them, in about a second.
"""

from __future__ import annotations

import argparse
import queue
import sys
import threading
import time
from typing import TextIO

from services.rig.cli_common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, error, load_rig_or_report
from services.rig.frame import ChannelSpec
from services.rig.options import add_render_arguments, from_arguments
from services.rig.rigfile import scene_path
from services.rig.threads import usable_cores

# Light: the pipeline (numba) is imported only when a compile runs.
from .compile_jobs import (
    CHECK,
    GROUPS,
    CompileError,
    CompileRequest,
    Progress,
    compile_kernels,
    compiled_before,
    hosted,
    mark_compiled,
    plan,
)
from .data import SCENES, bundled_or_path

#: Exit code after Ctrl-C (128 + SIGINT), as shells report it.
EXIT_INTERRUPTED = 130

#: Seconds between status lines when the output is not a terminal (a log, `ig demo`).
LOG_STATUS_EVERY_S = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig compile`."""
    parser.add_argument("--scene", default=None,
                        help="scene JSON the workers will render (its terrain, haze, fog and clouds "
                             "decide which kernels are needed), or a bundled scene's name "
                             f"({', '.join(SCENES)}); default: the rig file's [scene] path, else the "
                             "bundled airfield")
    parser.add_argument("--rig", default=None,
                        help="rig file whose [render] table the workers read (default: the bundled rig)")
    add_render_arguments(parser, renderer=True, with_range=True)
    parser.add_argument("--jobs", type=_jobs, default=usable_cores(),
                        help="cores to compile on (default: this machine's, "
                             f"{usable_cores()}): from 2, the kernel groups each compile in a process of "
                             "their own, all at once (three for a scene with terrain); 1 compiles "
                             "in this process, one kernel at a time")
    parser.add_argument("--prune", action="store_true",
                        help="also remove the cached kernels of other versions of the sources")


def run(args: argparse.Namespace) -> int:
    """Render one tiny frame with the workers' options; 0 ok, 1 a compile failed, 2 bad input,
    130 interrupted."""
    from .pipeline.kernel_cache import kernel_cache_dir, prune
    from .pipeline.scene.load import SceneError, bundled_scene_path, load_scene

    rig = load_rig_or_report(args.rig, "compile")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        # As a worker renders: the rig's options under the flags, colour only.
        options = from_arguments(args, base=rig.render)
        if args.with_range is None:
            options = options.replace(with_range=False)
        scene = scene_path(bundled_or_path(args.scene), rig, bundled_scene_path())
        database = load_scene(scene)
    except (SceneError, ValueError) as exc:
        error("compile", exc)
        return EXIT_BAD_INPUT
    first = rig.channels[0].spec
    # The workers' warm-up frame (channel_worker/worker.py): any frame size compiles the same
    # kernels, and a tiny one renders in no time once they are compiled.
    tiny = ChannelSpec("compile", 8, 6, first.left_deg, first.right_deg, first.bottom_deg, first.top_deg)
    request = CompileRequest(scene, options, tiny, cigi=rig.cigi.configured)
    cache = kernel_cache_dir()
    if compiled_before(request):
        groups: list[str] = []
        print(f"ig compile: loading the render kernels from {cache} (compiled there before for this scene "
              f"and these options)", flush=True)
    else:
        groups = plan(hosted(database, request), options, args.jobs)
        how = (f"{len(groups)} groups in processes of their own ({', '.join(groups)}), then one frame as a "
               f"worker renders it" if groups else "one frame as a worker renders it")
        print(f"ig compile: compiling the render kernels into {cache}: {how} (a minute or so the first time "
              f"on a new version of the sources, a second or two once cached)", flush=True)
    t0 = time.perf_counter()
    display = ProgressDisplay(sys.stdout, [*groups, CHECK])
    try:
        with display:
            compiled = compile_kernels(request, database, groups, display.put)
    except CompileError as exc:
        error("compile", exc)
        return EXIT_FAILED
    except ValueError as exc:  # options the renderer refuses for this scene (render_frame)
        error("compile", exc)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("ig compile: interrupted; the kernels compiled so far stay cached", file=sys.stderr)
        return EXIT_INTERRUPTED
    total = display.kernels_compiled()
    mark_compiled(request, total)
    what = f"{total} kernels compiled" if total else "every kernel was in the cache"
    print(f"ig compile: done in {time.perf_counter() - t0:.1f} s ({what})", flush=True)
    if groups and compiled:
        # Not an error (they are cached now), but a sign that compile_jobs.run_group no longer
        # renders what a worker does: the groups left these to one process, one at a time.
        print(f"ig compile: note: the check frame compiled {len(compiled)} kernels that no group did "
              f"({', '.join(_short(k) for k in compiled)}): channel_worker/compile_jobs.py's groups "
              f"no longer cover what a worker renders", file=sys.stderr)
    if args.prune:
        for path in prune(cache):
            print(f"ig compile: removed {path}", file=sys.stderr)
    return EXIT_OK


class ProgressDisplay:
    """A compile's progress on a stream: a line for each finished group and, while groups run,
    a status line (seconds so far, groups done of all, the kernel each running group compiles):
    redrawn every second on a terminal, printed every LOG_STATUS_EVERY_S seconds elsewhere.

    put() takes compile_jobs.Progress events from any thread; the display's own thread prints,
    so the status keeps counting while this process compiles (the check frame).
    """

    def __init__(self, stream: TextIO, groups: list[str]) -> None:
        self.stream = stream
        self.groups = groups
        self.tty = stream.isatty()
        self._events: queue.Queue[Progress | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="ig-compile-progress", daemon=True)
        self._t0 = time.monotonic()
        self._running: dict[str, list[str]] = {}  # group -> the kernels it is compiling, outermost first
        self._compiled = dict.fromkeys(groups, 0)
        self._done = 0
        self._status_shown = False

    def put(self, event: Progress) -> None:
        """Show event (thread-safe)."""
        self._events.put(event)

    def kernels_compiled(self) -> int:
        """Kernels compiled so far, every group together (read once the display has stopped)."""
        return sum(self._compiled.values())

    def __enter__(self) -> ProgressDisplay:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._events.put(None)
        self._thread.join()

    def _run(self) -> None:
        every = 1.0 if self.tty else LOG_STATUS_EVERY_S
        next_status = time.monotonic() + every
        while True:
            try:
                event = self._events.get(timeout=max(0.0, next_status - time.monotonic()))
            except queue.Empty:
                self._status()
                next_status = time.monotonic() + every
                continue
            if event is None:
                self._clear_status()
                return
            self._show(event)

    def _show(self, ev: Progress) -> None:
        if ev.kind == "group-start":
            self._running[ev.group] = []
        elif ev.kind == "kernel-start":
            self._running.setdefault(ev.group, []).append(_short(ev.name))
        elif ev.kind == "kernel-end":
            stack = self._running.get(ev.group)
            if stack:
                stack.pop()
            self._compiled[ev.group] = self._compiled.get(ev.group, 0) + 1
        elif ev.kind == "group-end":
            self._running.pop(ev.group, None)
            self._done += 1
            n = ev.kernels
            what = (f"{n} kernel{'s' if n != 1 else ''} compiled in {ev.seconds:.1f} s" if n
                    else f"every kernel loaded from the cache, {ev.seconds:.1f} s")
            self._line(f"  [{self._done}/{len(self.groups)}] {_label(ev.group)}: {what}")

    def _status(self) -> None:
        if not self._running:
            return
        now = ", ".join(f"{g}: {stack[-1] if stack else 'loading'}" for g, stack in self._running.items())
        text = f"  {time.monotonic() - self._t0:4.0f} s  [{self._done}/{len(self.groups)} done]  {now}"
        if self.tty:
            self.stream.write(f"\r{text}\x1b[K")  # \x1b[K: erase what a longer line left
            self._status_shown = True
        else:
            self.stream.write(f"ig compile:{text}\n")
        self.stream.flush()

    def _line(self, text: str) -> None:
        self._clear_status()
        self.stream.write(f"ig compile:{text}\n")
        self.stream.flush()

    def _clear_status(self) -> None:
        if self._status_shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._status_shown = False


def _label(group: str) -> str:
    """How the display names a step: "polygons (geometry, ...)", the check frame."""
    return f"{group} ({GROUPS[group]})" if group in GROUPS else "a frame as a worker renders it"


def _short(name: str) -> str:
    """A kernel's name without its package: "_resolve_kernels.box_subarea"."""
    module, _, qualname = name.rpartition(".")
    return f"{module.rpartition('.')[2]}.{qualname}" if module else name




#: Most --jobs: as many as RenderOptions.threads allows (more cores than any machine has).
MAX_JOBS = 1024


def _jobs(text: str) -> int:
    """argparse type: a whole number of processes in [1, MAX_JOBS]."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_JOBS:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number in [1, {MAX_JOBS}]")
    return value
