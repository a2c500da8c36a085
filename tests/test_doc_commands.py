"""Every command block of the README and the docs runs as written from a fresh clone, or says
why the tests do not run it (issue 32).

A command block is a fenced block tagged ```sh, ```bash, ```shell or ```console, in README.md,
docs/*.md or deploy/**/*.md. Each one runs through `bash -e` in a directory laid out like a
fresh clone after `make`: the checkout's tracked top-level files and folders linked in, and a
`.venv/bin` (first on PATH) whose `python` is this interpreter and whose `ig` is this checkout's
`services.cli`, with make's install stamps in place, so that `make certs` installs nothing.
What a block writes (out/, certs/) stays in that directory. The blocks run at once, each in a
directory of its own, and each must exit 0. Of a ```console block only the `$ ` lines run (with
their `\\` continuation lines); the rest is the output it shows.

A block the tests should not run (it takes more than a few seconds, needs other machines,
hardware or programs, or runs until it is stopped) has, directly above its opening fence,

    <!-- not run by the tests: REASON -->

and its `ig` commands are only parsed, with `ig`'s own parser: their options must exist and
their values be of the right kind.

An untagged block that reads like commands (a line starting `ig COMMAND`, `make`, `python`,
`.venv/bin/...`, `docker`, ...) fails: tag it ```sh, or ```text if it is a synopsis or a
program's output. IG_DOC_BLOCKS=docs/metrics.md,README.md:222 runs marked blocks too (a file's,
or one by its file and fence line), for checking a long walkthrough by hand.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
SHELLS = {"sh", "bash", "shell", "console"}
NOT_RUN = re.compile(r"^\s*<!-- not run by the tests: (?P<reason>\S.*?) -->\s*$")
OPENING = re.compile(r"^(?P<indent> *)```(?P<lang>[\w+-]*)\s*$")
#: A line of an untagged block that is a command rather than a synopsis, output or a diagram:
#: `ig` and a subcommand (not `ig host: error: ...`), or another program a doc may name.
COMMAND = re.compile(r"^(ig [a-z][a-z-]*(\s|$)|(make|python3?|\.venv/bin/\S+|docker|kubectl|curl|candump|fgfs"
                     r"|jsbsim|systemctl|pip)(\s|$)|[A-Z_]+=\S)")
_ASKED = [item for item in os.environ.get("IG_DOC_BLOCKS", "").split(",") if item]
#: How long the blocks may take, together, before those still running are called stuck (they
#: should take seconds; a long walkthrough asked for by IG_DOC_BLOCKS may take minutes).
DEADLINE_S = 600.0 if _ASKED else 60.0


@dataclass(frozen=True)
class Block:
    """One fenced block of a Markdown file."""

    path: str  # relative to the checkout
    line: int  # of the opening fence, from 1
    lang: str
    lines: tuple[str, ...]  # without the fence's indentation
    not_run: str | None  # the marker's reason

    @property
    def where(self) -> str:
        return f"{self.path}:{self.line}"

    def script(self) -> str:
        """What bash runs: the block, or a console block's `$ ` lines."""
        if self.lang != "console":
            return "\n".join(self.lines) + "\n"
        out, continued = [], False
        for line in self.lines:
            if continued or line.startswith("$ "):
                out.append(line if continued else line[2:])
                continued = line.endswith("\\")
        return "\n".join(out) + "\n"


def doc_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "deploy").rglob("*.md"))]


def parse(path: Path) -> tuple[list[Block], list[str]]:
    """The fenced blocks of a Markdown file, and what is wrong with its fences and markers."""
    rel = path.relative_to(ROOT).as_posix()
    lines = path.read_text().split("\n")
    blocks, problems = [], []
    i = 0
    while i < len(lines):
        if not lines[i].lstrip().startswith("```"):
            if NOT_RUN.match(lines[i]) and not (i + 1 < len(lines) and (m := OPENING.match(lines[i + 1]))
                                                and m["lang"] in SHELLS):
                problems.append(f"{rel}:{i + 1}: a not-run marker that is not directly above a command block")
            i += 1
            continue
        opening = OPENING.match(lines[i])
        if opening is None:
            problems.append(f"{rel}:{i + 1}: {lines[i].strip()[:40]!r} opens no block (a closing fence "
                            "stands alone on its line)")
            i += 1
            continue
        end = i + 1
        while end < len(lines) and not lines[end].lstrip().startswith("```"):
            end += 1
        if end == len(lines) or lines[end].strip() != "```":
            problems.append(f"{rel}:{i + 1}: the block is not closed by a line of its own ```")
            i = end + 1
            continue
        indent = len(opening["indent"])
        body = tuple(line[min(indent, len(line) - len(line.lstrip(" "))):] for line in lines[i + 1:end])
        marker = NOT_RUN.match(lines[i - 1]) if i > 0 else None
        blocks.append(Block(rel, i + 1, opening["lang"], body, marker["reason"] if marker else None))
        i = end + 1
    return blocks, problems


PARSED = {path: parse(path) for path in doc_files()}
BLOCKS = [block for blocks, _ in PARSED.values() for block in blocks]
COMMAND_BLOCKS = [block for block in BLOCKS if block.lang in SHELLS]
RUN = [block for block in COMMAND_BLOCKS
       if block.not_run is None or any(block.where == item or block.path == item for item in _ASKED)]


def test_the_docs_have_command_blocks_and_run_some():
    """The walk still finds the blocks (a renamed folder or fence would leave nothing to check)."""
    assert len(COMMAND_BLOCKS) >= 10
    assert len(RUN) >= 2


def test_every_fence_opens_and_closes_on_a_line_of_its_own():
    problems = [problem for _, found in PARSED.values() for problem in found]
    assert not problems, "\n".join(problems)


def test_an_untagged_block_holds_no_commands():
    """A block of commands is tagged, so that the tests find it: ```sh (run, or marked not run),
    or ```text for a synopsis or a program's output."""
    untagged = []
    for block in BLOCKS:
        command = next((line for line in block.lines if COMMAND.match(line)), None)
        if not block.lang and command is not None:
            untagged.append(f"{block.where}: {command!r}: tag it ```sh, or ```text if it is a synopsis or output")
    assert not untagged, "\n".join(untagged)


def ig_commands(script: str) -> list[list[str]]:
    """The arguments of every `ig` command of a shell script, with the $VARIABLES it sets (and
    any other $WORD kept as it is): `ig host --rig $RIG &` -> ["host", "--rig", "deploy/..."]."""
    variables: dict[str, str] = {}
    commands = []
    for line in script.replace("\\\n", " ").splitlines():
        lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
        lexer.whitespace_split = True
        segment: list[str] = []
        for token in [*lexer, ";"]:
            if token and set(token) <= set(lexer.punctuation_chars):  # ; & && | ( ): a command ends
                while segment[:1] and segment[0] in {"do", "then", "else", "time"}:
                    segment.pop(0)
                if len(segment) == 1 and re.fullmatch(r"[A-Za-z_]\w*=.*", segment[0]):
                    name, value = segment[0].split("=", 1)
                    variables[name] = value
                elif segment[:1] == ["ig"]:
                    commands.append([re.sub(r"\$(\w+)", lambda m: variables.get(m[1], m[0]), word)
                                     for word in segment[1:]])
                segment = []
            else:
                segment.append(token)
    return commands


def test_every_ig_command_of_a_block_parses():
    """Those the tests do not run too: their options exist and their values are of the kind
    the option takes (a file they name is not read)."""
    checked, refused = 0, []
    for block in COMMAND_BLOCKS:
        for argv in ig_commands(block.script()):
            checked += 1
            err = io.StringIO()
            try:
                with contextlib.redirect_stderr(err):
                    build_parser(argv[0]).parse_args(argv)
            except SystemExit:
                refused.append(f"{block.where}: ig {shlex.join(argv)}: {err.getvalue().strip().splitlines()[-1]}")
    assert checked >= 15  # the walk still finds them
    assert not refused, "\n".join(refused)


def fresh_clone(where: Path) -> dict[str, str]:
    """Lay out a fresh clone after `make` in `where`; the environment its commands run in."""
    where.mkdir()
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, text=True, check=True)
    for name in sorted({path.split("/", 1)[0] for path in tracked.stdout.split("\0") if path}):
        (where / name).symlink_to(ROOT / name)
    bin_dir = where / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    python = shlex.quote(sys.executable)
    wrappers = {"python": f'exec {python} "$@"', "python3": f'exec {python} "$@"',
                "ig": f'exec {python} -m services.cli "$@"'}
    for name, line in wrappers.items():
        (bin_dir / name).write_text(f"#!/bin/sh\n{line}\n")
        (bin_dir / name).chmod(0o755)
    for stamp in (".installed-run", ".installed-stamp"):  # make's: the .venv is installed
        (where / ".venv" / stamp).touch()
    env = dict(os.environ)
    env.pop("MAKEFLAGS", None)
    env.pop("MAKELEVEL", None)
    env["PATH"] = f"{bin_dir}:{env['PATH']}"
    # The modules come from the checkout itself, never through the links: numba keys its cached
    # kernels by their source files' paths, and a kernel imported through a link would compile
    # afresh. PYTHONSAFEPATH keeps `python -m` from putting the clone's folder first.
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(ROOT / "proto"), *filter(None, [env.get("PYTHONPATH")])])
    env["PYTHONSAFEPATH"] = "1"
    env["PIP_NO_INDEX"] = "1"  # a block that would install something fails rather than change this venv
    return env


@dataclass
class Ran:
    returncode: int | None  # None: stopped at the deadline
    seconds: float
    output: str
    left_running: bool  # processes of the block were still there when it had ended


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def stop_group(pgid: int, *, grace_s: float = 5.0) -> None:
    """SIGTERM to every process of the group; SIGKILL to those still there after grace_s."""
    if not group_alive(pgid):
        return
    os.killpg(pgid, signal.SIGTERM)
    end = time.monotonic() + grace_s
    while group_alive(pgid) and time.monotonic() < end:
        time.sleep(0.05)
    if group_alive(pgid):
        os.killpg(pgid, signal.SIGKILL)


@pytest.fixture(scope="module")
def ran(tmp_path_factory) -> dict[str, Ran]:
    """Every block of RUN, run at once, each in a fresh clone of its own."""
    started = {}
    for block in RUN:
        folder = tmp_path_factory.mktemp("doc-blocks")
        clone = folder / "clone"
        env = fresh_clone(clone)
        (folder / "block.sh").write_text(block.script())
        with open(folder / "output.txt", "w") as log:
            proc = subprocess.Popen(["bash", "-e", str(folder / "block.sh")], cwd=clone, env=env,
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    start_new_session=True)  # a group of its own: stop_group
        started[block.where] = (proc, folder, time.monotonic())
    deadline = time.monotonic() + DEADLINE_S
    ended: dict[str, float] = {}
    while len(ended) < len(started) and time.monotonic() < deadline:
        for where, (proc, _, _) in started.items():
            if where not in ended and proc.poll() is not None:
                ended[where] = time.monotonic()
        time.sleep(0.05)
    results = {}
    for where, (proc, folder, start) in started.items():
        left_running = where in ended and group_alive(proc.pid)
        stop_group(proc.pid)  # a block past the deadline, or what it left running
        proc.wait()
        results[where] = Ran(proc.returncode if where in ended else None, ended.get(where, time.monotonic()) - start,
                             (folder / "output.txt").read_text(errors="replace"), left_running)
    return results


@pytest.mark.parametrize("block", RUN, ids=[block.where for block in RUN])
def test_the_block_runs_as_written(block, ran):
    """It exits 0 and stops everything it started."""
    result = ran[block.where]
    tail = "\n".join(result.output.splitlines()[-20:])
    assert result.returncode is not None, (
        f"{block.where} ran past {DEADLINE_S:.0f} s: mark it <!-- not run by the tests: takes N s -->\n{tail}")
    assert result.returncode == 0, f"{block.where} exited {result.returncode} after {result.seconds:.1f} s:\n{tail}"
    assert not result.left_running, f"{block.where} left processes running: stop them, and say how\n{tail}"
    print(f"{block.where}: {result.seconds:.1f} s")
