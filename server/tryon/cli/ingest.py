"""``tryon ingest``: prepare garment files into the catalogue (offline), one line per garment.

    tryon ingest PATH... [--name N] [--category top|bottom|dress|auto] [--units auto|m|cm|mm|dm|in]
                 [--simplify B] [--size S] [--style ID] [--size-chart JSON] [--fabric NAME]
                 [--density KG_PER_M2] [--data-dir DIR]
    tryon ingest --catalogue garments/      # every file listed in garments/catalogue.json
    tryon ingest ... --ray [ADDRESS]        # prepared on a Ray cluster's workers (a local one by default)

``--category auto`` (the default) guesses the category from words in the file name, as the upload API
does (``tryon.garment.catalogue.guess_category``); a file whose name tells none is refused. A garment is made of
its ``--fabric`` (a catalogue.json entry's ``fabric``; default: its category's, ``garment.fabric.DEFAULT_FABRIC``)
and its masses of that fabric's density unless ``--density`` gives one. A file already in keeps its own words:
its fabric, and (once it has a style) its style, size and chart, whatever catalogue.json says, so that words
changed since (``PATCH /api/garments/{id}``) survive ``scripts/serve.sh``'s ingestion at every start.

With ``--ray`` the preparations (load, clean, simplify, springs: the costly part) run as Ray tasks, a
local Ray with every core when no ADDRESS is given, ``auto`` or ``host:port`` to join a running cluster;
the catalogue is written here, on the driver, entry by entry as each preparation comes back, exactly as a
local ingestion writes it (same ids, same arrays).

Exit status 0 if every file was ingested (or already was), 1 if any was refused (the others are still
ingested), 2 for a usage error.
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import sys
import time
from pathlib import Path

from tryon.cli.common import CliError, load_settings
from tryon.garment.fabric import DEFAULT_FABRIC, FABRICS
from tryon.garment.ingest import UNITS, GarmentError
from tryon.garment.sizes import check_labels


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ingest", help="prepare garment mesh files into the catalogue",
                       description="Prepare garment mesh files (OBJ, GLB/GLTF, PLY, STL, OFF) into the catalogue.")
    p.add_argument("paths", nargs="*", type=Path, help="garment files")
    p.add_argument("--catalogue", type=Path, metavar="DIR", help="ingest every file listed in DIR/catalogue.json")
    p.add_argument("--name", help="display name (default: the file name); only with one file")
    p.add_argument("--category", default="auto", choices=["auto", "top", "bottom", "dress"],
                   help="garment category (default auto: from words in the file name, such as shirt, skirt "
                        "or dress; a file whose name has none is refused)")
    p.add_argument("--units", default="auto", choices=list(UNITS), help="units of the file (default auto: guessed)")
    p.add_argument("--simplify", type=float, default=None, metavar="B",
                   help="simplification degree B = kept / original vertices, in (0, 1] (default 0.3)")
    p.add_argument("--size", help="size label, e.g. M")
    p.add_argument("--style", metavar="ID",
                   help="the style (product) this file is one size of: a short id such as tshirt; needs --size")
    p.add_argument("--size-chart", metavar="JSON", dest="size_chart",
                   help='the size\'s chart row, body girths in cm: \'{"chest": [92, 100], "waist": [78, 86]}\' '
                        "(chest, waist, hips; each [min, max] or one value); needs --size")
    p.add_argument("--fabric", choices=list(FABRICS), default=None,
                   help="what the garment is made of (default: its category's: "
                        + ", ".join(f"{c} {f}" for c, f in DEFAULT_FABRIC.items()) + ")")
    p.add_argument("--density", type=float, default=None,
                   help="areal density of the masses, kg/m^2 (default: the fabric's: "
                        + ", ".join(f"{f.name} {f.density:g}" for f in FABRICS.values()) + ")")
    p.add_argument("--data-dir", type=Path, help="catalogue directory (default: TRYON_DATA_DIR or ./data)")
    p.add_argument("--ray", nargs="?", const=LOCAL_RAY, default=None, metavar="ADDRESS",
                   help="prepare on a Ray cluster: no ADDRESS starts a local Ray, 'auto' or host:port joins one "
                        "(needs the extra: pip install '.[scale]')")
    p.set_defaults(func=run)


# What a JSON value is, in JSON's words (not Python's type names).
_JSON_KINDS = {dict: "an object", str: "a string", int: "a number", float: "a number", bool: "true or false",
               type(None): "null"}


# ``--ray`` without an address: start a local Ray
LOCAL_RAY = "local"


def _listing_problem(exc: Exception) -> str:
    """What is wrong with a catalogue.json, in words: the reason, not the exception's own text."""
    if isinstance(exc, json.JSONDecodeError):
        return f"it is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg.lower()})"
    if isinstance(exc, UnicodeDecodeError):
        return "it is not UTF-8 text"
    if isinstance(exc, OSError):
        return exc.strerror or "it cannot be read"
    return str(exc)  # one of _jobs' own messages


def _jobs(args: argparse.Namespace) -> list[dict]:
    """One dict per file: path and the ingest keyword arguments."""
    jobs = []
    if args.catalogue is not None:
        listing = args.catalogue / "catalogue.json"
        entries = json.loads(listing.read_text())
        if not isinstance(entries, list):
            raise ValueError(f"expected a JSON list of entries, got {_JSON_KINDS.get(type(entries), 'a value')}")
        for i, e in enumerate(entries):
            if not isinstance(e, dict) or not isinstance(e.get("file"), str):
                raise ValueError(f"entry {i} is not an object with a \"file\" name: {json.dumps(e)[:80]}")
            jobs.append(dict(path=args.catalogue / e["file"], name=e.get("name"), category=e.get("category", "top"),
                             units=e.get("units", "auto"), size=e.get("size"), style=e.get("style"),
                             chart=e.get("chart"), fabric=e.get("fabric")))
    for path in args.paths:
        jobs.append(dict(path=path, name=args.name, category=args.category, units=args.units, size=args.size,
                         style=args.style, chart=args.size_chart, fabric=args.fabric))
    for job in jobs:
        if args.simplify is not None:
            job["simplify"] = args.simplify
        if args.density is not None:
            job["density"] = args.density
    return jobs


def run(args: argparse.Namespace) -> int:
    from tryon.garment.catalogue import Catalogue

    if not args.paths and args.catalogue is None:
        print("tryon ingest: give garment files or --catalogue DIR", file=sys.stderr)
        return 2
    if args.name and len(args.paths) + (args.catalogue is not None) > 1:
        print("tryon ingest: --name only with a single file", file=sys.stderr)
        return 2
    if args.simplify is not None and not 0.0 < args.simplify <= 1.0:
        print(f"tryon ingest: --simplify must be in (0, 1], got {args.simplify}", file=sys.stderr)
        return 2
    if args.paths and (args.style or args.size_chart):
        try:  # one mistake in the flags is one usage error, not one refusal per file
            check_labels(args.style, args.size, args.size_chart)
        except GarmentError as exc:
            print(f"tryon ingest: {exc}", file=sys.stderr)
            return 2
    try:
        jobs = _jobs(args)
    except (OSError, ValueError) as exc:
        print(f"tryon ingest: cannot read {args.catalogue}/catalogue.json: {_listing_problem(exc)}", file=sys.stderr)
        return 2
    settings = load_settings()
    data_dir = args.data_dir or settings.data_dir
    try:
        catalogue = Catalogue(data_dir)
    except (OSError, sqlite3.Error) as exc:
        raise CliError(f"cannot open the catalogue in {data_dir}: {getattr(exc, 'strerror', None) or exc}") from None
    if args.ray is not None:
        return _run_on_ray(args.ray, catalogue, jobs, settings.max_faces, data_dir)
    refused = 0
    total = len(jobs)
    t_all = time.perf_counter()
    for i, job in enumerate(jobs, 1):
        path = job.pop("path")
        prefix = _prefix(i, total, path)
        print(f"{prefix} ...", end="\r", flush=True, file=sys.stderr) if sys.stderr.isatty() else None
        t0 = time.perf_counter()
        try:
            _check_path(path)
            meta, created = catalogue.ingest_with_status(path, max_faces=settings.max_faces, **job)
        except (GarmentError, OSError) as exc:
            refused += 1
            print(f"{prefix}: REFUSED: {_reason(exc)}")
            continue
        _print_entry(prefix, meta, time.perf_counter() - t0, created)
    _print_total(total, refused, data_dir, time.perf_counter() - t_all)
    return 1 if refused else 0


def _prefix(i: int, total: int, path: Path) -> str:
    return f"[{i:>{len(str(total))}}/{total}] {path.name}"


def _check_path(path: Path) -> None:
    if path.is_dir():
        raise GarmentError(f"{path} is a directory: give mesh files, or --catalogue DIR for a "
                           f"directory with a catalogue.json")
    if not path.is_file():
        raise GarmentError(f"no such file: {path}")


def _reason(exc: Exception) -> str:
    """Why a file was refused: a GarmentError's words; an OSError (unreadable file, or the catalogue could
    not be written: disk full) its system message and file."""
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}{f': {exc.filename}' if exc.filename else ''}"
    return str(exc)


def _print_entry(prefix: str, meta, seconds: float, created: bool) -> None:
    s = meta.springs
    print(
        f"{prefix}: {meta.id} {meta.name!r} {meta.category}"
        f"{' style ' + meta.style if meta.style else ''}{' ' + meta.size if meta.size else ''}, {meta.vertices} v / {meta.faces} f -> "
        f"{meta.coarse_vertices} v / {meta.coarse_faces} f (B {meta.simplification:g}), springs "
        f"{s.get('structural', 0)}/{s.get('shear', 0)}/{s.get('bending', 0)}, units {meta.units}"
        f"{' (guessed)' if meta.units_guessed else ''}, {meta.fabric or 'fabric unknown'} "
        f"{(meta.density or 0) * 1000:.0f} g/m2, "
        f"{seconds * 1000:.0f} ms"
        f"{'' if created else ' (cached)'}"
    )
    for note in meta.notes:
        if created:
            print(f"{' ' * (len(prefix) + 2)}note: {note}")


def _print_total(total: int, refused: int, data_dir: Path, seconds: float) -> None:
    print(f"{total - refused} of {total} garments in {data_dir} ({seconds:.2f} s)"
          + (f"; {refused} refused" if refused else ""))


def _run_on_ray(address: str, catalogue, jobs: list[dict], max_faces: int, data_dir: Path) -> int:
    """``--ray``: plan every file here, prepare the new ones as Ray tasks, add each to the catalogue here as
    it comes back (see the module docstring). Lines come in the order the preparations finish."""
    from tryon.garment.catalogue import prepare_model
    from tryon.scale.ray_jobs import RayUnavailable, connect, disconnect, run_tasks

    t_all = time.perf_counter()
    total = len(jobs)
    refused = 0
    plans = []  # (prefix, plan) of the files to prepare
    for i, job in enumerate(jobs, 1):
        path = job.pop("path")
        prefix = _prefix(i, total, path)
        try:
            _check_path(path)
            plan = catalogue.plan_ingest(path, max_faces=max_faces, **job)
        except (GarmentError, OSError) as exc:
            refused += 1
            print(f"{prefix}: REFUSED: {_reason(exc)}")
            continue
        if plan.preparation is None:  # already in the catalogue (or its model is): nothing to prepare
            meta, created = (plan.existing, False) if plan.existing is not None else catalogue.add_prepared(plan, None)
            _print_entry(prefix, meta, 0.0, created)
            continue
        plans.append((prefix, plan))
    if plans:
        try:
            started = connect(None if address == LOCAL_RAY else address)
        except RayUnavailable as exc:
            raise CliError(str(exc), code=1) from None
        try:
            t0 = time.perf_counter()
            for k, result in run_tasks(prepare_model, [(plan.preparation,) for _, plan in plans]):
                prefix, plan = plans[k]
                try:
                    if isinstance(result, BaseException):
                        raise result
                    meta, created = catalogue.add_prepared(plan, result)
                except (GarmentError, OSError) as exc:
                    refused += 1
                    print(f"{prefix}: REFUSED: {_reason(exc)}", flush=True)
                    continue
                except Exception as exc:  # noqa: BLE001 - the worker died past its retries: say so, go on
                    refused += 1
                    print(f"{prefix}: REFUSED: its preparation failed on the cluster ({type(exc).__name__})", flush=True)
                    continue
                _print_entry(prefix, meta, time.perf_counter() - t0, created)
        finally:
            if started:
                disconnect()
    _print_total(total, refused, data_dir, time.perf_counter() - t_all)
    return 1 if refused else 0
