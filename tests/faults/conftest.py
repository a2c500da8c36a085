"""The fault suite's shared fixture: the render kernels, compiled (or loaded) once for every worker."""

from __future__ import annotations

import subprocess
import sys

# Loaded now, at a shallow stack: hypothesis's pytest plugin imports it in its terminal summary,
# where Python 3.11.7's parser failed with "SystemError: AST constructor recursion depth
# mismatch" after this suite's failures (CPython gh-106905), losing the summary.
import hypothesis.internal.observability  # noqa: F401
import pytest

from .harness import ROOT, SCENE, env, write_rig


@pytest.fixture(scope="session")
def kernels(tmp_path_factory):
    """`ig compile` for the suite's tiny rig and scene (seconds from a warm cache, about 30 on a
    cold one): every worker started afterwards loads the kernels instead of compiling them."""
    tmp = tmp_path_factory.mktemp("compile")
    write_rig(tmp / "rig.toml")
    proc = subprocess.run([sys.executable, "-m", "services.cli", "compile", "--rig", str(tmp / "rig.toml"),
                           "--scene", str(SCENE)], capture_output=True, text=True, env=env(), cwd=ROOT,
                          timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr

