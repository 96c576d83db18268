"""Figures the documentation quotes, checked against the test that measures them: a test that
prints a figure also asserts that the document quoting it says the same, so a figure in the docs
is always the one a command in the repository prints."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def assert_documented(document: str, text: str) -> None:
    """``text`` appears in ``document`` (a path from the repository's root), line breaks and runs of
    spaces taken as one space: the figure the test just measured is the one the document quotes."""
    words = re.sub(r"\s+", " ", (ROOT / document).read_text(encoding="utf-8"))
    assert text in words, f"{document} should say {text!r}: the test measured it (update the document)"
