"""Past one machine (section "scale"): fit-table throughput, advice per second, in this process and on a
local Ray cluster with 1 and 2 worker processes, the same table row for row; Ray's overhead per task
against the time of one advice; and the memory one worker holds.

The catalogue is the generated T-shirt in S, M and L with their chart rows; the people are spread evenly
over the chart (``PEOPLE``). Each advice drapes the sizes it needs (``tryon.scale.fit_table``).
"""

from __future__ import annotations

import resource
import tempfile
import time
from pathlib import Path

from tryon.bench.common import Context, Section, SkipSection, Table, fmt

PEOPLE = {False: 12, True: 4}  # people in the full / quick run
# Worker processes of the Ray runs (the full run; the quick run leaves Ray out: starting a local cluster alone
# takes ~10 s, and tests/test_fit_table.py checks that Ray gives the same table)
WORKERS = (1, 2)
RAY_WORKERS = {False: WORKERS, True: ()}
SIZES = ("S", "M", "L")


def _catalogue(root: Path):
    from tryon.garment.catalogue import Catalogue
    from tryon.garment.generate import GARMENTS, chart_row, garment_mesh, obj_text

    catalogue = Catalogue(root / "data")
    name, category = GARMENTS["tshirt"]
    for size in SIZES:
        path = root / f"tshirt-{size.lower()}.obj"
        path.write_text(obj_text(garment_mesh("tshirt", size), f"tshirt {size}"))
        catalogue.ingest(path, name=f"{name} {size}", category=category, units="m", size=size, style="tshirt",
                         chart=chart_row(size, category))
    return catalogue


def _people(n: int, charts: list[dict]):
    """``n`` people from the smallest chart row's lower bounds to the largest's upper (cm)."""
    from tryon.scale.fit_table import Person

    lo = {k: charts[0][k][0] for k in ("chest", "waist", "hips") if k in charts[0]}
    hi = {k: charts[-1][k][1] for k in lo}
    people = []
    for i in range(n):
        t = (i + 0.5) / n
        m = {k: round(lo[k] + t * (hi[k] - lo[k]), 1) for k in lo}
        m.setdefault("waist", round(m["chest"] - 14, 1))
        m.setdefault("hips", round(m["chest"] + 4, 1))
        people.append(Person(f"p{i + 1}", {"height": round(160 + 25 * t, 1), **m}))
    return people


def _ray_rows(people, styles, models, workers: int):
    import ray

    from tryon.scale.fit_table import fit_rows

    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    try:
        # a first task per worker loads the kernels: not part of the throughput
        list(fit_rows(people[:workers], styles, models, set(), ray_address="auto"))
        t = time.perf_counter()
        rows = list(fit_rows(people, styles, models, set(), ray_address="auto"))
        return rows, time.perf_counter() - t
    finally:
        ray.shutdown()


def run(ctx: Context, sec: Section) -> None:
    try:
        import ray  # noqa: F401
    except ImportError:
        raise SkipSection("Ray is not installed (pip install '.[scale]')") from None
    from tryon.scale.fit_table import fit_rows

    with tempfile.TemporaryDirectory(prefix="tryon-scale-") as tmp:
        catalogue = _catalogue(Path(tmp))
        styles = {"tshirt": catalogue.style("tshirt")}
        models = {m.id: catalogue.model(m.id) for m in styles["tshirt"]}
        people = _people(PEOPLE[ctx.quick], [m.chart for m in styles["tshirt"]])
        list(fit_rows(people[:1], styles, models, set()))  # warm
        t = time.perf_counter()
        serial = list(fit_rows(people, styles, models, set()))
        serial_s = time.perf_counter() - t
        rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        key = lambda r: (r["person"], r["style"])  # noqa: E731
        rows = [["this process", 1, len(serial), fmt(serial_s), fmt(len(serial) / serial_s), "", "yes"]]
        data = {"people": len(people), "serial_s": serial_s, "per_advice_s": serial_s / len(serial),
                "max_rss_mb": rss_mb, "ray": {}}
        if ctx.quick:
            sec.notes.append("Ray left out of --quick (starting a local cluster alone takes ~10 s); the rows are "
                             "this process's")
        for workers in RAY_WORKERS[ctx.quick]:
            ctx.log(f"[bench]   fit table on a local Ray, {workers} worker(s)")
            got, seconds = _ray_rows(people, styles, models, workers)
            same = sorted(got, key=key) == sorted(serial, key=key)
            overhead = (seconds * workers - serial_s) / len(got)  # s of Ray per task, on its worker
            data["ray"][str(workers)] = {"seconds": seconds, "same_rows": same, "overhead_per_task_s": overhead}
            rows.append([f"local Ray, {workers} worker{'s' if workers > 1 else ''}", workers, len(got), fmt(seconds),
                         fmt(len(got) / seconds), f"{100 * overhead / data['per_advice_s']:+.1f} %",
                         "yes" if same else "NO"])
    sec.data.update(data)
    sec.tables.append(Table(
        "Fit table throughput (T-shirt S, M, L; people spread over its chart)",
        ["run", "workers", "advice", "seconds", "advice / s", "Ray overhead per task (of one advice)",
         "rows equal to this process's"],
        rows,
        note="One advice = one person and one style: the body built and the sizes the answer needs draped and "
             "judged (tryon.scale.fit_table, the code POST /api/fit runs). Overhead: the Ray run's worker time "
             "per task beyond the in-process time of one advice (negative: the noise of a shared machine). "
             f"Peak memory of this process (the driver with every model): {rss_mb:.0f} MB.",
    ))
    ray2 = data["ray"].get(str(WORKERS[-1]))
    if not data["ray"]:
        sec.headline.append(f"fit table: {fmt(len(serial) / serial_s)} advice/s in this process (Ray not run); "
                            f"one advice {fmt(data['per_advice_s'])} s")
    if ray2:
        sec.headline.append(
            f"fit table: {fmt(len(serial) / serial_s)} advice/s in this process, "
            f"{fmt(data['people'] / ray2['seconds'])} on a local Ray with {WORKERS[-1]} workers "
            f"(rows equal: {'yes' if ray2['same_rows'] else 'NO'}); one advice {fmt(data['per_advice_s'])} s")
