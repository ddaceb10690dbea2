"""Size advice over a style's sizes: which sizes to drape, each drape's verdict, the recommendation.

The drapes themselves are the caller's (the service runs them on its simulation pool and keeps them in its
result cache, ``tryon.api.advice``; ``tryon fit`` runs them in the process): this module only decides and
judges, from plain data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from tryon.body.types import Body
from tryon.garment.fabric import fabric_named
from tryon.garment.model import GarmentMeta
from tryon.fit.ease import measure_ease
from tryon.fit.verdict import judge, length_notes, recommend

# cm: a larger size measured with less cloth ease than the size under it, at the same girth, by more than this
# (the tape's precision on the shown mesh) is said in the advice's notes (``ease_notes``).
EASE_ORDER_CM = 1.0

# Sizes this many or more steps from the person's size on the style's chart are not draped (the answer
# does not need them: two sizes from the chart's choice are tight or loose for anyone the chart places).
SKIP_SIZES_AWAY = 2


@dataclass
class SizeAdvice:
    """One size's answer. ease_cm / cloth_ease_cm: per covered girth, cm (None where not measured)."""

    size: str
    garment_id: str
    verdict: str
    reason: str
    ease_cm: dict = field(default_factory=dict)
    cloth_ease_cm: dict = field(default_factory=dict)
    too_tight: dict = field(default_factory=dict)
    max_strain: float | None = None
    stays_up: bool | None = None
    slid_cm: float | None = None
    ends_cm: dict = field(default_factory=dict)
    length: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"size": self.size, "garment_id": self.garment_id, "verdict": self.verdict,
                "ease_cm": self.ease_cm, "cloth_ease_cm": self.cloth_ease_cm, "too_tight": self.too_tight,
                "max_strain": self.max_strain, "stays_up": self.stays_up, "slid_cm": self.slid_cm,
                "ends_cm": self.ends_cm, "length": self.length, "reason": self.reason}


def chart_position(charts: list[dict | None], measurements: dict) -> dict[str, float]:
    """Where the person falls on a style's chart, per girth every size's row gives: the index of the size
    whose range holds the person's girth (the nearest range's, between two), -1 below the smallest size,
    len(charts) above the largest. Empty if some size has no chart row."""
    if not charts or any(c is None for c in charts):
        return {}
    keys = [k for k in charts[0] if all(k in c for c in charts) and measurements.get(k) is not None]
    out = {}
    for k in keys:
        value = float(measurements[k])
        lo = np.array([c[k][0] for c in charts])
        hi = np.array([c[k][1] for c in charts])
        if value < lo.min():
            out[k] = -1.0
        elif value > hi.max():
            out[k] = float(len(charts))
        else:  # distance to each range, 0 inside it
            out[k] = float(np.argmin(np.maximum(lo - value, 0) + np.maximum(value - hi, 0)))
    return out


def chart_size(charts: list[dict | None], measurements: dict, clamp: bool = True) -> int | None:
    """Index of the person's size on a style's chart: the largest of the sizes whose ranges hold each girth the
    chart gives (a garment must go round every one). Off the chart, the smallest or largest size (``clamp``) or
    None; None without a chart."""
    position = chart_position(charts, measurements)
    if not position:
        return None
    worst = max(position.values())
    if not clamp and (worst < 0 or worst >= len(charts) or min(position.values()) < 0):
        return None
    return int(min(max(worst, 0), len(charts) - 1))


def sizes_away(index: int, position: dict[str, float]) -> float:
    """How many sizes ``index`` is from the person (the nearest of their girths' places); 0 without a chart."""
    return min((abs(index - p) for p in position.values()), default=0.0)


def skip_reason(index: int, charts: list[dict | None], position: dict[str, float], measurements: dict) -> str | None:
    """Why size ``index`` need not be draped (its chart row is ``SKIP_SIZES_AWAY`` or more sizes from the
    person's), or None to drape it."""
    away = sizes_away(index, position)
    if away < SKIP_SIZES_AWAY:
        return None
    row = ", ".join(f"{k} {charts[index][k][0]:g}-{charts[index][k][1]:g}" for k in position)
    yours = ", ".join(f"{k} {float(measurements[k]):g}" for k in position)
    return f"not draped: its chart ({row} cm) is {away:.0f} sizes from yours ({yours} cm)"


def advise_size(size: str, garment_id: str, category: str, body: Body, vertices: np.ndarray, faces: np.ndarray,
                rest_vertices: np.ndarray, metrics: dict, comfort_stretch: float = 0.0) -> SizeAdvice:
    """One drape's advice: the ease measured on the draped ``vertices`` (n, 3) m (rest shape ``rest_vertices``)
    around ``body``, and the verdict from it, the drape's ``metrics`` and the fabric's ``comfort_stretch``; its
    length (``metrics["ends_cm"]``) too long or too short is said after the reason."""
    girths = measure_ease(body, vertices, faces, rest_vertices, category)
    verdict, reason = judge(category, metrics, girths, comfort_stretch)
    ends = dict(metrics.get("ends_cm") or {})
    length = length_notes(ends)
    if length and verdict != "falls_off":
        reason = "; ".join([reason, *length])
    return SizeAdvice(
        size=size, garment_id=garment_id, verdict=verdict, reason=reason,
        ease_cm={k: (round(g.ease_cm, 1) if g else None) for k, g in girths.items()},
        cloth_ease_cm={k: (round(g.cloth_ease_cm, 1) if g else None) for k, g in girths.items()},
        too_tight=dict(metrics.get("too_tight") or {}), max_strain=round(float(metrics["max_strain"]), 5),
        stays_up=bool(metrics.get("stays_up", True)), slid_cm=float(metrics.get("slid_cm", 0.0)), ends_cm=ends,
        length=length)


def not_draped(size: str, garment_id: str, reason: str) -> SizeAdvice:
    return SizeAdvice(size=size, garment_id=garment_id, verdict="not_draped", reason=reason)


def recommendation(advice: list[SizeAdvice], chart: int | None = None, preference: str = "regular",
                   category: str = "top") -> tuple[str | None, str]:
    """``verdict.recommend`` over the sizes' advice in order."""
    return recommend([a.size for a in advice], [a.verdict for a in advice], [a.reason for a in advice],
                     [a.slid_cm for a in advice], chart, preference, [a.cloth_ease_cm for a in advice], category)


def ease_notes(advice: list[SizeAdvice]) -> list[str]:
    """Where a larger size measured less cloth ease than the size under it at a girth (by over
    ``EASE_ORDER_CM``), why in words: it sits lower on the body (a bottom whose band rests lower, where the body
    is wider), or else it does not, and the drape itself is to blame (the cloth folded or gathered differently
    where the tape crosses it)."""
    notes = []
    draped = [a for a in advice if a.verdict != "not_draped"]
    for small, large in zip(draped, draped[1:]):
        for girth, e_small in small.cloth_ease_cm.items():
            e_large = large.cloth_ease_cm.get(girth)
            if e_small is None or e_large is None or e_large >= e_small - EASE_ORDER_CM:
                continue
            lower = (large.slid_cm or 0.0) - (small.slid_cm or 0.0)
            why = (f"it sits {lower:.0f} cm lower on the body, where the body is wider" if lower >= 2.0 else
                   "it sits no lower: its drape, not its size, leaves less cloth round the body there")
            notes.append(f"{large.size} leaves less room at the {girth} than {small.size} ({e_large:+.1f} against "
                         f"{e_small:+.1f} cm): {why}")
    return notes


@dataclass
class Drape:
    """What advice needs of one size's drape: the shown mesh (vertices (n, 3) m, faces (f, 3)) and the
    drape's metrics (``TryOnResult.metrics``); ``advice``: its ``advise_size`` if the caller already judged it on
    the same body (the service judges every try-on), else None."""

    vertices: np.ndarray
    faces: np.ndarray
    metrics: dict
    advice: "SizeAdvice | None" = None


# Runs the drapes of the sizes at the given indices (of the style's entries) and answers, per index, the
# Drape or the reason (words) it was not draped.
DrapeSizes = Callable[[list[int]], dict[int, "Drape | str"]]


def next_size(advice: list[SizeAdvice], skipped: set[int]) -> int | None:
    """A skipped size the answer turns out to need, or None: when no draped size fits, the next larger one
    after the largest draped if that one is tight, else the next smaller one before the smallest draped if
    that one is too large (loose, falls off)."""
    if any(a.verdict == "fits" for a in advice):
        return None
    draped = [i for i, a in enumerate(advice) if i not in skipped and a.verdict != "not_draped"]
    if not draped:
        return None
    largest, smallest = max(draped), min(draped)
    if advice[largest].verdict == "tight" and largest + 1 in skipped:
        return largest + 1
    if advice[smallest].verdict in ("loose", "falls_off") and smallest - 1 in skipped:
        return smallest - 1
    return None


def advise_style(entries: list[GarmentMeta], measurements: dict, body: Body, drape_sizes: DrapeSizes,
                 rest_vertices: Callable[[str], np.ndarray], preference: str = "regular"
                 ) -> tuple[list[SizeAdvice], str | None, str, list[str]]:
    """The advice over a style's ``entries`` (in size order) for the person with ``measurements`` (cm) and
    ``body`` (built from them): the sizes near the person's on the style's chart are draped at once
    (``drape_sizes``, which may run them concurrently), the others reported ``not_draped`` unless the answer
    turns out to need them (``next_size``). ``rest_vertices(garment_id)``: the garment's rest mesh (n, 3);
    ``preference``: slim, regular or relaxed (``verdict.PREFERENCES``). Returns each size's advice, the
    recommended size (or None), why, and notes on sizes whose ease is out of order (``ease_notes``)."""
    charts = [m.chart for m in entries]
    position = chart_position(charts, measurements)
    advice: list[SizeAdvice] = []
    skipped: set[int] = set()
    wanted = []
    for i, meta in enumerate(entries):
        reason = skip_reason(i, charts, position, measurements)
        advice.append(not_draped(meta.size, meta.id, reason or "not draped"))
        if reason is None:
            wanted.append(i)
        else:
            skipped.add(i)
    while wanted:
        for i, outcome in drape_sizes(wanted).items():
            meta = entries[i]
            if isinstance(outcome, str):
                advice[i] = not_draped(meta.size, meta.id, outcome)
            elif outcome.advice is not None:
                advice[i] = outcome.advice
            else:
                comfort = fabric_named(meta.fabric, meta.category).comfort_stretch
                advice[i] = advise_size(meta.size, meta.id, meta.category, body, outcome.vertices, outcome.faces,
                                        rest_vertices(meta.id), outcome.metrics, comfort)
        extra = next_size(advice, skipped)
        wanted = [] if extra is None else [extra]
        skipped.discard(extra)
    category = entries[0].category if entries else "top"
    recommended, why = recommendation(advice, chart_size(charts, measurements), preference, category)
    return advice, recommended, why, ease_notes(advice)
