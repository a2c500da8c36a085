"""`ig --help` and every subcommand's --help describe their options."""

import subprocess
import sys
from pathlib import Path

import pytest

from services.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]


def test_top_level_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("demo", "render", "host", "worker", "compositor"):
        assert cmd in out


@pytest.mark.parametrize("cmd,option", [("demo", "--rate"), ("render", "--fov-h"), ("host", "--sync-timeout"),
                                        ("worker", "--channel"), ("compositor", "--exr-every")])
def test_subcommand_help(cmd, option, capsys):
    with pytest.raises(SystemExit) as exc:
        main([cmd, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert option in out
    # every option has a help text
    sub = build_parser()._subparsers._group_actions[0].choices[cmd]
    for action in sub._actions:
        assert action.help, f"{cmd} {action.option_strings or action.dest} has no help"


def test_worker_with_unknown_channel_exits_2(capsys):
    assert main(["worker", "--channel", "bogus"]) == 2
    assert "ig worker: error: channel_name: 'bogus' is not a channel of the rig" in capsys.readouterr().err


def test_bad_rig_file_exits_2_naming_the_key(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    rig.write_text('[host]\naddress = "nowhere"\n')
    for cmd in (["host"], ["compositor"], ["worker", "--channel", "left"], ["demo"]):
        assert main([*cmd, "--rig", str(rig)]) == 2
        assert "host.address: 'nowhere' is not host:port" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["host", "--rate", "0"], ["host", "--sync-timeout", "nan"],
                                  ["demo", "--width", "0"], ["demo", "--duration", "-1"],
                                  ["compositor", "--record-per-s", "nan"], ["compositor", "--record-per-s", "-2"]])
def test_bad_numbers_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert argv[-2] in capsys.readouterr().err


def test_demo_with_an_unknown_sample_pattern_exits_2_before_starting_anything(tmp_path, capsys):
    assert main(["demo", "--samples", "7", "--out", str(tmp_path / "demo")]) == 2
    assert "samples: 7 has no pattern" in capsys.readouterr().err
    assert not (tmp_path / "demo").exists()


def test_demo_takes_a_bundled_scene_by_name(tmp_path, capsys):
    from channel_worker.pipeline.scene.load import bundled_scene_path
    from services.demo import prepare_rig

    args = build_parser("demo").parse_args(["demo", "--scene", "airfield"])
    _, scene = prepare_rig("demo", args)
    assert scene == str(bundled_scene_path())
    assert main(["demo", "--scene", "airfeild", "--out", str(tmp_path / "demo")]) == 2
    assert ("ig demo: error: --scene: 'airfeild' is neither a bundled scene (airfield-terrain, airfield) nor a file"
            in capsys.readouterr().err)
    assert not (tmp_path / "demo").exists()


def test_every_flag_of_the_readmes_commands_is_an_option_of_its_command():
    """The README's commands, in its code blocks (`ig render [SCENE | --scene NAME|FILE] ...`,
    continuation lines included) name only options their command has."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    def options_of(parser) -> dict[str, set[str]]:
        """Options by command, "terrain build" for a command's own subcommands."""
        out = {}
        for name, sub in parser._subparsers._group_actions[0].choices.items():
            out[name] = {o for a in sub._actions for o in a.option_strings}
            if sub._subparsers is not None:
                out.update({f"{name} {k}": v for k, v in options_of(sub).items()})
        return out

    options = options_of(build_parser())
    checked, unknown = 0, []
    for block in re.findall(r"```[a-z]*\n(.*?)```", text, re.S):
        command = None
        for line in block.splitlines():
            words = line.split()
            if words[:1] == ["ig"] and len(words) > 1 and words[1] in options:
                command = " ".join(words[1:3]) if " ".join(words[1:3]) in options else words[1]
            elif not line.startswith(" "):
                command = None  # a line of another program, or RENDER OPTIONS: ends the command
            if command is None:
                continue
            code = line.split("#", 1)[0]  # a shell comment is no option
            for flag in re.findall(r"(?<![\w-])--(?:\[no-\])?[a-z][a-z-]*", code):
                checked += 1
                flags = {flag.replace("[no-]", ""), flag.replace("[no-]", "no-")}
                if not flags & options[command]:
                    unknown.append(f"ig {command} {flag}")
    assert checked > 50  # the pattern still finds the README's commands
    assert not unknown, f"README.md names options its commands do not have: {unknown}"


def test_a_reader_that_goes_away_ends_the_command_without_a_traceback():
    # `ig host --replay LOG --report | head -1` printed a BrokenPipeError traceback.
    proc = subprocess.Popen([sys.executable, "-m", "services.cli", "host", "--replay",
                             str(ROOT / "host_sim" / "data" / "flights" / "circuit.igc"), "--report"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline().startswith(b"replay report:")
    proc.stdout.close()  # what head does after its line
    err = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=60) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err, err
