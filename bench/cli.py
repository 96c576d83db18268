"""The ``wfsbench`` command line."""

from __future__ import annotations

import argparse
import sys


def _demo(args: argparse.Namespace) -> int:
    from bench.demo import run_demo

    for line in run_demo(seed=args.seed):
        print(line)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wfsbench", description="Wheel force sensor test bench")
    commands = parser.add_subparsers(dest="command", required=True)
    demo = commands.add_parser("demo", help="run the paper's shaker campaign on the simulated bench")
    demo.add_argument("--seed", type=int, default=1, help="noise seed of the simulated sensors")
    demo.set_defaults(handler=_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.handler(args)


if __name__ == "__main__":
    sys.exit(main())
