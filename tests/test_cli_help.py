"""Every ``rfsw-plan`` subcommand answers ``--help`` with its usage and exit code 0."""

from __future__ import annotations

import pytest

from rfsw_plan.cli.main import build_parser, main

COMMANDS = ("robots", "predict", "identify", "deviation", "plan", "simulate-campaign",
            "validate", "compare", "design-campaign")


def test_the_listed_commands_are_the_discovered_ones() -> None:
    _, commands = build_parser()
    assert set(COMMANDS) <= set(commands), sorted(set(COMMANDS) - set(commands))


@pytest.mark.parametrize("argv", [["--help"], *([c, "--help"] for c in COMMANDS)],
                         ids=lambda a: " ".join(a))
def test_help_exits_zero(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out.startswith(f"usage: rfsw-plan {argv[0] if len(argv) > 1 else ''}".rstrip())
    assert "--help" in out
    assert err == ""
