"""Styles and sizes: a catalogue entry's ``style`` (one product in several sizes), its ``size`` label, and
its size-chart row (the body measurements, cm, the size is made for). Checked here, once, for the upload
form, ``tryon ingest`` and ``catalogue.json`` alike; every refusal is a ``GarmentError`` in words.

A chart row is ``{"chest": [min, max], "waist": [min, max], "hips": [min, max]}`` (any of the three; a
single number is a range of one value), kept as ``{name: [min, max]}`` floats in cm.
"""

from __future__ import annotations

import json
import math
import re

from tryon.body.params import MEASUREMENT_RANGES
from tryon.garment.ingest import GarmentError

# The girths a chart row may give (cm): the body measurements a shop's size chart lists.
CHART_KEYS = ("chest", "waist", "hips")
# A style id: short, lower case, usable in a URL and a file name (``tshirt``, ``a-line-skirt``).
STYLE_PATTERN = re.compile(r"[a-z0-9][a-z0-9_-]{0,39}")
SIZE_MAX_CHARS = 20
# Letter sizes in their order; a style whose labels are all here is ordered by it, one whose labels are
# all numbers (EU 36, 38...) numerically, any other in the order its entries were added ("the order given").
LETTER_SIZES = ("XXXS", "XXS", "XS", "S", "M", "L", "XL", "XXL", "XXXL", "4XL", "5XL")
_LETTER_ALIASES = {"2XS": "XXS", "3XS": "XXXS", "2XL": "XXL", "3XL": "XXXL"}


def check_style(style: str | None) -> str | None:
    """The style id stripped (None for none or blank); GarmentError unless it matches ``STYLE_PATTERN``."""
    style = (style or "").strip() or None
    if style is not None and not STYLE_PATTERN.fullmatch(style):
        raise GarmentError(f"style must be a short id of lower-case letters, digits, '-' or '_' (at most 40, "
                           f"starting with a letter or digit), such as tshirt, got {style!r}")
    return style


def check_size(size: str | None) -> str | None:
    """The size label stripped (None for none or blank); GarmentError if longer than ``SIZE_MAX_CHARS``."""
    size = (size or "").strip() or None
    if size is not None and len(size) > SIZE_MAX_CHARS:
        raise GarmentError(f"size must be a label of at most {SIZE_MAX_CHARS} characters, such as M, got {size!r}")
    return size


def parse_chart(chart) -> dict[str, list[float]] | None:
    """A size-chart row (a dict, or its JSON text; None / "" / {} for none) as ``{name: [min, max]}`` cm.
    GarmentError for JSON that does not read, unknown keys, values that are not a number or a pair of
    numbers, min > max, or a value outside the range a body may measure (``MEASUREMENT_RANGES``)."""
    if chart is None or (isinstance(chart, str) and not chart.strip()):
        return None
    if isinstance(chart, str):
        try:
            chart = json.loads(chart)
        except ValueError as exc:
            raise GarmentError(f"size chart is not valid JSON ({exc.msg.lower()} at character {exc.pos}): give "
                               'an object such as {"chest": [92, 100], "waist": 80}') from None
    if not isinstance(chart, dict):
        raise GarmentError('size chart must be a JSON object such as {"chest": [92, 100], "waist": 80}')
    unknown = [k for k in chart if k not in CHART_KEYS]
    if unknown:
        raise GarmentError(f"size chart: unknown key {unknown[0]!r}: a row gives {', '.join(CHART_KEYS)} (cm)")
    out = {}
    for key in CHART_KEYS:
        if key not in chart:
            continue
        value = chart[key]
        pair = value if isinstance(value, list) else [value, value]
        if len(pair) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pair):
            raise GarmentError(f"size chart: {key} must be a number or [min, max] in cm, got {json.dumps(value)}")
        lo, hi = float(pair[0]), float(pair[1])
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise GarmentError(f"size chart: {key} must be finite numbers (cm)")
        if lo > hi:
            raise GarmentError(f"size chart: {key} min {lo:g} cm is greater than its max {hi:g} cm")
        r_lo, r_hi = MEASUREMENT_RANGES[key]
        if lo < r_lo or hi > r_hi:
            raise GarmentError(f"size chart: {key} [{lo:g}, {hi:g}] cm is outside the plausible range "
                               f"[{r_lo:g}, {r_hi:g}] cm of a body's {key}")
        out[key] = [lo, hi]
    return out or None


def check_labels(style, size, chart) -> tuple[str | None, str | None, dict | None]:
    """(style, size, chart) checked together: a style's entries each need a size, and a chart row belongs
    to a size."""
    style, size, chart = check_style(style), check_size(size), parse_chart(chart)
    if style is not None and size is None:
        raise GarmentError(f"style {style!r} needs a size label: each entry of a style is one of its sizes")
    if chart is not None and size is None:
        raise GarmentError("a size chart row needs a size label: it says which body that size is made for")
    return style, size, chart


def _letter(label: str) -> str:
    up = label.strip().upper()
    return _LETTER_ALIASES.get(up, up)


def size_order(labels: list[str]) -> list[int]:
    """Indices that put a style's size ``labels`` (in the order given) in size order: letter sizes by
    ``LETTER_SIZES``, numbers numerically, anything else as given."""
    idx = list(range(len(labels)))
    if labels and all(_letter(s) in LETTER_SIZES for s in labels):
        return sorted(idx, key=lambda i: LETTER_SIZES.index(_letter(labels[i])))
    try:
        numbers = [float(s) for s in labels]
    except ValueError:
        return idx
    return sorted(idx, key=lambda i: numbers[i])


def chart_centre(chart: dict) -> dict[str, float]:
    """The middle of each range of a chart row, cm."""
    return {k: (lo + hi) / 2 for k, (lo, hi) in chart.items()}
