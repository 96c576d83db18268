"""``--meta KEY=VALUE``: test metadata given on the command line (docs/cli.md), for the commands that
write a campaign (``run``, ``demo``, ``import-csv``).

The option collects the fields given into one mapping (``args.meta``, key -> text); each is checked
as it is parsed (:func:`sequences.metadata.parse_assignment`), so a bad key or date is a command-line
error (exit code 3, the usage printed). The check is imported only when the option is given:
``--help`` stays light (``tests/test_cli_imports.py``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

META_HELP = (
    "test metadata recorded with the campaign, repeatable: bench_id, sensor_serial,"
    " sensor_calibration_date (YYYY-MM-DD), tyre_make, tyre_size, tyre_id, operator, notes;"
    " wins over the [metadata] of {over} (docs/configuration.md)"
)


class _MetaAction(argparse.Action):
    """Adds one ``KEY=VALUE`` to the namespace's mapping; a refused one is a usage error."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[object] | None,
        option_string: str | None = None,
    ) -> None:
        from sequences.metadata import parse_assignment

        try:
            key, value = parse_assignment(str(values))
        except ValueError as exc:
            parser.error(f"argument --meta: {exc}")
        setattr(namespace, self.dest, {**(getattr(namespace, self.dest) or {}), key: value})


def add_meta_option(parser: argparse.ArgumentParser, over: str) -> None:
    """``--meta KEY=VALUE`` on ``parser``; ``over``: whose ``[metadata]`` it wins over, for the help."""
    parser.add_argument(
        "--meta", action=_MetaAction, default={}, metavar="KEY=VALUE", help=META_HELP.format(over=over)
    )
