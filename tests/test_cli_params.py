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


def test_a_parameter_in_another_error_becomes_the_flag_too() -> None:
    """Errors other than InputError (here the fold split's IdentificationError) name the
    parameter in backquotes; the CLI shows the flag, keeping the class, exit code and
    attributes; a message without one is the error itself."""
    from rfsw_plan.exceptions import IdentificationError, InfeasibleError

    exc = IdentificationError("m.csv: 2 distinct poses cannot be split into 3 folds (use "
                              "`folds` 2 or measure more poses)")
    shown = as_flag_error(exc)
    assert type(shown) is IdentificationError and shown.exit_code == exc.exit_code
    assert str(shown) == ("m.csv: 2 distinct poses cannot be split into 3 folds (use --folds 2 "
                          "or measure more poses)")
    inf = InfeasibleError("`add` j2: outside", 4, "range", -1.0)
    out = as_flag_error(inf)
    assert (str(out), out.exit_code, out.waypoint, out.margin) == ("--add j2: outside", 3, 4,
                                                                   -1.0)
    plain = IdentificationError("too few samples")
    assert as_flag_error(plain) is plain


def test_a_calibrate_error_names_the_parameter_and_the_cli_the_flag(capsys) -> None:
    from rfsw_plan.validation.calibrate import CalibrationRequest

    with pytest.raises(InputError) as err:
        CalibrationRequest("zk500", data=()).check()
    assert str(err.value) == "data: no training file (expected one or more in `data`)"
    assert str(as_flag_error(err.value)) == \
        "--data: no training file (expected one or more in --data)"
