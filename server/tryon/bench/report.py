"""The benchmark's outputs: ``bench.json`` (every number), ``bench.md`` (tables and headline), PNG plots
(matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from tryon.bench.common import Section, finite, fmt


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_json(path: Path, report: dict) -> None:
    path.write_text(json.dumps(finite(report), indent=1, allow_nan=False) + "\n")


def _md_table(table: dict) -> list[str]:
    cols = table["columns"]
    out = [f"**{table['title']}**", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in table["rows"]:
        out.append("| " + " | ".join(fmt(c) for c in row) + " |")
    if table.get("note"):
        out += ["", table["note"]]
    return out + [""]


def render_markdown(report: dict, plot_prefix: str = "", title: str = "tryon bench",
                    reproduce: bool = False) -> str:
    """The report as Markdown: headline, section list, then every section's tables, plots and notes.
    ``plot_prefix``: put before each plot's file name in its link; ``reproduce``: give each section the
    command that runs it again."""
    lines = [
        f"# {title}", "",
        f"Run {report['started']} UTC, mode **{report['mode']}**, {report['seconds']:.0f} s in all. "
        f"Command: `{report['command']}`.", "",
        f"Machine: {report['machine'].get('cpu', '?')}, {report['machine'].get('cpus')} CPUs, load average "
        f"{', '.join(f'{x:.1f}' for x in report['machine'].get('load_average', []))} at the start, "
        f"Python {report['machine'].get('python')}, code at commit {report['machine'].get('commit') or '?'}.", "",
        "## Headline", "",
    ]
    heads = [h for s in report["sections"] for h in s["headline"]]
    lines += [f"- {h}" for h in heads] or ["- (no headline figures: see the sections)"]
    lines.append("")
    lines += ["## Sections", "", "| section | status | seconds | reason |", "|---|---|---|---|"]
    for s in report["sections"]:
        lines.append(f"| {s['title']} | {s['status']} | {s['seconds']:.1f} | {s['error'] or ''} |")
    lines.append("")
    for s in report["sections"]:
        lines += [f"## {s['title']}", ""]
        if reproduce and s.get("name"):
            lines += [f"Reproduce: `tryon bench --only {s['name']}` (figures in `bench-results/bench.json`, "
                      f"section `{s['name']}`).", ""]
        if s["status"] != "ok":
            lines += [f"**{s['status']}**: {s['error']}", ""]
        for t in s["tables"]:
            lines += _md_table(t)
        for p in s["plots"]:
            lines += [f"![{p}]({plot_prefix}{p})", ""]
        notes = [n for n in s["notes"] if not n.startswith("Traceback")]
        lines += [f"- {n}" for n in notes]
        tb = [n for n in s["notes"] if n.startswith("Traceback")]
        if tb:
            lines += ["", "```", *tb[0].splitlines(), "```"]
        lines.append("")
    return "\n".join(lines) + "\n"


def write_markdown(path: Path, report: dict) -> None:
    path.write_text(render_markdown(report))


# The figures page's plots go in this folder beside it.
PAGE_PLOTS = "bench"


def write_page(page: Path, report: dict, bench_dir: Path) -> list[Path]:
    """The figures page (``docs/benchmarks.md``), written from a bench run's report (``bench.json``'s
    content) so it cannot drift from the measurements: the same tables and notes, each section with the
    command that reproduces it, the plots copied from ``bench_dir`` into ``<page's folder>/bench/``.
    Returns the files written. FileNotFoundError if a plot the report names is missing."""
    plots_dir = page.parent / PAGE_PLOTS
    plots_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for s in report["sections"]:
        for name in s["plots"]:
            target = plots_dir / name
            target.write_bytes((bench_dir / name).read_bytes())
            written.append(target)
    text = render_markdown(report, plot_prefix=f"{PAGE_PLOTS}/", title="Benchmarks", reproduce=True)
    page.write_text(text.replace("\n## Headline", "\nWritten by `tryon bench --page` from the run's "
                                 "`bench.json`; run it again to bring this page up to date.\n\n## Headline", 1))
    return [page, *written]


def write_report(out_dir: Path, sections: list[Section], meta: dict) -> dict:
    """Write bench.json and bench.md into ``out_dir``; returns the report dict."""
    report = {**meta, "sections": [s.as_dict() for s in sections]}
    write_json(out_dir / "bench.json", report)
    write_markdown(out_dir / "bench.md", report)
    return report


def now() -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())


# ---------------------------------------------------------------------------------------------- plots


def plot_peers(out_dir: Path, results: dict, name: str = "peers.png") -> str:
    """Per-frame time against particles, one line per engine (log-log)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    engines = {}
    for rows in results.values():
        for r in rows:
            if "error" in r or r.get("frame_ms_median") is None:
                continue
            engines.setdefault(r["engine"], []).append((r["particles"], r["frame_ms_median"], r["max_stretch"]))
    for engine, pts in sorted(engines.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=engine)
        for n, ms, st in pts:
            ax.annotate(f"{st:.0%}", (n, ms), textcoords="offset points", xytext=(4, 4), fontsize=7)
    xs = [p[0] for pts in engines.values() for p in pts]
    ys = [p[1] for pts in engines.values() for p in pts]
    if xs and max(xs) / min(xs) >= 10:
        ax.set_xscale("log")
    if ys and max(ys) / min(ys) >= 10:
        ax.set_yscale("log")
    ax.set_xlabel("particles")
    ax.set_ylabel("ms per 1/60 s frame (median)")
    ax.set_title("Cloth dropped on a ball (labels: max stretch)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / name)
    plt.close(fig)
    return name


def plot_xy(out_dir: Path, name: str, series: dict, xlabel: str, ylabel: str, title: str,
            logx: bool = False, logy: bool = False, labels: dict | None = None, highlight=None) -> str:
    """A generic scatter/line plot: ``series`` name -> (xs, ys, style); ``labels`` name -> per-point
    strings; ``highlight`` (x, y, text) marks one point."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    for key, (xs, ys, style) in series.items():
        ax.plot(xs, ys, style, label=key)
        if labels and key in labels:
            for x, y, t in zip(xs, ys, labels[key]):
                ax.annotate(t, (x, y), textcoords="offset points", xytext=(3, 3), fontsize=6)
    if highlight is not None:
        ax.plot([highlight[0]], [highlight[1]], "r*", markersize=14, label=highlight[2])
    xs_all = [x for xs, _, _ in series.values() for x in xs if x and x > 0]
    ys_all = [y for _, ys, _ in series.values() for y in ys if y and y > 0]
    # a log axis only where the values span a decade or more (else its ticks say nothing)
    if logx and xs_all and max(xs_all) / min(xs_all) >= 10:
        ax.set_xscale("log")
    if logy and ys_all and max(ys_all) / min(ys_all) >= 10:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / name)
    plt.close(fig)
    return name
