"""Sequence files the tests write: a header and the hydraulics brought up, then the steps a test is
about (``[[steps]]`` tables as TOML text)."""

from __future__ import annotations


def sequence_text(name: str, steps: str, description: str = "") -> str:
    """A sequence file named ``name``: hydraulics low, then high, then ``steps``."""
    header = f'[sequence]\nname = "{name}"\n'
    if description:
        header += f'description = "{description}"\n'
    return (
        header
        + '\n[[steps]]\ntype = "hydraulics"\nlevel = "low"\n'
        + '\n[[steps]]\ntype = "hydraulics"\nlevel = "high"\n\n'
        + steps
    )
