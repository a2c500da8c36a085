"""`ig compile`: the kernels compiled in several processes into one cache, from which a worker then
loads every kernel without compiling; the lock that keeps concurrent saves apart; the progress
display."""

from __future__ import annotations

import argparse
import dataclasses
import fcntl
import io
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from channel_worker import cli_compile
from channel_worker.compile_jobs import CHECK, CompileError, CompileRequest, Progress, compile_kernels, plan
from channel_worker.pipeline.kernel_cache import LOCK_NAME, serialise_cache_writes
from channel_worker.pipeline.scene.load import bundled_scene_path, demo_scene_path, load_scene
from services.rig.frame import ChannelSpec
from services.rig.options import RenderOptions

ROOT = Path(__file__).resolve().parents[2]

#: A fresh process doing what a worker does before it serves (Worker.warm_up, with the bundled
#: rig's options and first channel), printing the cache hits and misses of every kernel.
_WARM_UP = """
import gc, json, sys
from numba.core.dispatcher import Dispatcher
from channel_worker.compile_jobs import EYEPOINT
from channel_worker.pipeline.render import render_frame
from channel_worker.pipeline.scene.load import load_scene
from channel_worker.submit import warm_encoders
from services.rig.cli_common import load_rig_or_report
from services.rig.frame import ChannelSpec

rig = load_rig_or_report(None, "test")
c = rig.channels[0].spec
tiny = ChannelSpec("warm-up", 8, 6, c.left_deg, c.right_deg, c.bottom_deg, c.top_deg)
render_frame(load_scene(sys.argv[1]), tiny, EYEPOINT, rig.render.replace(with_range=False))
warm_encoders()
ours = [d for d in gc.get_objects() if isinstance(d, Dispatcher)
        and d.py_func.__module__.split(".")[0] in ("channel_worker", "services")]
print(json.dumps({
    "hits": sum(sum(d.stats.cache_hits.values()) for d in ours),
    "misses": sorted(f"{d.py_func.__module__}.{d.py_func.__qualname__}"
                     for d in ours if sum(d.stats.cache_misses.values())),
}))
"""


def _ig(argv: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "services.cli", *argv], capture_output=True, text=True,
                          cwd=ROOT, env=env, timeout=900)


def _cache_with_the_bundled_terrain(cache: Path) -> Path:
    """cache, holding the bundled terrain (a link to the one in the suite's own cache, built
    there if missing) and no kernels: the demo scene's terrain is not what these tests are
    about, and building it again into an empty cache took 16 s of the compile test on the
    loaded 2-core VM (7 s of a core)."""
    from channel_worker.pipeline.scene.terrain.bundled import bundled_terrain_path

    built = bundled_terrain_path()
    cache.mkdir()
    (cache / built.name).symlink_to(built, target_is_directory=True)
    return cache


def cold_kernel_cache(tmp_path: Path) -> tuple[dict[str, str], Path]:
    """The environment of a compile into a cold kernel cache, and that cache's directory for
    the sources as they are now (kernel_cache_dir).

    The suite's own cache when it is cold (a fresh clone, CI, sources just changed: no kernel
    and no compile marker for these sources yet), so that the one cold compile of the session
    fills the cache every later test and rig loads from; compiled into a private one besides,
    it was the suite's largest single cost (a second compile of every kernel: 100-240 s of
    the 2-core VM). A warm suite cache gets a private empty one, as before. conftest.py runs
    this test first, before any other test has compiled a kernel into the suite's cache."""
    from channel_worker.pipeline.kernel_cache import kernel_cache_dir

    shared = kernel_cache_dir()
    if not any(shared.glob("*.nbi")) and not any(shared.glob("compiled-*.json")):
        return dict(os.environ), shared
    env = {**os.environ, "IG_CACHE_DIR": str(_cache_with_the_bundled_terrain(tmp_path / "cache"))}
    return env, tmp_path / "cache" / "numba" / shared.name


def test_compile_jobs_fill_a_cold_cache_that_a_worker_then_loads_every_kernel_from(tmp_path):
    # An empty kernel cache, as on a fresh clone: every kernel compiles, in three processes at
    # once (polygons, the terrain cast, the sky and clouds).
    env, kernels = cold_kernel_cache(tmp_path)
    scene = str(demo_scene_path())
    done = _ig(["compile", "--jobs", "2", "--scene", scene], env)
    assert done.returncode == 0, done.stdout + done.stderr
    out = done.stdout
    assert "[1/4]" in out and "[2/4]" in out and "[3/4]" in out and "kernels compiled in" in out
    # The groups rendered what render_frame renders: the check frame found every kernel cached.
    assert "note:" not in done.stderr, done.stderr
    assert f"[4/4] {cli_compile._label(CHECK)}: every kernel loaded from the cache" in out, out
    index_files = {p: p.stat().st_mtime_ns for p in kernels.rglob("*.nbi")}
    assert index_files

    warm = subprocess.run([sys.executable, "-c", _WARM_UP, scene], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=300)
    assert warm.returncode == 0, warm.stderr
    stats = json.loads(warm.stdout)
    assert stats["misses"] == []
    assert stats["hits"] > 0
    # Nothing was saved again: every index is as the compile left it.
    assert {p: p.stat().st_mtime_ns for p in kernels.rglob("*.nbi")} == index_files

    # Compiled before for this request (its marker): no groups, the check frame loads everything.
    assert len(list(kernels.glob("compiled-*.json"))) == 1
    again = _ig(["compile", "--jobs", "2", "--scene", scene], env)
    assert again.returncode == 0, again.stderr
    assert "compiled there before" in again.stdout and "[1/1]" in again.stdout
    assert "every kernel was in the cache" in again.stdout


def test_the_groups_are_planned_only_where_there_are_two_jobs_and_two_kinds_of_kernels():
    flat = load_scene(bundled_scene_path())  # polygons only
    demo = load_scene(demo_scene_path())  # terrain, haze, clouds
    options = RenderOptions()
    assert plan(demo, options, 2) == ["polygons", "terrain", "sky"]
    assert plan(demo, options, 1) == []
    assert plan(flat, options, 4) == []
    hazy = dataclasses.replace(demo, terrain=None, fog=None)
    assert hazy.haze is not None and hazy.clouds is not None
    assert plan(hazy, options, 2) == ["polygons", "sky"]  # no terrain: no scan to compile
    assert plan(hazy, options.replace(haze=False, clouds=False), 2) == []  # as render_frame draws it
    assert plan(demo, options.replace(renderer="scanline", samples="centre"), 2) == []


def test_a_failing_compile_process_is_reported_with_its_group_and_error(tmp_path):
    missing = str(tmp_path / "no-such-scene.json")
    request = CompileRequest(missing, RenderOptions(), ChannelSpec("compile", 8, 6, -30, 30, -22.5, 22.5))
    events: list[Progress] = []
    with pytest.raises(CompileError, match=r"the polygons compile process failed: SceneError: .*no-such-scene"):
        compile_kernels(request, load_scene(bundled_scene_path()), ["polygons"], events.append)
    assert [e.kind for e in events] == ["group-start", "failed"]


def test_numba_cache_saves_wait_for_the_lock(tmp_path):
    from numba.core.caching import IndexDataCacheFile

    serialise_cache_writes()
    serialise_cache_writes()  # a second call wraps nothing again
    cache_file = IndexDataCacheFile(str(tmp_path), "kernel", "stamp")
    with open(tmp_path / LOCK_NAME, "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # as another process saving meanwhile
        saver = threading.Thread(target=cache_file.save, args=(("sig",), {"code": 1}))
        saver.start()
        saver.join(timeout=0.5)
        assert saver.is_alive()  # waiting for the lock
        assert not (tmp_path / "kernel.nbi").exists()
    saver.join(timeout=30)
    assert not saver.is_alive()
    assert cache_file.load(("sig",)) == {"code": 1}


def test_the_display_shows_each_group_finished_and_the_total():
    out = io.StringIO()
    display = cli_compile.ProgressDisplay(out, ["polygons", "sky", CHECK])
    with display:
        for ev in [Progress("polygons", "group-start"), Progress("sky", "group-start"),
                   Progress("polygons", "kernel-start", "channel_worker.pipeline.visibility._v.visibility_kernel"),
                   Progress("polygons", "kernel-start", "channel_worker.pipeline.resolve._r.box_subarea"),
                   Progress("polygons", "kernel-end", "channel_worker.pipeline.resolve._r.box_subarea", 9.0),
                   Progress("polygons", "kernel-end", "channel_worker.pipeline.visibility._v.visibility_kernel", 12.0),
                   Progress("polygons", "group-end", seconds=12.5, kernels=2),
                   Progress("sky", "group-end", seconds=1.0, kernels=0),
                   Progress(CHECK, "group-start"), Progress(CHECK, "group-end", seconds=0.2, kernels=0)]:
            display.put(ev)
    lines = [line.removeprefix("ig compile:  ") for line in out.getvalue().splitlines()]
    assert lines[0] == "[1/3] polygons (geometry, binning, visibility, shading): 2 kernels compiled in 12.5 s"
    assert lines[1].startswith("[2/3] sky (") and lines[1].endswith("every kernel loaded from the cache, 1.0 s")
    assert lines[2] == "[3/3] a frame as a worker renders it: every kernel loaded from the cache, 0.2 s"
    assert display.kernels_compiled() == 2
    assert cli_compile._short("channel_worker.pipeline.resolve._resolve_kernels.box_subarea") == \
        "_resolve_kernels.box_subarea"


def test_jobs_must_be_a_whole_number_of_processes():
    parser = argparse.ArgumentParser()
    cli_compile.add_arguments(parser)
    assert parser.parse_args(["--jobs", "3"]).jobs == 3
    assert parser.parse_args([]).jobs >= 1
    assert parser.parse_args(["--jobs", "1024"]).jobs == cli_compile.MAX_JOBS == 1024
    for bad in ("0", "-1", "two", "1025", "999999"):
        with pytest.raises(SystemExit):
            parser.parse_args(["--jobs", bad])


def test_a_compile_is_remembered_only_for_the_sources_numba_keyed_it_by(tmp_path, monkeypatch):
    # numba keys its entries by the sources' paths and time stamps: a clone elsewhere, or the
    # same sources written again, compiles afresh, so the marker must not claim otherwise.
    from channel_worker import compile_jobs
    from channel_worker.pipeline import kernel_cache

    monkeypatch.setenv("IG_CACHE_DIR", str(tmp_path / "cache"))
    request = CompileRequest(str(bundled_scene_path()), RenderOptions(), ChannelSpec("c", 8, 6, -30, 30, -20, 20))
    kernel_cache.kernel_cache_dir().mkdir(parents=True)
    assert not compile_jobs.compiled_before(request)
    compile_jobs.mark_compiled(request, 30)
    assert compile_jobs.compiled_before(request)
    monkeypatch.setattr(kernel_cache, "sources_stamp", lambda: "another clone")
    assert not compile_jobs.compiled_before(request)


def test_a_rig_that_follows_a_cigi_host_compiles_the_atmosphere_for_a_scene_without_one():
    from channel_worker.compile_jobs import hosted

    flat = load_scene(bundled_scene_path())  # polygons only: no haze, fog or clouds of its own
    tiny = ChannelSpec("compile", 8, 6, -30.0, 30.0, -22.5, 22.5)
    plain = CompileRequest(str(bundled_scene_path()), RenderOptions(), tiny)
    cigi = dataclasses.replace(plain, cigi=True)
    assert hosted(flat, plain) is flat and plan(hosted(flat, plain), RenderOptions(), 2) == []
    weather = hosted(flat, cigi)
    assert weather.haze is not None and weather.fog is not None and weather.clouds is not None
    assert plan(weather, RenderOptions(), 2) == ["polygons", "sky"]


def test_compile_and_worker_take_a_bundled_scenes_name_as_render_and_demo_do():
    # `ig compile --scene airfield-terrain` said "cannot read: No such file or directory".
    from channel_worker.data import SCENES, bundled_or_path
    from channel_worker.pipeline.scene.load import demo_scene_path

    assert Path(bundled_or_path("airfield-terrain")) == demo_scene_path()
    assert Path(bundled_or_path("airfield")) == bundled_scene_path()
    assert bundled_or_path("some/scene.json") == "some/scene.json"
    assert bundled_or_path(None) is None
    for name in SCENES:
        assert Path(bundled_or_path(name)).is_file()
    parser = argparse.ArgumentParser()
    cli_compile.add_arguments(parser)
    assert "airfield-terrain" in parser.format_help()
