"""`ig --help` and every subcommand's --help describe their options."""

import pytest

from services.cli import build_parser, main


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
    assert "channel_name: 'bogus' is not a channel of the rig" in capsys.readouterr().err
