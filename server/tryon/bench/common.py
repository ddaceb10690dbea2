"""Shared pieces of the benchmark: the section result shape, timing helpers, the run context."""

from __future__ import annotations

import math
import os
import platform
import subprocess
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np


@dataclass
class Table:
    """A table for bench.md (and bench.json): ``columns`` names, ``rows`` lists of cells."""

    title: str
    columns: list[str]
    rows: list[list]
    note: str = ""

    def as_dict(self) -> dict:
        return {"title": self.title, "columns": self.columns, "rows": self.rows, "note": self.note}


@dataclass
class Section:
    """One benchmark section's outcome.

    status: ok | failed (our code raised) | skipped (an optional dependency or input is missing).
    data: the numbers (JSON-able); tables / plots (PNG file names) / notes: for the report.
    """

    name: str
    title: str
    status: str = "ok"
    error: str = ""
    seconds: float = 0.0
    data: dict = field(default_factory=dict)
    tables: list[Table] = field(default_factory=list)
    plots: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    headline: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {
            "name": self.name, "title": self.title, "status": self.status, "error": self.error,
            "seconds": self.seconds, "data": self.data, "tables": [t.as_dict() for t in self.tables],
            "plots": self.plots, "notes": self.notes, "headline": self.headline,
        }


class SkipSection(Exception):
    """Raised by a section whose inputs are missing (not a failure of our code)."""


@dataclass
class Context:
    """What every section gets: the output directory, the run mode, and a cache shared between sections
    (bodies, prepared garments) so that nothing is built twice in one run. ``substeps``: the fit section's
    substeps per step (one spring pass each), None for the default settings; ``projection``: its Newton steps of
    the fast projection of the strain limits, None for the default (none); ``sequences``: the motion section's
    random pose sequences per garment, None for its mode's."""

    out_dir: Path
    quick: bool
    stress: bool
    cache: dict = field(default_factory=dict)
    log: Callable[[str], None] = print
    substeps: int | None = None
    projection: int | None = None
    bodies: Path | None = None  # the sizes section's people (an ANSUR II style CSV); None: the shipped sample
    sequences: int | None = None

    def cached(self, key, make):
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]


def run_section(name: str, title: str, fn: Callable[[Context, Section], None], ctx: Context) -> Section:
    """Run ``fn(ctx, section)`` isolated: an exception marks the section failed (with the reason) and the
    benchmark goes on; ``SkipSection`` marks it skipped."""
    sec = Section(name=name, title=title)
    t0 = time.perf_counter()
    ctx.log(f"[bench] {title} ...")
    try:
        fn(ctx, sec)
    except SkipSection as exc:
        sec.status = "skipped"
        sec.error = str(exc)
    except Exception as exc:  # noqa: BLE001 - isolation is the point: report and go on
        sec.status = "failed"
        sec.error = f"{type(exc).__name__}: {exc}"
        sec.notes.append(traceback.format_exc(limit=6))
    sec.seconds = time.perf_counter() - t0
    ctx.log(f"[bench] {title}: {sec.status} in {sec.seconds:.1f} s {sec.error}")
    return sec


def median_seconds(fn: Callable[[], object], repeats: int, warmup: int = 1) -> float:
    """Median wall time (s) of ``repeats`` calls of ``fn`` after ``warmup`` untimed calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def timed(fn: Callable[[], object]) -> tuple[object, float]:
    """(result, seconds) of one call."""
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def machine() -> dict:
    """The facts about this machine (and code) a reader needs to compare numbers."""
    info = {"python": platform.python_version(), "platform": platform.platform(), "cpus": os.cpu_count()}
    try:
        here = Path(__file__).resolve().parent
        info["commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True,
                                        text=True, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        info["commit"] = None
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
        info["load_average"] = list(os.getloadavg())
    except OSError:
        pass
    return info


def finite(value):
    """``value`` with every non-finite float replaced by None (JSON has no NaN), recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (np.floating,)):
        return finite(float(value))
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, dict):
        return {str(k): finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    if isinstance(value, np.ndarray):
        return finite(value.tolist())
    return value


def median(values) -> float | None:
    """The median of ``values`` (numbers), None when there are none."""
    return float(np.median(values)) if len(values) else None


def fmt(value, digits: int = 3) -> str:
    """A table cell: floats to ``digits`` significant digits, None as a dash."""
    if value is None:
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return "nan"
        if v == 0.0:
            return "0"
        if abs(v) >= 10 ** digits:
            return f"{v:,.0f}"
        return f"{v:.{digits}g}"
    return str(value)


def speed_words(ratio: float) -> str:
    """A time ratio (theirs / ours) in words: '2.5x faster', '1.3x slower'."""
    return f"{fmt(ratio)}x faster" if ratio >= 1 else f"{fmt(1 / ratio)}x slower"


def fmt_range(values, digits: int = 3) -> str:
    """'a-b' of the smallest and largest of ``values`` (one number when they are equal)."""
    lo, hi = min(values), max(values)
    return fmt(lo, digits) if fmt(lo, digits) == fmt(hi, digits) else f"{fmt(lo, digits)}-{fmt(hi, digits)}"
