"""The figures the documentation quotes from a benchmark's output, checked by running the benchmark
as a user would (``PYTHONPATH=. python benchmarks/<name>.py``) and finding what it printed in the
documents, number for number: every Markdown table row it prints in the document that holds its
tables (matched by its label: its first cell and the cells after it without a digit), and each line
a document quotes. The benchmarks say what they print that is quoted in a ``DOCUMENTED``
(:class:`benchmarks.documented.Documented`); a number may lie from the document's by the tolerance
the benchmark states, or two units of its last printed digit (rounding). Figures a test measures are
checked by that test (:func:`tests.documented.assert_documented`)."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from dataclasses import dataclass

import pytest

from benchmarks.documented import Documented
from tests.documented import ROOT

BENCHMARKS = ROOT / "benchmarks"


#: A benchmark's declaration, annotated or not.
DECLARATION = re.compile(r"^DOCUMENTED\b[^=\n]*=\s*Documented\(", re.M)


def _documented_names() -> list[str]:
    """The benchmarks that declare a ``DOCUMENTED`` (found by its text: nothing is imported to
    collect the tests)."""
    return [
        path.stem
        for path in sorted(BENCHMARKS.glob("*.py"))
        if DECLARATION.search(path.read_text(encoding="utf-8"))
    ]


def _declared(name: str) -> Documented:
    return importlib.import_module(f"benchmarks.{name}").DOCUMENTED


def _data_rows(lines: list[str]) -> list[str]:
    """The rows of the Markdown tables among ``lines``: neither a header (the row above a ``|---``
    line) nor a separator."""
    rows = []
    for i, line in enumerate(lines):
        below = lines[i + 1] if i + 1 < len(lines) else ""
        if line.startswith("| ") and not below.startswith("|---"):
            rows.append(line)
    return rows


#: A number as the benchmarks print it: sign, digits, decimals, an exponent (``3.7e-4`` is one).
NUMBER = re.compile(r"-?\d+(?:\.(\d+))?(?:e([-+]?\d+))?")
#: What follows a share in percent: ``%``, or the rest of a range that ends in it (``99.9-100.0 %``).
PERCENT_AFTER = re.compile(r" ?(?:-\d+(?:\.\d+)? ?)?%")
#: What stands for a number in a text's words (a character no text holds).
PLACE = "\x01"


@dataclass(frozen=True)
class Figure:
    """A number read from a text: its ``value``, the ``unit`` of its last printed digit (0 for a
    whole number, compared exactly), and whether it is a ``percent`` (a ``%`` follows it)."""

    value: float
    unit: float
    percent: bool


def _words_and_numbers(text: str) -> tuple[str, list[Figure]]:
    """The text with each number replaced by :data:`PLACE` (runs of spaces as one), and its numbers."""
    text = re.sub(r"\s+", " ", text)
    figures = []
    for m in NUMBER.finditer(text):
        decimals, exponent = m.group(1), int(m.group(2) or 0)
        unit = 0.0 if decimals is None and m.group(2) is None else 10.0 ** (exponent - len(decimals or ""))
        figures.append(Figure(float(m.group(0)), unit, bool(PERCENT_AFTER.match(text, m.end()))))
    return NUMBER.sub(PLACE, text), figures


def _agrees(printed: str, documented: str, run: Documented) -> bool:
    """The same words, and each number the document's: a whole number exactly, a share in percent
    within ``run.percent_points``, any other within ``run.relative_tolerance`` of the document's or
    one unit of the coarser last printed digit (rounding)."""
    words, numbers = _words_and_numbers(printed)
    doc_words, doc_numbers = _words_and_numbers(documented)
    if words != doc_words:
        return False
    for figure, doc in zip(numbers, doc_numbers, strict=True):
        if figure.percent:
            allowed = max(run.percent_points, figure.unit, doc.unit)
        elif figure.unit == 0 and doc.unit == 0:
            allowed = run.relative_tolerance * abs(doc.value)
        else:
            allowed = max(run.relative_tolerance * abs(doc.value), figure.unit, doc.unit)
        if abs(figure.value - doc.value) > allowed * (1 + 1e-9):
            return False
    return True


def _key(row: str) -> tuple[str, ...]:
    """A table row's label: its first cell and the cells after it that hold no digit."""
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    label = [cells[0]]
    for cell in cells[1:]:
        if re.search(r"\d", cell):
            break
        label.append(cell)
    return tuple(label)


def _quoted(document: str, printed: str, run: Documented) -> bool:
    """Some stretch of ``document`` says ``printed``, its numbers as :func:`_agrees` takes them."""
    words, _ = _words_and_numbers(printed)
    pattern = re.escape(words).replace(PLACE, NUMBER.pattern)
    text = re.sub(r"\s+", " ", document)
    return any(_agrees(printed, m.group(0), run) for m in re.finditer(pattern, text))


def test_numbers_are_read_as_the_benchmarks_print_them():
    """An exponent is part of its number; a whole number is compared exactly; a share in percent by
    percentage points; a range's second bound is a number of its own (its sign on both sides)."""
    exact = Documented()
    assert _agrees("flat to 3.7e-4", "flat to 3.7e-4", exact)
    assert not _agrees("flat to 3.7e-6", "flat to 3.7e-4", exact)
    assert not _agrees("Model 4", "Model 2", Documented(relative_tolerance=0.10))
    assert _agrees("0.46-1.13 N", "0.46-1.14 N", exact)  # rounding: one unit of the last digit
    assert not _agrees("0.46-1.16 N", "0.46-1.14 N", exact)
    shares = Documented(relative_tolerance=0.10, percent_points=1.0)
    assert _agrees("99.9-100.0 %", "100.0-100.0 %", shares)
    assert not _agrees("90.0 %", "100.0 %", shares)
    assert not _agrees("90.0-100.0 %", "100.0-100.0 %", shares)  # the range's first bound is a share too
    assert _agrees("a # sign and 2 N", "a # sign and 2 N", exact)
    assert _quoted("It says\n0.46-1.13 N rms, then more.", "0.46-1.13 N rms", exact)


def test_every_declaration_is_found_and_names_documents_that_exist():
    names = _documented_names()
    assert "road_validation" in names
    for name in names:
        run = _declared(name)
        for document in (run.tables_in, *run.quoted.values()):
            assert document is None or (ROOT / document).is_file(), (name, document)


@pytest.mark.validation
@pytest.mark.parametrize("name", _documented_names())
def test_the_documents_quote_what_the_benchmark_prints(name: str, tmp_path):
    run = _declared(name)
    script = f"benchmarks/{name}.py"
    arguments = [argument.format(tmp=tmp_path) for argument in run.arguments]
    done = subprocess.run(
        [sys.executable, script, *arguments],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=1800,
        check=False,
    )
    assert done.returncode == 0, f"{script} failed ({done.returncode}): {done.stderr[-2000:]}"
    printed = done.stdout.splitlines()
    if run.tables_in is not None:
        rows = _data_rows(printed)
        assert rows, f"{script} printed no table row"
        documented: dict[tuple[str, ...], list[str]] = {}
        for line in _data_rows((ROOT / run.tables_in).read_text(encoding="utf-8").splitlines()):
            documented.setdefault(_key(line), []).append(line)
        differing = [r for r in rows if not any(_agrees(r, d, run) for d in documented.get(_key(r), []))]
        assert not differing, f"{run.tables_in} should say (rerun {script}): {differing}"
    for prefix, quoted_in in run.quoted.items():
        lines = [line.removeprefix(prefix) for line in printed if line.startswith(prefix)]
        assert len(lines) == 1, (prefix, printed)
        document = (ROOT / quoted_in).read_text(encoding="utf-8")
        assert _quoted(document, lines[0], run), f"{quoted_in} should say {lines[0]!r} (rerun {script})"
