"""``tryon warmup``: compile (or load) every kernel a request needs into numba's disk cache, so that a
service started afterwards with the same cache (``NUMBA_CACHE_DIR``) is ready within a second or two.
The test command and the Docker image run it once; ``scripts/serve.sh`` runs it beside the ingestion."""

from __future__ import annotations

import argparse
import os


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("warmup", help="compile the simulation kernels into the on-disk cache")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tryon.api.warmup import warm_up

    seconds = warm_up()
    print(f"kernels ready in {seconds:.1f} s (cache: {os.environ.get('NUMBA_CACHE_DIR', 'numba default')})")
    return 0
