"""The layers of docs/architecture.md hold at run time too: the host process never loads the
renderer (numba), the pipeline's imports have no circle, and the kernel cache is keyed by the
pipeline's sources."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _python(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args, "-c", code], capture_output=True, text=True, cwd=ROOT,
                          timeout=120, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


def test_ig_host_and_everything_the_host_runs_import_no_numba():
    code = ("import sys\n"
            "from services import cli\n"
            "cli.build_parser('host').parse_args(['host'])\n"
            "import host_sim.cli_host, host_sim.server, host_sim.publisher, host_sim.controlled\n"
            "import host_sim.flight, host_sim.flight_model, host_sim.replay, host_sim.inputs\n"
            "import host_sim.inputs.can_bus, host_sim.inputs.serial_panel, host_sim.inputs.can_log\n"
            "heavy = sorted(m for m in ('numba', 'llvmlite', 'OpenImageIO', 'channel_worker') if m in sys.modules)\n"
            "print(heavy)\n")
    done = _python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_the_dispatcher_loads_only_the_subcommand_it_runs():
    done = _python("import sys\nfrom services import cli\ncli.build_parser('compositor')\n"
                   "print('channel_worker' in sys.modules, 'host_sim' in sys.modules)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False False"


def test_the_kernel_cache_is_keyed_by_every_pipeline_source(tmp_path, monkeypatch):
    from channel_worker.pipeline import kernel_cache

    copy = tmp_path / "pipeline"
    (copy / "fog").mkdir(parents=True)
    (copy / "render.py").write_text("a = 1\n")
    (copy / "fog" / "fog.py").write_text("b = 2\n")
    monkeypatch.setattr(kernel_cache, "_PIPELINE", copy)
    monkeypatch.setenv("IG_CACHE_DIR", str(tmp_path / "cache"))
    key = kernel_cache.sources_key()
    assert kernel_cache.kernel_cache_dir() == tmp_path / "cache" / "numba" / key
    (copy / "fog" / "fog.py").write_text("b = 3\n")  # a helper that kernels inline, in a subpackage
    assert kernel_cache.sources_key() != key
    (copy / "fog" / "fog.py").write_text("b = 2\n")
    assert kernel_cache.sources_key() == key
    kept = kernel_cache.kernel_cache_dir()
    stale = kept.parent / "0123456789abcdef"
    for d in (kept, stale):
        d.mkdir(parents=True)
    assert kernel_cache.prune(kept) == [stale]
    assert kept.is_dir() and not stale.exists()


def test_the_pipeline_points_numba_at_its_cache():
    done = _python("import os\nimport channel_worker.pipeline.render\n"
                   "from channel_worker.pipeline.kernel_cache import kernel_cache_dir\n"
                   "from numba.core import config\n"
                   "print(config.CACHE_DIR == str(kernel_cache_dir()) == os.environ['NUMBA_CACHE_DIR'])")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True"
