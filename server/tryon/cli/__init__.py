"""``tryon`` command line: a thin layer over the package's functions.

Each command is a module with ``add_parser(subparsers)``; the parser's ``func`` runs it and returns the
exit code.
"""

from __future__ import annotations

import argparse
import sys

from tryon import __version__
from tryon.cli import bench, ingest, serve

COMMANDS = [serve, ingest, bench]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tryon", description="Virtual try-on service")
    parser.add_argument("--version", action="version", version=f"tryon {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
