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


def test_command_names_are_read_from_the_modules_heads(tmp_path) -> None:
    """``rfsw-plan`` lists its commands from their sources' ``NAME`` and ``HELP`` literals,
    parsing only a module's part before its first definition: the literals a parse of the
    whole source gives, for every command module; a module that assigns them again later, or
    whose head does not parse alone, is parsed whole."""
    import importlib
    from pathlib import Path

    import rfsw_plan.cli.commands as pkg
    from rfsw_plan.cli.main import _command_specs, _literal_names, _literals_in

    for path in sorted(Path(pkg.__path__[0]).glob("[!_]*.py")):
        head = _literal_names(path)
        assert head == _literals_in(path.read_text()) and set(head) == {"NAME", "HELP"}, path
        mod = importlib.import_module(f"{pkg.__name__}.{path.stem}")
        assert (head["NAME"], head["HELP"]) == (mod.NAME, mod.HELP)
    assert len(_command_specs()) == len(list(Path(pkg.__path__[0]).glob("[!_]*.py")))
    later = tmp_path / "later.py"
    later.write_text('NAME = "a"\nHELP = "h"\n\n\ndef f():\n    pass\n\n\nNAME = "b"\n')
    assert _literal_names(later) == {"NAME": "b", "HELP": "h"}
    split = tmp_path / "split.py"  # a string that runs over the first definition's line
    split.write_text('NAME = "a"\nHELP = """h\ndef g():\n"""\n\n\ndef f():\n    pass\n')
    assert _literal_names(split) == {"NAME": "a", "HELP": "h\ndef g():\n"}


def test_the_script_ends_with_its_exit_handlers_after_freezing_the_heap(tmp_path) -> None:
    """``rfsw-plan`` (``console``) freezes the objects left at the end before it exits, so the
    interpreter's last collection skips them; the exit handlers still run (buffered output
    written, logging flushed) and the exit code is the command's."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    code = ("import atexit, gc, sys\n"
            "atexit.register(lambda: print('frozen', gc.get_freeze_count() > 0))\n"
            "from rfsw_plan.cli.main import console\n"
            "sys.argv[1:] = sys.argv[2:]\n"
            "console()\n")
    env = {**os.environ, "PYTHONPATH": str(root)}
    ok = subprocess.run([sys.executable, "-c", code, "-", "robots"], capture_output=True,
                        text=True, env=env, cwd=tmp_path, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.rstrip().endswith("frozen True") and "zk500" in ok.stdout
    bad = subprocess.run([sys.executable, "-c", code, "-", "plan", "no_such_problem"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert bad.returncode == 2 and bad.stdout.rstrip().endswith("frozen True")
    assert bad.stderr.startswith("rfsw-plan plan: error:") and "Traceback" not in bad.stderr
