"""Size advice against the size chart on real people (section "sizes"): for every person of an ANSUR II
style CSV (``tryon bench --bodies CSV``; by default the small sample of made-up people in
``tests/data/bodies-sample.csv``) and the catalogue's T-shirt and trousers styles, the drape-based advice
(``tryon fit-table``'s code, that of ``POST /api/fit``) beside the size the style's own chart gives:
how often they agree, exactly and within one size, every disagreement with the advice's reason, and the time
of one advice against that of one try-on of the advised size (the body built and the size draped, as
``POST /api/tryon`` does; issue 52: advice at most 3x one try-on).

The advice starts from the chart's size (the maker's claim) and the drapes move it (our measurement: up while
too tight, down while it falls off or is loose), so every disagreement is such a move and the report gives its
reason (the advice's); the verdicts are the drapes' alone. The chart's size of a person is the largest of
the sizes whose ranges hold each of their girths the chart gives (a garment must go round every one);
people outside the chart (below its smallest row or above its largest) are counted apart.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from tryon.bench.common import Context, Section, SkipSection, Table, fmt, median

STYLES = ("tshirt", "trousers")
# The fit preferences compared with the regular fit's advice (``fit.verdict.PREFERENCES``).
PREFERENCES = ("slim", "relaxed")
# People taken in the quick run (the first of the CSV).
QUICK_PEOPLE = 3
# People per style whose advised size is also draped alone, timed as one try-on (the first of the CSV).
TRYON_PEOPLE = 5
SAMPLE = Path("tests") / "data" / "bodies-sample.csv"


def _bodies_path(ctx: Context) -> Path:
    from tryon.bench.scenes import garments_dir

    if ctx.bodies is not None:
        return ctx.bodies
    sample = garments_dir().parent / SAMPLE
    if not sample.exists():
        raise SkipSection(f"no bodies: give --bodies CSV (the sample {SAMPLE} is not in this installation)")
    return sample


def _one_tryon(person, model) -> float:
    """s: one try-on of ``model`` on ``person``: the body built and the garment draped (default settings and
    pose, as ``POST /api/tryon``)."""
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.run import drape

    t = time.perf_counter()
    drape(build_body(Measurements(**person.measurements), Pose()), model)
    return time.perf_counter() - t


def _catalogue(root: Path):
    """The catalogue's styles of STYLES, ingested from ``garments/`` with their charts."""
    from tryon.bench.scenes import catalogue_entries, garments_dir
    from tryon.garment.catalogue import Catalogue

    catalogue = Catalogue(root)
    for e in catalogue_entries():
        if e.get("style") in STYLES:
            catalogue.ingest(garments_dir() / e["file"], name=e["name"], category=e["category"], units=e["units"],
                             size=e["size"], style=e["style"], chart=e.get("chart"))
    return catalogue


def run(ctx: Context, sec: Section) -> None:
    from tryon.fit.advice import chart_size
    from tryon.scale.fit_table import advise_person, read_bodies

    path = _bodies_path(ctx)
    people = read_bodies(path)
    if ctx.quick:
        people = people[:QUICK_PEOPLE]
    with tempfile.TemporaryDirectory(prefix="tryon-sizes-") as tmp:
        catalogue = _catalogue(Path(tmp))
        styles = {s: catalogue.style(s) for s in STYLES if catalogue.style(s)}
        models = {m.id: catalogue.model(m.id) for entries in styles.values() for m in entries}
        rows, disagreements = [], []
        times, tryon_times = {}, {}  # style -> s of each advice, of each timed try-on
        stats, moved = {}, {}
        for style, entries in styles.items():
            labels = [m.size for m in entries]
            st = stats[style] = {"people": 0, "covered": 0, "exact": 0, "within_one": 0, "no_advice": 0}
            mv = moved[style] = {p: {"smaller": 0, "same": 0, "larger": 0} for p in PREFERENCES}
            times[style], tryon_times[style] = [], []
            for person in people:
                t = time.perf_counter()
                row = advise_person(person, style, entries, models, also=PREFERENCES)
                times[style].append(time.perf_counter() - t)
                for p in PREFERENCES:
                    if row[p] in labels and row["recommended"] in labels:
                        step = labels.index(row[p]) - labels.index(row["recommended"])
                        mv[p]["smaller" if step < 0 else "larger" if step > 0 else "same"] += 1
                st["people"] += 1
                want = chart_size([m.chart for m in entries], person.measurements, clamp=False)
                got = labels.index(row["recommended"]) if row["recommended"] in labels else None
                if got is None:
                    st["no_advice"] += 1
                if want is None:
                    continue
                st["covered"] += 1
                st["exact"] += got == want
                st["within_one"] += got is not None and abs(got - want) <= 1
                if len(tryon_times[style]) < TRYON_PEOPLE and got is not None:
                    tryon_times[style].append(_one_tryon(person, models[entries[got].id]))
                if got != want:
                    disagreements.append([person.id, style, labels[want], row["recommended"] or "none",
                                          row["verdicts"], row["reason"]])
    for style, st in stats.items():
        covered = max(st["covered"], 1)
        rows.append([style, st["people"], st["covered"], st["exact"], f"{100 * st['exact'] / covered:.0f} %",
                     st["within_one"], f"{100 * st['within_one'] / covered:.0f} %", st["no_advice"]])
    sec.data.update({"bodies": str(path), "people": len(people), "styles": stats, "preferences": moved,
                     "advice_s_median": {k: median(v) for k, v in times.items()},
                     "tryon_s_median": {k: median(v) for k, v in tryon_times.items()},
                     "disagreements": disagreements})
    sec.tables.append(Table(
        f"Drape-based advice against the style's chart ({len(people)} people of {path.name})",
        ["style", "people", "in the chart", "same size", "same %", "within one size", "within one %", "no size fits"],
        rows,
        note="The chart's size: the largest of the sizes whose ranges hold the person's girths (chest and waist for "
             "tops, waist and hips for bottoms, as the catalogue's charts give them); 'in the chart': people inside "
             "its smallest and largest rows. 'no size fits': the advice recommends none (its reason below). The "
             "advice (regular fit) starts from the chart's size and moves where its drape is too tight, falls off "
             "or is loose: each disagreement below is such a move.",
    ))
    sec.tables.append(Table(
        "The fit preference against the regular fit's advice (people with both)",
        ["style", "preference", "a size smaller", "the same size", "a size larger"],
        [[style, p, c["smaller"], c["same"], c["larger"]] for style, by in moved.items() for p, c in by.items()],
        note="slim asks for a size under the chart's and relaxed for one over; the same size where that size's "
             "drape is too tight (slim), falls off or is loose (relaxed), or the chart has no size beyond.",
    ))
    sec.tables.append(Table(
        "Where the drape and the chart disagree",
        ["person", "style", "chart", "advice", "verdicts", "the advice's reason"],
        disagreements or [["-", "-", "-", "-", "-", "none"]],
    ))
    for style, st in stats.items():
        covered = max(st["covered"], 1)
        advice, one = sec.data["advice_s_median"][style], sec.data["tryon_s_median"][style]
        ratio = (f", {advice / one:.2f}x one try-on of the advised size ({fmt(one)} s, median of "
                 f"{len(tryon_times[style])})" if advice and one else "")
        sec.headline.append(
            f"sizes, {style}: the advice agrees with the chart for {st['exact']} of {st['covered']} people "
            f"({100 * st['exact'] / covered:.0f} %), within one size for {st['within_one']} "
            f"({100 * st['within_one'] / covered:.0f} %); median {fmt(advice)} s an advice (its three fits from "
            f"the same drapes){ratio}")
