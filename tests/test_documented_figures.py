"""The figures the documentation quotes from a benchmark's output, checked by running the benchmark
as a user would (``PYTHONPATH=. python benchmarks/<name>.py``) and finding what it printed in the
documents: every Markdown table row it prints in the document that holds its tables, and each line
a document quotes, number for number. Seeded simulations only: a timing is quoted from a benchmark
too, but no two runs print the same one. The road validation's campaign is the demo's, which the
simulated bench runs in real time, so its dwells differ a little from run to run: three runs printed
figures up to 4.6 % apart (a per-octave error of 0.605 and 0.633 N; the rest within 1.2 %), so a
number may differ from the document's by 10 % or two units of its last printed digit: a stale
document (a band of 2.47 N where the command prints 3.82) still fails. Figures a test measures are
checked by that test (:func:`tests.documented.assert_documented`)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.documented import ROOT


@dataclass(frozen=True)
class DocumentedRun:
    """A benchmark, its arguments (``{tmp}``: a temporary folder, for what it writes), the document
    holding the tables it prints, and the prefixes of printed lines whose rest a document quotes
    (prefix -> document)."""

    script: str
    arguments: tuple[str, ...]
    tables_in: str
    quoted: dict[str, str]


RUNS = (
    DocumentedRun(
        "benchmarks/road_validation.py",
        ("--figures", "{tmp}"),  # not over the documents' own figures
        "docs/compensate.md",
        {"summary (README.md): ": "README.md", "model-compensated error: ": "docs/compensate.md"},
    ),
)


#: Relative difference allowed between a printed number and the document's (see the docstring).
RELATIVE_TOLERANCE = 0.10
NUMBER = re.compile(r"-?\d+(?:\.(\d+))?")


def _words_and_numbers(text: str) -> tuple[str, list[tuple[float, int]]]:
    """The text with each number replaced by ``#``, and the numbers with their printed decimals."""
    numbers = [(float(m.group(0)), len(m.group(1) or "")) for m in NUMBER.finditer(text)]
    return NUMBER.sub("#", re.sub(r"\s+", " ", text)), numbers


def _agrees(printed: str, documented: str) -> bool:
    """The same words, and each number within the tolerance of the document's."""
    words, numbers = _words_and_numbers(printed)
    doc_words, doc_numbers = _words_and_numbers(documented)
    return words == doc_words and all(
        abs(value - doc) <= max(RELATIVE_TOLERANCE * abs(doc), 2 * 10.0**-decimals)
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


def _quoted(document: str, printed: str) -> bool:
    """Some stretch of ``document`` says ``printed``, its numbers within the tolerance."""
    words, _ = _words_and_numbers(printed)
    pattern = re.escape(words).replace("\\#", NUMBER.pattern)
    text = re.sub(r"\s+", " ", document)
    return any(_agrees(printed, m.group(0)) for m in re.finditer(pattern, text))


@pytest.mark.validation
@pytest.mark.parametrize("run", RUNS, ids=[Path(r.script).stem for r in RUNS])
def test_the_documents_quote_what_the_benchmark_prints(run: DocumentedRun, tmp_path):
    arguments = [argument.format(tmp=tmp_path) for argument in run.arguments]
    printed = subprocess.run(
        [sys.executable, run.script, *arguments],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=900,
        check=True,
    ).stdout.splitlines()
    rows = [line for line in printed if line.startswith("| ") and not line.startswith("| road |")]
    assert len(rows) >= 6, printed
    documented = {}
    for line in (ROOT / run.tables_in).read_text(encoding="utf-8").splitlines():
        if line.startswith("| "):
            documented.setdefault(_key(line), []).append(line)
    differing = [r for r in rows if not any(_agrees(r, d) for d in documented.get(_key(r), []))]
    assert not differing, f"{run.tables_in} should say (rerun {run.script}): {differing}"
    for prefix, quoted_in in run.quoted.items():
        lines = [line.removeprefix(prefix) for line in printed if line.startswith(prefix)]
        assert len(lines) == 1, (prefix, printed)
        document = (ROOT / quoted_in).read_text(encoding="utf-8")
        assert _quoted(document, lines[0]), f"{quoted_in} should say {lines[0]!r} (rerun {run.script})"
