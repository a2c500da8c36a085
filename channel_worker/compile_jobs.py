"""The render kernels compiled in several processes at once, for `ig compile` on a cold cache.

numba compiles one kernel at a time per process (a process-wide compiler lock), and a cold
compile of the pipeline takes well over a minute of one core. The kernels fall into two groups
that never call each other:

- ``polygons``: geometry, edges, binning, the visibility with its fused shading (or the sample
  store and the resolve filters), i.e. a frame of the scene without its atmosphere, where the
  background is contract.no_background(), whose arrays have the real background's types; and
  the worker's image encoder;
- ``background``: the background stage alone, with no sub-area lists (bins=None: sample depth
  everywhere, same types), in two groups: ``terrain`` (the terrain cast and its per-sample
  depth) and ``sky`` (sky and earth, clouds, the frame's air).

Each group is compiled in a process of its own (spawned, not forked: numba's thread pools do
not survive a fork), all writing into the machine's kernel cache (pipeline/kernel_cache.py).
Then the parent renders one tiny frame exactly as a worker does: it loads every kernel the
groups compiled and compiles whatever they missed (nothing while the groups match
render_frame; tests/channel_worker/test_compile.py checks that they do). So the split can only
make a compile faster or, if it drifts from render_frame, no faster: never wrong.

Once a compile has finished, a marker in the cache directory records it for its scene,
options and source files as numba keys them (mark_compiled), and the next compile of the same
request skips the groups: spawning
them only to load kernels from the cache would take seconds, the check frame alone about one.

Progress goes to a callback as Progress events: a numba event listener in each process reports
every kernel it starts and finishes compiling (numba's own helper overloads are left out).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import multiprocessing
import queue
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from services.rig.frame import ChannelSpec, Eyepoint
from services.rig.options import RenderOptions

if TYPE_CHECKING:
    from .pipeline.scene.database import Database

#: The groups, in the order they are handed to processes, and what each compiles.
GROUPS = {
    "polygons": "geometry, binning, visibility, shading",
    "terrain": "the terrain cast and its per-sample depth",
    "sky": "sky and earth, clouds, haze and fog",
}

#: The last step: one frame as a worker renders it (loads every kernel, compiles any missed).
CHECK = "check"

#: Where the tiny frame's eye is (the workers' warm-up frame: channel_worker/worker.py).
EYEPOINT = Eyepoint.of(0.0, 0.0, 10.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CompileRequest:
    """What to compile for: the workers' scene and options, on a tiny channel.

    Attributes:
        scene: path of the scene JSON the workers render.
        options: the workers' render options (colour only, as a worker renders).
        channel: the tiny channel the frames are rendered on (the first channel's frustum).
        cigi: the rig follows a CIGI host (its rig file has a [cigi] table): the height and
            line-of-sight query kernels too, and the atmosphere's with a host's weather
            (environment.WARM_UP_ENVIRONMENT) for a scene without its own.
    """

    scene: str
    options: RenderOptions
    channel: ChannelSpec
    cigi: bool = False


class Progress(NamedTuple):
    """One step of a compile, as the display sees it.

    Attributes:
        group: the group (GROUPS: "polygons", "terrain", "sky") or CHECK.
        kind: "group-start", "group-end" (seconds: the group's wall time; kernels: how many it
            compiled), "kernel-start" (name: the kernel), "kernel-end" (name, seconds),
            "failed" (name: the error and its traceback).
        name: see kind.
        seconds: see kind.
        kernels: see kind.
    """

    group: str
    kind: str
    name: str = ""
    seconds: float = 0.0
    kernels: int = 0


class CompileError(RuntimeError):
    """A compile process failed; the message names the group and the error."""


def plan(database: Database, options: RenderOptions, jobs: int) -> list[str]:
    """The groups compiled in parallel processes before the check frame: none (everything in
    the check frame, in this process) with one job, or when the scene has nothing but polygons
    (no terrain or atmosphere drawn, or the scanline renderer, which draws none); "terrain"
    only for a scene with terrain.

    Three processes on two cores rather than two: the background's kernels took 32 s in one
    process against the polygons' 21 s; split into the scan's and the warp's, the three
    share the cores evenly (the demo scene's compile on a cold cache 31.3 -> 27.3 s); the
    terrain cast replaced both in 2026-11, and its group is split the same way."""
    if jobs < 2 or options.renderer == "scanline":
        return []
    scene = _drawn(database, options)
    if scene.terrain is None and scene.haze is None and scene.fog is None and scene.clouds is None:
        return []
    return [g for g in GROUPS if g != "terrain" or scene.terrain is not None]


def compiled_before(request: CompileRequest) -> bool:
    """A compile of this request has finished into the current kernel cache (mark_compiled)."""
    return _marker(request).is_file()


def mark_compiled(request: CompileRequest, kernels: int) -> None:
    """Record that every kernel of request is in the kernel cache (a JSON file, for people to
    read too); a cache that cannot be written is left unmarked."""
    doc = {"scene": request.scene, "options": repr(request.options), "channel": repr(request.channel),
           "kernels_compiled": kernels}
    with contextlib.suppress(OSError):  # it only spares the next compile its groups
        _marker(request).write_text(json.dumps(doc, indent=1) + "\n")


def _marker(request: CompileRequest) -> Path:
    """compiled-<hash of the scene file, the options, the channel and where and when the sources
    were written>.json in the cache. The last because numba keys its entries by the source
    files' paths and time stamps (kernel_cache.sources_stamp): a fresh clone of the same sources
    finds the cache directory but compiles every kernel again, and then the groups' processes
    should do it in parallel (measured on a fresh clone without this: the check frame compiled
    all 30 kernels in one process in 53 s)."""
    from .pipeline.kernel_cache import kernel_cache_dir, sources_stamp

    digest = hashlib.sha256()
    digest.update(repr((request.options, request.channel, request.cigi, sources_stamp())).encode())
    try:
        digest.update(Path(request.scene).read_bytes())
    except OSError:
        digest.update(request.scene.encode())
    return kernel_cache_dir() / f"compiled-{digest.hexdigest()[:16]}.json"


def compile_kernels(request: CompileRequest, database: Database, groups: list[str],
                    on_progress: Callable[[Progress], None]) -> list[str]:
    """Compile every kernel a worker rendering request needs into the kernel cache.

    Args:
        request: the scene, options and tiny channel.
        database: the scene, loaded (by the caller, who reports a bad one).
        groups: the groups to compile in processes of their own first (plan()); none: every
            kernel in the check frame, in this process, one at a time.
        on_progress: called with every Progress event, from this thread.

    Returns:
        The kernels the check frame compiled (those the groups missed; every one without
        groups), by module.qualname.

    Raises:
        CompileError: a compile process failed or died.
        ValueError: the options cannot render the scene (render_frame's errors).
    """
    from .pipeline.kernel_cache import serialise_cache_writes

    serialise_cache_writes()
    if groups:
        _in_processes(request, groups, on_progress)
    return _check_frame(request, database, on_progress)


def hosted(database: Database, request: CompileRequest) -> Database:
    """The database a group compiles for: under a host's weather when the rig follows a CIGI
    host, so that the atmosphere's kernels are compiled even for a scene without one."""
    if not request.cigi:
        return database
    from .pipeline.scene.environment import WARM_UP_ENVIRONMENT, with_environment

    return with_environment(database, WARM_UP_ENVIRONMENT)


def run_group(group: str, request: CompileRequest) -> None:
    """Render the part of a frame that compiles group's kernels (GROUPS), in this process."""
    from .pipeline.background.background import render_background
    from .pipeline.geometry.view import frame_constants, make_view
    from .pipeline.render import render_frame
    from .pipeline.scene.load import load_scene

    database = hosted(load_scene(request.scene), request)
    if group == "polygons":
        from .submit import warm_encoders

        bare = dataclasses.replace(database, terrain=None, haze=None, fog=None, clouds=None)
        render_frame(bare, request.channel, EYEPOINT, request.options)
        warm_encoders()  # the worker's encoders for the compositor, compiled here too
        if request.cigi:
            from .query.service import warm_queries

            warm_queries(database)  # and the CIGI height and line-of-sight queries
    elif group in ("terrain", "sky"):
        # No sub-area lists (bins None): the stage then wants per-sample depth everywhere, with
        # arguments of the same types as a frame's.
        # The terrain group casts the terrain (and its per-sample depth) without the clouds,
        # the sky group paints the sky and earth plane and lays the clouds without the terrain.
        scene = _drawn(database, request.options)
        if group == "terrain":
            if scene.terrain is None:
                return
            scene = dataclasses.replace(scene, clouds=None)
        else:
            scene = dataclasses.replace(scene, terrain=None)
            if scene.haze is None and scene.fog is None and scene.clouds is None:
                return
        view = make_view(request.channel, EYEPOINT)
        frame = frame_constants(view, scene, request.options.sample_offsets())
        render_background(scene, view, frame, request.options, None, {})
    else:
        raise ValueError(f"group: {group!r} is none of {', '.join(GROUPS)}")


def _drawn(database: Database, options: RenderOptions) -> Database:
    """The database as render_frame draws it: without its haze or clouds when the options turn
    them off (render._drawn)."""
    return dataclasses.replace(database, haze=database.haze if options.haze else None,
                               clouds=database.clouds if options.clouds else None)


def _check_frame(request: CompileRequest, database: Database,
                 on_progress: Callable[[Progress], None]) -> list[str]:
    """The worker's warm-up (Worker.warm_up: a tiny frame, its image encoded for the
    compositor; when the rig follows a CIGI host, the frame again under a host's weather and one
    query of each kind), in this process; returns the kernels it compiled."""
    from .pipeline.render import render_frame
    from .query.service import warm_queries
    from .submit import warm_encoders

    on_progress(Progress(CHECK, "group-start"))
    t0 = time.perf_counter()
    with kernel_events(CHECK, on_progress) as compiled:
        render_frame(database, request.channel, EYEPOINT, request.options)
        warm_encoders()
        if request.cigi:
            render_frame(hosted(database, request), request.channel, EYEPOINT, request.options)
            warm_queries(database)
    on_progress(Progress(CHECK, "group-end", seconds=time.perf_counter() - t0, kernels=len(compiled)))
    return compiled


@contextmanager
def kernel_events(group: str, on_progress: Callable[[Progress], None]) -> Iterator[list[str]]:
    """Report every kernel this process compiles meanwhile; yields the list of their names."""
    from numba.core import event

    compiled: list[str] = []
    started: list[float] = []

    class Listener(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            started.append(time.perf_counter())
            name = _kernel_name(ev)
            if name:
                on_progress(Progress(group, "kernel-start", name))

        def on_end(self, ev: event.Event) -> None:
            # Nested compiles (a kernel's non-inlined callees) end before their caller.
            seconds = time.perf_counter() - started.pop()
            name = _kernel_name(ev)
            if name:
                compiled.append(name)
                on_progress(Progress(group, "kernel-end", name, seconds))

    with event.install_listener("numba:compile", Listener()):
        yield compiled


def _kernel_name(ev: Any) -> str:
    """The compiled function's module.qualname; "" for numba's own overloads (np.empty's
    implementation and the like), which compile inside the kernels that use them."""
    func = ev.data["dispatcher"].py_func
    module = func.__module__ or ""
    return "" if module.startswith("numba.") else f"{module}.{func.__qualname__}"


def _in_processes(request: CompileRequest, groups: list[str],
                  on_progress: Callable[[Progress], None]) -> None:
    """Compile each group in a process of its own; returns once all have finished."""
    ctx = multiprocessing.get_context("spawn")
    events: Any = ctx.Queue()
    procs = {g: ctx.Process(target=_group_main, args=(g, request, events), name=f"ig-compile-{g}",
                            daemon=True) for g in groups}
    # SIGTERM (`ig demo` stopping, systemd) ends this process through the finally below, which
    # stops the children, instead of killing it outright and leaving them compiling. (Python
    # takes signals in its main thread only.)
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _exit_on_sigterm) if main else None
    try:
        for p in procs.values():
            try:
                p.start()
            except OSError as exc:
                raise CompileError(f"cannot start the {p.name} process: {exc}") from exc
        running = set(groups)
        while running:
            try:
                ev = events.get(timeout=0.5)
            except queue.Empty:
                # A process that has ended put its last events before it did: one more look
                # for them, then it ended without finishing (killed: out of memory, a signal).
                gone = [g for g in running if procs[g].exitcode is not None]
                if gone and events.empty():
                    g = gone[0]
                    raise CompileError(f"the {g} compile process exited with code {procs[g].exitcode} "
                                       f"before it finished") from None
                continue
            on_progress(ev)
            if ev.kind == "failed":
                raise CompileError(f"the {ev.group} compile process failed: {ev.name}")
            if ev.kind == "group-end":
                running.discard(ev.group)
        for p in procs.values():
            p.join(timeout=10.0)
    finally:
        if main:
            signal.signal(signal.SIGTERM, previous)
        for p in procs.values():
            if p.is_alive():
                p.terminate()
                p.join(timeout=5.0)


def _exit_on_sigterm(signum: int, frame: Any) -> None:
    sys.exit(128 + signum)


def _group_main(group: str, request: CompileRequest, events: Any) -> None:
    """Entry point of a compile process: run_group under the event listener."""
    from .pipeline.kernel_cache import serialise_cache_writes

    def send(ev: Progress) -> None:
        events.put(ev)

    serialise_cache_writes()
    try:
        send(Progress(group, "group-start"))
        t0 = time.perf_counter()
        with kernel_events(group, send) as compiled:
            run_group(group, request)
        send(Progress(group, "group-end", seconds=time.perf_counter() - t0, kernels=len(compiled)))
    except KeyboardInterrupt:
        # Ctrl-C reaches every process of the terminal's group: the parent reports it.
        sys.exit(130)
    except BaseException as exc:  # the parent reports it; a traceback alone would be lost
        send(Progress(group, "failed", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
        raise SystemExit(1) from None
    finally:
        events.close()
        events.join_thread()  # the last events reach the parent before this process ends
