"""A size's verdict from its drape: ``fits``, ``tight``, ``loose``, ``falls_off`` or ``not_draped``, with the
reason in words; and the recommendation over a style's sizes.

In this order (the first that applies):
- ``not_draped``: the size was not simulated (its chart is far from the person's, or the run was cut
  short by the service's wall-clock limit).
- ``tight``, before anything else when the drape holds springs over their limit around the body
  (``too_tight``: the cloth would have to stretch more than it can): a waistband far smaller than the waist
  slides down too, but it is too small, not too large (trousers S on a 113 cm waist slid 15 cm, their cloth
  at 2.5x its length).
- ``falls_off``: the drape's ``stays_up`` is false: it slid off the shoulders or the hips (a waistband
  wider than the hips). Every other figure of such a drape is measured where it lies, not where it is worn.
- ``tight``: a top's or dress's cloth is shorter than the chest by more than its fabric lets it be worn
  fitted (``Fabric.comfort_stretch`` of the body's chest: a knit a few per cent, a woven nothing).
- ``loose``: at a covered girth the draped garment has more tape ease than ``MAX_EASE_CM``.
- ``fits``: none of these.

``max_strain`` and ``display_max_strain`` are reported but do not decide: a spring of free cloth at its
limit is the solver holding it there (every drape reaches it somewhere: 0.15, the shear limit, on a loose
XXL T-shirt), and the shown mesh's strain also grows where the drape comes apart around a hand or a foot
(0.98 on trousers that fit well), which is the drape's fault, not the size's. Too tight is told by the
springs held over their limit by the body (``too_tight``) and by the cloth's own girth.
"""

from __future__ import annotations

from tryon.fit.ease import Girth

VERDICTS = ("fits", "tight", "loose", "falls_off", "not_draped")

# The girths whose cloth length decides tight: a top or dress hangs from the shoulders, so nothing but the body
# stretches its cloth around the chest, and a ring shorter than the chest (by more than its fabric's comfortable
# stretch) is too small for it. Measured on the catalogue's jersey T-shirt at the centres of the chart's rows: the
# size below the chart's leaves +1.2 to +3.6 cm (a slim fit), two sizes below -7 cm (tight); the jersey dress's
# chart size -2.7 to +0.2 cm (2.4 % of the chest at most: fitted). The waist and hips are not judged by the
# cloth's length: a bottom hangs from its band, and a woven's seat does not stretch; there only springs held past
# their limit by the body (``too_tight``) tell tight: on the catalogue's trousers they do for each size below the
# chart's, never for the chart's own.
CLOTH_JUDGED = ("chest",)
# cm: more tape ease than this at a girth and the garment hangs off the body: loose. The T-shirt is cut with
# 8 cm at the chest and grows 8 cm a size; measured on the same bodies, one size over the chart's leaves 9-14
# cm (tape ease, 2.8 cm of it the cloth's offset from the skin), two sizes over 18-25 cm. The trousers' seat
# is cut with 6 cm and grows 6 cm a size; two sizes over leave 11-31 cm at the hips, a spread the waist's
# band (resting on the hips) makes.
MAX_EASE_CM = {"chest": 16.0, "waist": 16.0, "hips": 16.0}
# Where a garment hangs from, by category: what "stays up" means in words.
HANGS_FROM = {"top": "the shoulders", "dress": "the shoulders", "bottom": "the hips"}
# cm: the smallest size that is not too tight is still recommended if it slid at most this far from where it
# was put on (``metrics.SLID_LIMIT_CM`` calls it falling off from 10 cm): trousers L on a man with a 90 cm waist
# and 99 cm hips slid 11 cm, their band a little wider than his waist resting on his hips, as it would.
SITS_LOW_CM = 20.0


def _cm(x: float) -> str:
    """A length in words: whole centimetres ("8 cm"), "under 1 cm" for less."""
    r = round(abs(x))
    return f"{r:.0f} cm" if r >= 1 else "under 1 cm"


def place_name(place: str) -> str:
    """A ``too_tight`` place in words: 'torso hips' -> 'the hips', 'upper_arm_l' -> 'the left upper arm'."""
    if place.startswith("torso "):
        return "the " + place[len("torso "):]
    side = "left " if place.endswith("_l") else ("right " if place.endswith("_r") else "")
    base = place[:-2] if side else place
    return f"the {side}{base.replace('_', ' ')}"


def judge(category: str, metrics: dict, girths: dict[str, Girth | None], comfort_stretch: float = 0.0
          ) -> tuple[str, str]:
    """(verdict, reason) of one drape: its ``metrics`` (``TryOnResult.metrics``: too_tight, stays_up,
    slid_cm, sized_to_body), its ``girths`` (``ease.measure_ease``) and its fabric's ``comfort_stretch``
    (``Fabric``). See the module doc."""
    hangs = HANGS_FROM.get(category, "the body")
    slid = metrics.get("stays_up", True) is False
    if slid and not metrics.get("too_tight"):
        return "falls_off", (f"does not stay on {hangs}: it slid {_cm(metrics.get('slid_cm', 0.0))} down from "
                             f"where it was put on")
    measured = {k: g for k, g in girths.items() if g is not None}
    short = []  # (place, words)
    if not metrics.get("sized_to_body", False) and not slid:  # a slid garment's girths are not where it is worn
        for name, g in measured.items():
            allowed = comfort_stretch * g.body_cm
            if name in CLOTH_JUDGED and g.cloth_ease_cm < -allowed:
                # the cloth's own length round the body (unstretched), not the draped tape girth (ease_cm: the
                # cloth stretched over the body and lying off the skin): "+6 cm of ease" and "3 cm short" at once
                # read as a contradiction on the page
                fitted = f", more than the {_cm(allowed)} its fabric takes fitted" if allowed >= 0.5 else ""
                short.append((name, f"too tight at the {name}: its cloth, unstretched, is "
                                    f"{_cm(g.cloth_ease_cm)} shorter than the {name}{fitted}"))
    named = {name for name, _ in short}
    stretched = [place_name(p) for p in metrics.get("too_tight") or {}
                 if not (p.startswith("torso ") and p[len("torso "):] in named)]
    if stretched:
        where = stretched[0] if len(stretched) == 1 else f"{', '.join(stretched[:-1])} and {stretched[-1]}"
        short.append(("", f"too tight at {where}: the cloth is stretched past its limit there"))
    if short:
        fell = f" (and it slid {_cm(metrics.get('slid_cm', 0.0))} down from where it was put on)" if slid else ""
        return "tight", "; ".join(words for _, words in short) + fell
    over = [(n, g) for n, g in measured.items() if g.ease_cm > MAX_EASE_CM[n]]
    if over:
        return "loose", "loose: " + ", ".join(f"{_cm(g.ease_cm)} of ease at the {n} (over {MAX_EASE_CM[n]:g} cm)"
                                              for n, g in over) + f"; stays on {hangs}"
    if not measured:
        return "fits", f"not too tight anywhere; stays on {hangs}"
    return "fits", f"{_ease_phrase(measured)}; stays on {hangs}"


def _ease_phrase(measured: dict[str, Girth]) -> str:
    """'8 cm of ease at the chest' / '4 cm of ease at the waist, 6 cm at the hips'."""
    parts = [f"{_cm(g.ease_cm)} at the {n}" for n, g in measured.items()]
    first = parts[0].replace(" at the", " of ease at the", 1)
    return ", ".join([first, *parts[1:]])


# cm (``sim.length.garment_ends``): beyond these a garment's ends are too long or too short for the body. A
# long sleeve's cuff more than 5 cm past the wrist joint covers half the palm, more than 5 cm short of it bares
# the wrist bone and the forearm; a full-length trouser leg's hem more than 5 cm below the ankle bone (6-7 cm
# above the floor) lies on the shoe and the floor, more than 3 cm above it bares the ankle; a top's hem more
# than 20 cm below the hips line reaches well past the crotch (about 10 cm below it), more than 8 cm above it
# is cropped.
TOO_LONG_CM = {"sleeve": 5.0, "leg": -5.0, "hem": 20.0}
TOO_SHORT_CM = {"sleeve": -5.0, "leg": 3.0, "hem": -8.0}
_ENDS = {"sleeve": ("sleeves", "past the wrists", "short of the wrists"),
         "leg": ("trouser legs", "below the ankles", "above the ankles"),
         "hem": ("hem", "below the hips", "above the hips")}


def length_notes(ends_cm: dict[str, float]) -> list[str]:
    """Too long or too short, in words, from where a drape's ends lie (``sim.length.garment_ends``): 'too long:
    the sleeves end 7 cm past the wrists'. A pair of sleeves or legs is judged by the one farther out of range."""
    notes = []
    for kind, (what, past, short) in _ENDS.items():
        values = [v for k, v in ends_cm.items() if k.split("_")[0] == kind and v is not None]
        if not values:
            continue
        sign = -1.0 if kind == "leg" else 1.0  # legs: lower (more negative) is longer
        longest, shortest = max(values, key=lambda v: sign * v), min(values, key=lambda v: sign * v)
        verb = "ends" if kind == "hem" else "end"
        if sign * longest > sign * TOO_LONG_CM[kind]:
            notes.append(f"too long: the {what} {verb} {_cm(longest)} {past if sign * longest > 0 else short}")
        elif sign * shortest < sign * TOO_SHORT_CM[kind]:
            notes.append(f"too short: the {what} {verb} {_cm(shortest)} {past if sign * shortest > 0 else short}")
    return notes


# The fit a shopper asks for, and how many sizes from the chart's size it asks (``recommend``).
PREFERENCES = {"slim": -1, "regular": 0, "relaxed": 1}
# cm: the least cloth ease (``Girth.cloth_ease_cm``) at every measured girth a size must leave for each fit, by
# category, where the style has no chart to start from: a slim fit any that is not tight, a regular one the room
# the catalogue's chart sizes leave at their rows' centres (T-shirt chest +3.2 to +4.4 cm, bottoms' waist +2.3 to
# +4.6 and hips +3.0 to +4.0, the jersey dress's chest -2.7 to +0.2), a relaxed one about a size more.
ROOM_CM = {
    "top": {"regular": {"chest": 3.0}, "relaxed": {"chest": 9.0}},
    "dress": {"regular": {"chest": -3.0}, "relaxed": {"chest": 3.0}},
    "bottom": {"regular": {"waist": 2.0, "hips": 2.0}, "relaxed": {"waist": 5.0, "hips": 5.0}},
}


def _wearable(verdict: str, slid_cm: float | None) -> bool:
    """A size one can be advised: not too tight, and on the body (a band a little wider than the waist resting
    lower, on the hips, at most ``SITS_LOW_CM`` down, counts)."""
    return verdict in ("fits", "loose") or (verdict == "falls_off" and slid_cm is not None and slid_cm <= SITS_LOW_CM)


def _has_room(room: dict | None, floor: dict[str, float]) -> bool:
    """Whether a size's cloth ease ``room`` (girth -> cm or None) leaves at least ``floor`` at every measured
    girth (unknown room: yes)."""
    return all(room.get(k) is None or room[k] >= v for k, v in floor.items()) if room else True


def recommend(sizes: list[str], verdicts: list[str], reasons: list[str], slid_cm: list[float | None] | None = None,
              chart: int | None = None, preference: str = "regular", room: list[dict | None] | None = None,
              category: str = "top") -> tuple[str | None, str]:
    """(recommended size or None, why in words) over a style's ``sizes`` in order with their verdicts, how far
    each drape slid (cm) and its cloth ease per girth (``room``).

    With the person's size on the style's chart (``chart``, an index): the chart's size shifted by the
    ``preference`` (``PREFERENCES``: slim a size under, relaxed a size over), checked by its drape: if it is too
    tight, the next larger size that is wearable (``_wearable``); if it is not wearable otherwise (it falls off),
    the nearest smaller one that is; a size that fits goes before one that is loose. Without a chart: the
    smallest wearable size with the preference's room (``ROOM_CM``); if none has it, the largest wearable one.
    Either way a body larger in every girth (a larger chart size, more sizes too tight) never gets a smaller
    size."""
    slid_cm = slid_cm or [None] * len(sizes)
    room = room or [None] * len(sizes)
    draped = [i for i, v in enumerate(verdicts) if v != "not_draped"]
    if not draped:
        return None, "no size was draped"
    ok = [i for i in draped if _wearable(verdicts[i], slid_cm[i])]
    tight = [i for i in draped if verdicts[i] == "tight"]
    free = [i for i in draped if verdicts[i] != "tight"]
    if not free:
        return None, f"every size draped is too tight: the largest, {sizes[tight[-1]]}, is {reasons[tight[-1]]}"
    if not ok or (chart is None and free[0] not in ok):
        # the smallest size that is not too tight falls off: a larger one cannot stay on better
        i = free[0]
        smaller = [sizes[k] for k in tight if k < i]
        tight_words = f" ({', '.join(smaller)} too tight)" if smaller else ""
        return None, f"no size fits: {sizes[i]}, the smallest that is not too tight{tight_words}, {reasons[i]}"
    fit = "" if preference == "regular" else f" for a {preference} fit"
    if chart is not None:
        target = min(max(chart + PREFERENCES[preference], 0), len(sizes) - 1)
        above = [i for i in ok if i >= target]
        tightest = max([i for i in tight if i <= target], default=-1)  # never below a size that is too tight
        below = [i for i in ok if tightest < i <= target]
        if verdicts[target] == "tight" or not below:
            pick = min(above) if above else max(ok)
        else:
            fitting = [i for i in below if verdicts[i] == "fits"]
            pick = max(fitting) if fitting else max(below)
        start = (f"the chart's size for you is {sizes[chart]}" +
                 (f", {sizes[target]}{fit}" if target != chart else ""))
        if pick != target:
            start += f"; {sizes[target]} {_why_not(verdicts[target], reasons[target])}"
        return sizes[pick], f"{sizes[pick]}: {start}; {sizes[pick]} {_in_words(verdicts[pick], reasons[pick], slid_cm[pick])}"
    floor = ROOM_CM.get(category, {}).get(preference, {})
    roomy = [i for i in ok if _has_room(room[i], floor)]
    pick = roomy[0] if roomy else ok[-1]
    smaller = [sizes[k] for k in tight if k < pick]
    tight_words = f" ({', '.join(smaller)} too tight)" if smaller else ""
    if roomy:
        what = (f"the smallest size with the room of a {preference} fit" if floor else
                "the smallest size that is not too tight anywhere")
    else:
        what = f"the largest size that is not too tight, still short of the room of a {preference} fit"
    return sizes[pick], (f"{sizes[pick]} is {what}{tight_words}; it "
                         f"{_in_words(verdicts[pick], reasons[pick], slid_cm[pick])}")


def _why_not(verdict: str, reason: str) -> str:
    """Why the size the chart and the preference ask for is not the answer: 'is too tight at ...'."""
    if verdict == "not_draped":
        return f"was {reason}"
    return f"is {reason}" if verdict != "falls_off" else reason


def _in_words(verdict: str, reason: str, slid_cm: float | None) -> str:
    """The advised size's verdict as the end of a sentence: 'fits: 4 cm of ease ...'."""
    if verdict == "falls_off":
        return f"sits {_cm(slid_cm or 0.0)} lower than it was put on"
    return f"fits: {reason}" if verdict == "fits" else f"is {reason}"
