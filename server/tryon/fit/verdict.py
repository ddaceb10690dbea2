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
- ``tight``: a top's cloth leaves less room than a regular fit at the chest (``MIN_CLOTH_EASE_CM``).
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

# cm: the least room a top's or dress's cloth must leave at the chest (its ring of cloth there, unstretched,
# minus the body's chest; ``ease.Girth.cloth_ease_cm``) for a regular fit. A top hangs from the shoulders:
# nothing but the body stretches its cloth around the chest, so a ring hardly longer than the chest is a top
# too small for it. Measured on the catalogue's T-shirt (cut with 8 cm at the chest, in jersey) on bodies at
# the centres of the chart's S, M and L rows: the chart's own size leaves +3.8 to +4.3 cm, the size below it
# +0.5 to +1.6 cm (a size below is body-tight, -6 cm two sizes below).
# The waist and hips are not judged by the cloth's length: a bottom hangs from its band, and a woven's seat
# does not stretch; there only springs held past their limit by the body (``too_tight``) tell tight: on the
# catalogue's trousers they do for each size below the chart's, never for the chart's own.
MIN_CLOTH_EASE_CM = {"chest": 3.0}
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


def judge(category: str, metrics: dict, girths: dict[str, Girth | None]) -> tuple[str, str]:
    """(verdict, reason) of one drape: its ``metrics`` (``TryOnResult.metrics``: too_tight, stays_up,
    slid_cm, sized_to_body) and its ``girths`` (``ease.measure_ease``). See the module doc."""
    hangs = HANGS_FROM.get(category, "the body")
    slid = metrics.get("stays_up", True) is False
    if slid and not metrics.get("too_tight"):
        return "falls_off", (f"does not stay on {hangs}: it slid {_cm(metrics.get('slid_cm', 0.0))} down from "
                             f"where it was put on")
    measured = {k: g for k, g in girths.items() if g is not None}
    short = []  # (place, words)
    if not metrics.get("sized_to_body", False) and not slid:  # a slid garment's girths are not where it is worn
        for name, g in measured.items():
            if name in MIN_CLOTH_EASE_CM and g.cloth_ease_cm < MIN_CLOTH_EASE_CM[name]:
                # the cloth's own length round the body (unstretched), not the draped tape girth (ease_cm: the
                # cloth stretched over the body and lying off the skin): "+6 cm of ease" and "3 cm short" at once
                # read as a contradiction on the page
                room = (f"is {_cm(g.cloth_ease_cm)} shorter than the {name}" if g.cloth_ease_cm < 0.0 else
                        f"is only {_cm(g.cloth_ease_cm)} longer than the {name}, short of the "
                        f"{MIN_CLOTH_EASE_CM[name]:g} cm of a regular fit")
                short.append((name, f"too tight at the {name}: its cloth, unstretched, {room}"))
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


def recommend(sizes: list[str], verdicts: list[str], reasons: list[str],
              slid_cm: list[float | None] | None = None) -> tuple[str | None, str]:
    """(recommended size or None, why in words) over a style's ``sizes`` in order with their verdicts (and how
    far each drape slid, cm): the smallest draped size that is not too tight. No larger size can be less
    tight, only looser: if that size fits, it is the answer; if it is loose, or slid at most ``SITS_LOW_CM`` (a
    band a little wider than the waist rests lower, on the hips), it is still the best there is and the
    answer says what is wrong with it; if it slid further, no size fits. So a body larger in every girth
    (more sizes too tight) never gets a smaller size because one size's drape came out a little looser than
    the next one's (trousers S loose at 17 cm of hip ease and M fitting at 16 cm, on a body the chart calls
    S: before, M)."""
    slid_cm = slid_cm or [None] * len(sizes)
    draped = [i for i, v in enumerate(verdicts) if v != "not_draped"]
    if not draped:
        return None, "no size was draped"
    tight = [i for i in draped if verdicts[i] == "tight"]
    free = [i for i in draped if verdicts[i] != "tight"]
    if not free:
        return None, f"every size draped is too tight: the largest, {sizes[tight[-1]]}, is {reasons[tight[-1]]}"
    i = free[0]
    size, verdict, reason = sizes[i], verdicts[i], reasons[i]
    smaller = [sizes[k] for k in tight if k < i]
    tight_words = f" ({', '.join(smaller)} too tight)" if smaller else ""
    if verdict == "fits":
        return size, f"{size} is the smallest size that fits without being tight anywhere{tight_words}"
    sits_low = verdict == "falls_off" and slid_cm[i] is not None and slid_cm[i] <= SITS_LOW_CM
    if verdict == "loose" or sits_low:
        what = f"is {reason}" if verdict == "loose" else f"sits {_cm(slid_cm[i])} lower than it was put on"
        return size, f"{size} is the smallest size that is not too tight anywhere{tight_words}; it {what}"
    return None, f"no size fits: {size}, the smallest that is not too tight{tight_words}, {reason}"
