"""Sizing a garment whose units were guessed at ingestion (alignment): its bodice scaled in girth about the
torso's centre, its sleeves moved out with their armholes unscaled (``scale_girth_keep_sleeves``,
``size_top``), the scale graded from the shoulders down (``graded_scale``). A garment in the right units is
never rescaled: its size is the point of trying it on."""

from __future__ import annotations

import numpy as np

from tryon.sim.landmarks import BodyLandmarks
from tryon.sim.sleeves import SLEEVE_BLEND, Sleeve, fit_sleeve, has_sleeves, sleeve_openings

# How fast a guessed-units top without sleeves widens at the shoulders, relative to its girth scale (x scale
# 1 + (scale - 1) x this at the shoulder line, blending in from the chest line): the bodies' shoulder joints
# are 1.12 x as far apart on the large body as on the medium, their chests 1.17 x as big (0.7 as fast). Scaled
# 1.49 x plainly to the large body's chest, the DiffAvatar strap dress's straps started beyond its
# shoulders and one slid down the arm; at 0.7 they end on the shoulders' edge, at 0.5 on the shoulders.
SHOULDER_GRADE = 0.5
# Height bands between the body's waist and chest lines in which a top's centre line is found
# (``bodice_centre_x``).
CENTRE_BANDS = 5


def bodice_centre_x(x: np.ndarray, lm: BodyLandmarks) -> float:
    """x (m) of the centre line of a top's points (k, 3) hung on the body: the median, over
    ``CENTRE_BANDS`` height bands between the body's waist and chest lines, of the middle of the points'
    extent in x in the band (the bodice, with the sleeves where they hang beside it). The middle of the
    whole extent was off where a garment is not symmetric below its bodice: the DiffAvatar strap dress's
    skirt flares further to one side, so its bodice started 1.8 cm off the body's centre, one side inside
    the torso, and the body growing out of it pushed that side's strap off the shoulder (medium body, left
    armhole off the arm). The middle of the whole extent if no band holds a point."""
    mids = []
    for y in np.linspace(lm.waist_y, lm.chest_y, CENTRE_BANDS):
        band = x[np.abs(x[:, 1] - y) < 0.5 * (lm.chest_y - lm.waist_y) / CENTRE_BANDS, 0]
        if len(band):
            mids.append(0.5 * (band.min() + band.max()))
    return float(np.median(mids)) if mids else 0.5 * float(x[:, 0].min() + x[:, 0].max())


def scale_girth_keep_sleeves(x: np.ndarray, anchor: np.ndarray, scale: float, lm: BodyLandmarks,
                             openings: list[np.ndarray] | None = None) -> np.ndarray:
    """A guessed-units top's points (k, 3) scaled around the body by ``scale`` (x and z about ``anchor``
    (3,)), its sleeves excepted, for a top whose sleeves are not found over the cloth (``find_sleeves``: a
    sleeve held out level; else ``size_top``): only the bodice's half-width that lands on the body's
    shoulder joints (``shoulder_half / scale`` before scaling) is scaled, and what lies beyond it (the
    sleeves) moves out with the shoulder, unscaled, its depth (z) scale fading from ``scale`` to 1 over
    ``SLEEVE_BLEND``. Scaling a sleeve that hangs at 30-50 degrees in x and z only stretched it along its
    length and flattened its section (a MakeHuman blouse at 1.8 on the large body: sleeves 1.8 x as wide
    as deep, well past the wrists), which the arms then cut through. A top without sleeves
    (``has_sleeves`` and, if its boundary loops ``openings`` (index arrays into x) are given,
    ``sleeve_openings``) is scaled plainly: beyond its bodice there is only a flared skirt (the DiffAvatar
    strap dress, kept at its bodice's size, flew off the large body in front), or a cape, or the side of a
    bodice wider than the body's shoulders; but its width above the chest line grows only
    ``SHOULDER_GRADE`` as fast as its girth (``graded_scale``)."""
    plain = x.copy()
    plain[:, [0, 2]] = anchor[[0, 2]] + (x[:, [0, 2]] - anchor[[0, 2]]) * scale
    # the sleeve points are looked for at the smaller size (a bodice scaled up reaches past SLEEVE_REACH like
    # a sleeve), their openings at the larger (a short sleeve's cuff hangs partly inside the reach at the
    # smaller size: the MakeHuman T-shirt and the DiffAvatar polo on the large body)
    small, large = (x, plain) if scale > 1.0 else (plain, x)
    if not has_sleeves(small, lm) or (
            openings is not None and not all(sleeve_openings(large, lm, sign, openings) for sign in (1.0, -1.0))):
        return graded_scale(x, anchor, scale, lm)
    out = x.copy()
    dx = x[:, 0] - anchor[0]
    inner = lm.shoulder_half / scale
    beyond = np.maximum(np.abs(dx) - inner, 0.0)
    out[:, 0] = anchor[0] + np.sign(dx) * (np.minimum(np.abs(dx), inner) * scale + beyond)
    z_scale = scale + (1.0 - scale) * np.clip(beyond / SLEEVE_BLEND, 0.0, 1.0)
    out[:, 2] = anchor[2] + (x[:, 2] - anchor[2]) * z_scale
    return out


def graded_scale(x: np.ndarray, anchor: np.ndarray, scale: float, lm: BodyLandmarks) -> np.ndarray:
    """The points (k, 3) scaled by ``scale`` about ``anchor`` (3,) in x and z, their width above the body's
    chest line growing only ``SHOULDER_GRADE`` as fast, reaching that at the shoulder line (a size up is
    graded so, and so are bodies: the straps of a strap dress stay on the shoulders)."""
    t = np.clip((x[:, 1] - lm.chest_y) / max(lm.shoulder_y - lm.chest_y, 1e-6), 0.0, 1.0)
    out = x.copy()
    out[:, 2] = anchor[2] + (x[:, 2] - anchor[2]) * scale
    out[:, 0] = anchor[0] + (x[:, 0] - anchor[0]) * (scale + t * (scale - 1.0) * (SHOULDER_GRADE - 1.0))
    return out


def size_top(x: np.ndarray, anchor: np.ndarray, scale: float, lm: BodyLandmarks, sleeves: dict[float, Sleeve],
             arms: dict[float, tuple[np.ndarray, np.ndarray]] | None) -> np.ndarray:
    """A guessed-units top's points (k, 3) with ``sleeves`` (``find_sleeves``) sized to the body: the bodice
    scaled whole by ``scale`` about ``anchor`` (3,) (``graded_scale``), all round, under the armpits too,
    and each sleeve moved with its armhole, keeping its own girth but no less than ``LEG_EASE`` x the arm's
    (``arms``: ``arm_surfaces``; ``fit_sleeve``). Only the half-width that lands on the shoulder joints
    used to be scaled (``scale_girth_keep_sleeves``), the bodice's sides under the armpits not: a T-shirt
    at 0.7 of its girth kept 314 springs over at the chest, a long-sleeve at 0.6 999."""
    bodice = x.copy() if scale == 1.0 else graded_scale(x, anchor, scale, lm)
    out = bodice
    for sign, sleeve in sleeves.items():
        joint = lm.shoulder_l if sign > 0 else lm.shoulder_r
        out = fit_sleeve(out, x, bodice, sleeve, joint, arms.get(sign) if arms is not None else None)
    return out
