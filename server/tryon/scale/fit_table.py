"""Fit tables: the size advice (``tryon.fit.advice.advise_style``, the code ``POST /api/fit`` runs) for every
person of an ANSUR II style CSV and every style, one CSV row per person and style. What a shop runs over its
customer base, or to check its size chart against real bodies.

Each (person, style) is one job: build the body, drape the sizes the advice needs, judge them. The jobs run
in this process one after another, or as Ray tasks (``tryon.scale.ray_jobs``) with the prepared models put in
Ray's object store once. Rows are appended to the output as they finish; a run interrupted and started again
with the same output skips the (person, style) pairs already written.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from tryon.garment.model import GarmentMeta, GarmentModel

COLUMNS = ["person", "style", "recommended", "verdicts", "ease_cm", "reason"]


@dataclass(frozen=True)
class Person:
    """One row of the bodies CSV: its ``subjectid`` (or row number) and measurements (cm)."""

    id: str
    measurements: dict


def _is_number(text: str | None) -> bool:
    try:
        float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def read_bodies(path: Path) -> list[Person]:
    """Every person of an ANSUR II style CSV (millimetres; columns stature, chestcircumference,
    waistcircumference, buttockcircumference). ValueError naming the row for a missing column or a value
    that is not a number."""
    from tryon.body.survey import REQUIRED_COLUMNS, ansur_measurements

    people = []
    with open(path, newline="", encoding="latin-1") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in REQUIRED_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"it has no column {', '.join(missing)} (an ANSUR II style CSV in millimetres)")
        for i, row in enumerate(reader, 2):
            try:
                people.append(Person(str(row.get("subjectid") or f"row {i}"), ansur_measurements(row)))
            except ValueError:
                bad = next(c for c in REQUIRED_COLUMNS if not _is_number(row.get(c)))
                raise ValueError(f"line {i}: {bad} is {row.get(bad)!r}, not a number (mm)") from None
    return people


def advise_person(person: Person, style: str, entries: list[GarmentMeta], models: dict[str, GarmentModel],
                  also: tuple[str, ...] = ()) -> dict:
    """The table row of one person and one style (``entries`` in size order, ``models`` by garment id): the
    recommended size (regular fit), each size's verdict and ease, the reason; and for each fit preference in
    ``also`` (slim, relaxed) its recommended size under that key, chosen among the same sizes' advice. The sizes' drapes run
    here (default settings, the pose the API defaults to), at once where the calling thread may use two threads
    (``sim.blocks.at_once``; a Ray task has one), else one after another: the same verdicts either way."""
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose, check_measurements
    from tryon.fit.advice import Drape, advise_style, chart_size, recommendation
    from tryon.sim.blocks import at_once
    from tryon.sim.run import drape

    measurements = Measurements(**person.measurements)
    problems = check_measurements(measurements)
    if problems:
        return {"person": person.id, "style": style, "recommended": "", "verdicts": "", "ease_cm": "",
                "reason": "not advised: " + "; ".join(problems)}
    body = build_body(measurements, Pose())

    def drape_sizes(indices: list[int]) -> dict[int, Drape]:
        results = at_once(lambda i: drape(body, models[entries[i].id]), indices)
        return {i: Drape(r.vertices, r.faces, r.metrics) for i, r in zip(indices, results)}

    advice, recommended, reason, _ = advise_style(entries, measurements.as_dict(), body, drape_sizes,
                                                  lambda gid: models[gid].vertices)
    # the other fits from the same sizes' advice: only the choice among them differs
    chart = chart_size([m.chart for m in entries], measurements.as_dict())
    others = {p: recommendation(advice, chart, p, entries[0].category)[0] or "" for p in also}
    ease = "; ".join(f"{a.size} " + " ".join(f"{k} {v:+.1f}" for k, v in a.ease_cm.items() if v is not None)
                     for a in advice if any(v is not None for v in a.ease_cm.values()))
    return {"person": person.id, "style": style, "recommended": recommended or "",
            "verdicts": " ".join(f"{a.size}={a.verdict}" for a in advice), "ease_cm": ease, "reason": reason,
            **others}


def done_pairs(out: Path) -> set[tuple[str, str]]:
    """The (person, style) pairs an earlier run already wrote to ``out`` (empty if there is no such file)."""
    if not out.exists():
        return set()
    with open(out, newline="") as fh:
        return {(r["person"], r["style"]) for r in csv.DictReader(fh) if r.get("person") and r.get("style")}


def fit_rows(people: list[Person], styles: dict[str, list[GarmentMeta]], models: dict[str, GarmentModel],
             skip: set[tuple[str, str]], ray_address: str | None = None) -> Iterator[dict | str]:
    """The rows of every (person, style) not in ``skip``, in the order they finish: in this process, or with
    ``ray_address`` (None: here; ``"local"``: a local Ray; ``"auto"`` / ``host:port``: a running cluster) as
    Ray tasks, the models sent to the object store once. A job that failed on the cluster past Ray's
    retries (its worker died again and again) is a string saying which, not a row: it is not written, so a
    run started again does it."""
    jobs = [(p, s) for p in people for s in styles if (p.id, s) not in skip]
    if ray_address is None:
        for person, style in jobs:
            yield advise_person(person, style, styles[style], models)
        return
    from tryon.scale.ray_jobs import connect, disconnect, run_tasks

    started = connect(None if ray_address == "local" else ray_address)
    try:
        for k, row in run_tasks(_advise_job, [(person, style) for person, style in jobs], shared=(styles, models)):
            if isinstance(row, BaseException):
                person, style = jobs[k]
                row = f"{person.id} / {style}: the job failed on the cluster ({type(row).__name__}); run again to retry it"
            yield row
    finally:
        if started:
            disconnect()


# A worker's models, kept from its first task: every task gets the same models from the object store, but
# as a new copy, whose per-model derived data (the shown mesh's springs, computed on first use) would
# otherwise be made again in every task (measured: a quarter of an advice).
_worker_models: dict[tuple, dict] = {}


def _advise_job(person: Person, style: str, styles: dict, models: dict) -> dict:
    key = tuple(sorted((gid, m.meta.source_sha256) for gid, m in models.items()))
    return advise_person(person, style, styles[style], _worker_models.setdefault(key, models))


def append_rows(out: Path, rows: Iterator[dict | str]) -> Iterator[dict | str]:
    """Append each row to the CSV ``out`` as it comes (the header first in a new file), flushed, so an
    interruption loses at most the row being written; yields the rows (and failures, unwritten) on."""
    new = not out.exists() or out.stat().st_size == 0
    with open(out, "a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        if new:
            writer.writeheader()
            fh.flush()
        for row in rows:
            if isinstance(row, dict):
                writer.writerow(row)
                fh.flush()
            yield row
