"""What the documents quote from a benchmark's output, declared beside the benchmark.

A benchmark whose printed figures a document quotes (seeded simulations and counts, never a timing:
no two runs print the same one) declares them in a module-level ``DOCUMENTED``
(:class:`Documented`); ``tests/test_documented_figures.py`` (validation tier) runs each such
benchmark as a user would, ``PYTHONPATH=. python benchmarks/<name>.py ARGUMENTS``, and finds what it
printed in the documents, number for number."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Documented:
    """``arguments``: the command line's arguments (``{tmp}`` becomes a temporary folder, for what
    the benchmark writes); ``tables_in``: the document that holds every Markdown table row the
    benchmark prints (``None``: its tables are not quoted); ``quoted``: printed lines a document
    quotes, by the prefix that marks them (the rest of the line is quoted) and the document's path
    from the repository's root; ``relative_tolerance``: how far a printed number may lie from the
    document's, for a benchmark whose figures vary between runs (say why beside it)."""

    arguments: tuple[str, ...] = ()
    tables_in: str | None = None
    quoted: dict[str, str] = field(default_factory=dict)
    relative_tolerance: float = 0.0
    percent_points: float = 0.0
