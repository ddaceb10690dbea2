"""``tryon`` command line: a thin layer over the package's functions.

Each command is a module with ``add_parser(subparsers)``; the parser's ``func`` runs it and returns the
exit code. A ``CliError`` (a mistake the user can fix) is printed as one line, without a traceback.
"""

from __future__ import annotations

import argparse
import sys

from tryon import __version__
from tryon.cli import bench, fit, fit_table, ingest, serve, warmup
from tryon.cli.common import CliError

COMMANDS = [serve, ingest, fit, fit_table, bench, warmup]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tryon", description="Virtual try-on service")
    parser.add_argument("--version", action="version", version=f"tryon {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"tryon {args.command}: {exc}", file=sys.stderr)
        return exc.code


if __name__ == "__main__":
    sys.exit(main())
