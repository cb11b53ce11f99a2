"""No move or wait of a written program is shorter than its controller's interpolation cycle
(KUKA IPO 12 ms, FANUC ITP 8 ms, ABB assumed 12 ms: :attr:`ControllerFormat.cycle`), read
from the file's own text (written positions over written speeds, ``tests/_program_moves.py``),
not from the export's objects; and the minimum is what makes it so (without it the same plan's
programs have sub-cycle moves at the weld start)."""

from __future__ import annotations

from pathlib import Path

import pytest
from _program_moves import program_moves
from conftest import PROGRAM_CASES

from rfsw_plan.export.fanuc_tp import ITP_CYCLE
from rfsw_plan.export.format import get_format
from rfsw_plan.export.krl import IPO_CYCLE
from rfsw_plan.export.rapid import PATH_CYCLE

#: The written speeds and positions round (mm/s with 4 to 7 digits, mm with 4 decimals): a move
#: of a whole cycle reads back at most this share shorter.
READ_TOL = 0.02


def _main_file(out: Path, fmt: str) -> Path:
    suffix = get_format(fmt).suffix
    return next(p for p in sorted(out.iterdir()) if p.name.endswith(suffix))


def test_cycles_are_the_vendors() -> None:
    """The constants carry the cycles their sources give (KUKA 12 ms, FANUC 8 ms) and the
    stated ABB assumption."""
    assert (IPO_CYCLE, ITP_CYCLE, PATH_CYCLE) == (0.012, 0.008, 0.012)
    assert [get_format(f).cycle for f in ("krl", "fanuc_tp", "rapid", "stream")] == \
        [IPO_CYCLE, ITP_CYCLE, PATH_CYCLE, 0.0]


@pytest.mark.parametrize("problem", [c[0] for c in PROGRAM_CASES])
@pytest.mark.parametrize("fmt", ["krl", "fanuc_tp", "rapid"])
def test_no_move_or_wait_shorter_than_the_cycle(plan_with_programs, problem: str,
                                                fmt: str) -> None:
    out, _ = plan_with_programs(problem)
    path = _main_file(out, fmt)
    moves = program_moves(path)
    assert sum(m.kind == "lin" for m in moves) > 50  # the reader found the moves
    cycle = get_format(fmt).cycle
    short = [(m.kind, m.label, m.line, round(m.duration * 1e3, 2)) for m in moves
             if m.duration < cycle * (1 - READ_TOL)]
    assert not short, f"{path.name}: shorter than {cycle * 1e3:g} ms: {short[:5]}"


def test_without_the_minimum_the_weld_start_has_sub_cycle_moves(plan_with_programs,
                                                                tmp_path: Path,
                                                                monkeypatch) -> None:
    """The same plan's KRL with every format's cycle 0 has moves and holds of one 10 ms
    plan sample (the weld start's speed split), so the test above can fail."""
    from rfsw_plan.cli.main import main
    from rfsw_plan.export.krl import KrlFormat

    monkeypatch.setattr(KrlFormat, "cycle", 0.0)
    out, _ = plan_with_programs("zk500_table6_seam")
    dest = tmp_path / "nomin"
    assert main(["-q", "export", str(out), "-o", str(dest), "--format", "krl"]) == 0
    moves = program_moves(_main_file(dest, "krl"))
    assert any(m.kind == "lin" and m.duration < IPO_CYCLE for m in moves)
    assert any(m.kind == "wait" and m.duration < IPO_CYCLE for m in moves)
