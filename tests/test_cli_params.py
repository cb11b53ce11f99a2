"""The one table from library parameters to flags (rfsw_plan/cli/params.py): library jobs name
their parameters, the CLI shows the flags the user typed."""

from __future__ import annotations

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.cli.params import PARAMETER_FLAGS, as_flag_error
from rfsw_plan.exceptions import InputError
from rfsw_plan.placement.job import PlaceRequest


def test_a_library_error_names_the_parameter_and_the_cli_the_flag(capsys) -> None:
    with pytest.raises(InputError) as err:
        PlaceRequest("zk500_table6_seam", candidates=0).check()
    assert str(err.value) == "candidates: got 0 (expected >= 1)"
    assert main(["place", "zk500_table6_seam", "--candidates", "0"]) == 2
    assert capsys.readouterr().err.strip() == \
        "rfsw-plan place: error: --candidates: got 0 (expected >= 1)"


def test_backquoted_parameters_in_a_message_become_flags() -> None:
    exc = InputError("base_height", "", "the region already gives heights z0,z1",
                     "the height either in `region` or as `base_height`")
    shown = as_flag_error(exc)
    assert str(shown) == ("--robot-base-height: the region already gives heights z0,z1 "
                          "(expected the height either in --region or as --robot-base-height)")
    assert as_flag_error(InputError("problem.toml", "seam", "`not_a_parameter`")) is not None
    assert str(as_flag_error(InputError("f.csv", "row 2", "bad `x`"))) == "f.csv: row 2: bad `x`"


def test_every_flag_of_the_table_is_an_option_of_some_command() -> None:
    from rfsw_plan.cli.main import build_parser

    parser, _ = build_parser()
    subs = parser._subparsers._group_actions[0].choices.values()  # type: ignore[union-attr]
    text = " ".join(a for sub in subs
                    for act in sub._actions for a in act.option_strings)
    missing = [f for f in PARAMETER_FLAGS.values() if f not in text.split()]
    assert not missing, missing
