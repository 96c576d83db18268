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

import pytest

from benchmarks.documented import Documented
from tests.documented import ROOT

BENCHMARKS = ROOT / "benchmarks"


def _documented_names() -> list[str]:
    """The benchmarks that declare a ``DOCUMENTED`` (found by its text: nothing is imported to
    collect the tests)."""
    return [
        path.stem
        for path in sorted(BENCHMARKS.glob("*.py"))
        if "\nDOCUMENTED = Documented(" in path.read_text(encoding="utf-8")
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


NUMBER = re.compile(r"-?\d+(?:\.(\d+))?")


def _words_and_numbers(text: str) -> tuple[str, list[tuple[float, int]]]:
    """The text with each number replaced by ``#``, and the numbers with their printed decimals."""
    numbers = [(float(m.group(0)), len(m.group(1) or "")) for m in NUMBER.finditer(text)]
    return NUMBER.sub("#", re.sub(r"\s+", " ", text)), numbers


def _agrees(printed: str, documented: str, tolerance: float) -> bool:
    """The same words, and each number within ``tolerance`` (relative) of the document's, or two
    units of its last printed digit."""
    words, numbers = _words_and_numbers(printed)
    doc_words, doc_numbers = _words_and_numbers(documented)
    return words == doc_words and all(
        abs(value - doc) <= max(tolerance * abs(doc), 2 * 10.0**-decimals)
        for (value, decimals), (doc, _) in zip(numbers, doc_numbers, strict=True)
    )


def _key(row: str) -> tuple[str, ...]:
    """A table row's label: its first cell and the cells after it that hold no digit."""
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    label = [cells[0]]
    for cell in cells[1:]:
        if re.search(r"\d", cell):
            break
        label.append(cell)
    return tuple(label)


def _quoted(document: str, printed: str, tolerance: float) -> bool:
    """Some stretch of ``document`` says ``printed``, its numbers within the tolerance."""
    words, _ = _words_and_numbers(printed)
    pattern = re.escape(words).replace("\\#", NUMBER.pattern)
    text = re.sub(r"\s+", " ", document)
    return any(_agrees(printed, m.group(0), tolerance) for m in re.finditer(pattern, text))


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
    printed = subprocess.run(
        [sys.executable, script, *arguments],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=1800,
        check=True,
    ).stdout.splitlines()
    tolerance = run.relative_tolerance
    if run.tables_in is not None:
        rows = [line for line in printed if line.startswith("| ") and not line.startswith("| road |")]
        assert rows, f"{script} printed no table row"
        documented: dict[tuple[str, ...], list[str]] = {}
        for line in (ROOT / run.tables_in).read_text(encoding="utf-8").splitlines():
            if line.startswith("| "):
                documented.setdefault(_key(line), []).append(line)
        differing = [
            r for r in rows if not any(_agrees(r, d, tolerance) for d in documented.get(_key(r), []))
        ]
        assert not differing, f"{run.tables_in} should say (rerun {script}): {differing}"
    for prefix, quoted_in in run.quoted.items():
        lines = [line.removeprefix(prefix) for line in printed if line.startswith(prefix)]
        assert len(lines) == 1, (prefix, printed)
        document = (ROOT / quoted_in).read_text(encoding="utf-8")
        assert _quoted(document, lines[0], tolerance), f"{quoted_in} should say {lines[0]!r} (rerun {script})"
