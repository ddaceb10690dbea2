"""``tryon bench``: measure speed and accuracy on this machine (see ``tryon.bench``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from tryon.cli.common import CliError, writable_dir
from tryon.sim.settings import SimSettings

# the most substeps ``--substeps`` takes (as the API's settings)
MAX_SUBSTEPS = 16


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="benchmark: paper tables, run time vs error, peers, stability, scaling")
    p.add_argument("--quick", action="store_true", help="small version (under two minutes)")
    p.add_argument("--stress", action="store_true", help="run the long stability stress test")
    p.add_argument("--out", type=Path, default=Path("bench-results"), help="output directory (default bench-results/)")
    p.add_argument("--only", nargs="+", metavar="SECTION", default=None,
                   help="run only these sections (table1 table2 table3 fit poses pareto simplify peers stability scaling)")
    p.add_argument("--substeps", type=int, default=None, metavar="N",
                   help=f"fit section: N substeps per step, one spring pass each (default {SimSettings().substeps}), "
                        f"to see what fewer cost in accuracy; 1 to {MAX_SUBSTEPS}")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tryon.bench import run_bench, sections

    known = [name for name, _, _ in sections()]
    unknown = [name for name in args.only or () if name not in known]
    if unknown:
        raise CliError(f"unknown section {', '.join(map(repr, unknown))} for --only: choose from {' '.join(known)}")
    if args.substeps is not None and not 1 <= args.substeps <= MAX_SUBSTEPS:
        raise CliError(f"--substeps must be 1 to {MAX_SUBSTEPS}, got {args.substeps}")
    writable_dir(args.out, "--out")  # before the run, not after minutes of it
    report, code = run_bench(args.out, quick=args.quick, stress=args.stress, only=args.only,
                             substeps=args.substeps)
    for s in report["sections"]:
        for h in s["headline"]:
            print(h)
    print(f"wrote {args.out / 'bench.json'}, {args.out / 'bench.md'}"
          + ("" if code == 0 else " (some sections failed: see bench.md)"))
    return code
