"""A flag is made one way (:func:`bench.analysis.flags.flag`, with its code), and every code is
documented: a ``FLAG`` line written by hand anywhere in the product would reach the text without a
code, so none may be."""

from __future__ import annotations

import ast
import pickle
import re
from pathlib import Path

from bench.analysis.campaign import AnalysisKind, RunAnalysis
from bench.analysis.flags import Flag, FlagCode, FlagLine, flag, flags_of
from bench.app.analysis_record import AnalysisRecord, parse_record, record_text

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = ("bench", "drivers", "sequences", "simulators")


def _string_parts(tree: ast.AST) -> list[tuple[int, str]]:
    """Every literal text of a module with its line: strings and the literal parts of f-strings."""
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
    ]


def test_no_product_module_writes_a_flag_line_by_hand():
    by_hand = [
        f"{path.relative_to(ROOT)}:{line}"
        for folder in PRODUCT
        for path in sorted((ROOT / folder).rglob("*.py"))
        for line, text in _string_parts(ast.parse(path.read_text(encoding="utf-8")))
        if re.match(r"FLAG\b", text) and path.name != "flags.py"
    ]
    assert by_hand == []


def test_every_code_is_documented_and_every_documented_code_is_one():
    text = (ROOT / "docs" / "analysis-json.md").read_text(encoding="utf-8")
    section = text[text.index("## Flag codes") : text.index("## `runs[]`")]
    documented = re.findall(r"^\| `([a-z_]+)` \|", section, flags=re.MULTILINE)
    assert documented == [str(code) for code in FlagCode]


def test_a_flag_line_reads_as_its_text_and_carries_its_code():
    line = flag(FlagCode.REJECTED, "rejected: 12 Hz clipped")
    assert line == "FLAG rejected: 12 Hz clipped" and isinstance(line, str)
    by_hand = "FLAG written by hand"  # no code: not a flag of the analysis
    assert flags_of(["a line", line, by_hand]) == (Flag(FlagCode.REJECTED, "rejected: 12 Hz clipped"),)


def test_a_flag_line_crosses_a_process_as_it_is():
    """The post-run analysis sends its lines from its own process: pickled, a flag line keeps its code."""
    line = flag(FlagCode.NOT_SETTLED, "not settled: 12 Hz")
    back = pickle.loads(pickle.dumps(line))
    assert back == line and isinstance(back, FlagLine) and back.flag == line.flag


def test_the_flags_survive_the_record():
    lines = ("m_comp 4.2 kg", flag(FlagCode.FREE_RUN, "free run: a misfit"))
    outcome = RunAnalysis("r", "free_run", AnalysisKind.PLATE_MASS, lines, {}, flags=flags_of(lines))
    back = parse_record(record_text(AnalysisRecord(outcome, {}, 0, "test", "0" * 64))).outcome
    assert back == outcome and not isinstance(back.lines[1], FlagLine)
    assert back.flags == (Flag(FlagCode.FREE_RUN, "free run: a misfit"),)


def test_a_failed_analysis_is_flagged_with_its_code():
    failed = RunAnalysis.failed("r", "sweep", "no sweep recorded")
    assert failed.flags == (Flag(FlagCode.ANALYSIS_FAILED, "analysis failed: no sweep recorded"),)
    assert failed.lines == ("FLAG analysis failed: no sweep recorded",)
