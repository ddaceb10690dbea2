"""Putting the garment on the body before the simulation starts (paper section 3.1).

1. Global alignment: centre the garment on the torso in x and z, and translate it vertically so that a
   top's (or dress's) shoulder line sits on the body's shoulders, or a bottom's waistband at the body's
   waist level. A garment whose units were guessed at ingestion is also scaled so that its girth at the
   chest is about 1.15 x the body's, a bottom's waistband the body's girth just under its waist (if they are
   not within 0.95-1.6 x already; a garment in the right units is never rescaled:
   its size is the point of trying it on). A top's bodice is measured and scaled without its sleeves,
   which move out with their armholes, unscaled (found over the cloth from cuff to armpit,
   ``find_sleeves``), and a bottom's legs keep their own girth; but no sleeve or leg is left narrower
   than ``LEG_EASE`` x the body's arm or leg. Its springs' natural lengths are then those of the sized
   shape (``align_sized``): it is shown at the size this body would wear.
2. Local alignment (the paper's construction): a = the garment's rear-most point (smallest z) on the
   torso, b = the body point nearest to a, c = the garment's highest point near the centre line (the
   collar for a top, the waistband for a bottom); the garment turns about the X axis through c by the
   angle between (a - c) and (b - c), so its back follows the body's back. Limited to +-15 degrees.
   For a top larger than the body, b is first moved back by the garment's ease (``back_ease``), so a
   loose top is not tilted onto the body's back (its sleeves would swing off the arms).
3. Sleeve directions: the turn that puts each arm along its sleeve is measured, so the simulation can
   pose the arms along the sleeves and bring them back (``ArmPlan``); a long sleeve bent at the elbow
   (modelled on an arm that was bent) gets a second turn of the forearm about the elbow.

This module places the garment (steps 1 and 2, the entry points ``align_garment`` and ``align_sized``); what
it reads and fits is in its neighbours: ``landmarks.py`` (the body's heights and centre), ``sizing.py``
(guessed-units grading), ``sleeves.py`` (finding sleeves and fitting them round the arms), ``legs.py`` (the
crotch, trouser legs over the legs), ``arm_plan.py`` (step 3).
"""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.landmarks import BodyLandmarks, band_points, body_landmarks, hull_girth, torso_points
from tryon.sim.legs import clear_feet, fit_legs, foot_top, garment_crotch, leg_axes, leg_girth, leg_points
from tryon.sim.pieces import bottom_mask
from tryon.sim.sizing import bodice_centre_x, scale_girth_keep_sleeves, size_top
from tryon.sim.sleeves import arm_surfaces, find_sleeves, sleeve_points

# m: the garment's shoulder line is placed this far above the body's (a few mm of air, so the first
# step does not start in contact; gravity closes the gap at once).
SHOULDER_CLEARANCE = 0.01
# Target girth ratio garment / body when a garment's units were guessed (a loose but not baggy fit).
GUESSED_UNITS_EASE = 1.15
# The same for a bottom, at its waistband: snug, since the band's grip is what holds it up (at 1.15 of
# the hips a MakeHuman outfit's trousers slid down to the floor, at 1.0 of the hips its skirt did).
GUESSED_UNITS_BOTTOM_EASE = 1.0
# m: a bottom's waistband girth is measured in a band this far below the body's waist line, and as deep
# (the top 4 cm of a bottom placed with its top at the waist).
BAND_BELOW_WAIST = 0.02
# Largest local-alignment turn about X, radians: the construction is a correction, not a re-posing.
MAX_LOCAL_TURN = np.radians(15.0)
# m: half-height of the band around the rear-most point a in which a top's ease (its depth beyond the
# body's) is measured for the local turn (see ``local_alignment``).
EASE_BAND = 0.02
# m: a bottom's crotch is put at least this far below the body's (a low-rise pair of trousers, whose top
# sits at the hips, is lowered from the waist until it is); the crotch seam then hangs clear of the body.
CROTCH_DROP = 0.02


def align_garment(body: Body, model: GarmentModel, points: np.ndarray | None = None) -> np.ndarray:
    """Aligned copy (k, 3) of ``points`` (default: the garment's coarse rest positions), see module doc
    and ``align_sized``."""
    return align_sized(body, model, points)[0]


def align_sized(body: Body, model: GarmentModel, points: np.ndarray | None = None,
                piece: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Aligned copy (k, 3) of ``points`` (default: the garment's coarse rest positions), see module doc,
    and the garment's natural shape on this body (k, 3), or None if it is its own: a garment whose units
    were guessed is sized to the body, and its springs' natural lengths are those of this shape (the
    points after the girth scale and, for trousers, their legs' girth; ``GarmentModel.resized``), else the
    springs pull it back to the file's size in the first steps: by 49 % round the DiffAvatar strap dress
    scaled to the large body, which then fell through the growing body to the floor. ``piece``: the coarse
    points' ``pieces.piece_labels`` if the caller has them.

    Each piece of a garment file is aligned by its own kind (``pieces.bottom_mask``): the pieces over the
    shoulders as the garment's category says, the pieces hanging from a waist as a bottom (each fitted by
    its own girth when the units were guessed: an outfit's top and bottom were made for one body, which
    is not this one).

    The same rigid transform (plus scale) is what one would apply to the full mesh; we only need it
    for the coarse one, since the full mesh follows the coarse one through the re-attachment.
    """
    x = np.array(model.coarse_vertices if points is None else points, dtype=np.float64)
    shape = x.copy()
    sized = False
    lm = body_landmarks(body)
    torso = torso_points(body)
    guessed = bool(getattr(model.meta, "units_guessed", False))
    bottom = bottom_mask(x, model.coarse_faces, model.meta.category, piece)
    legs = leg_axes(body)
    leg_surface = leg_points(body) if legs is not None and guessed else None  # only guessed units use it
    arm_surface = arm_surfaces(body) if guessed else None
    feet = foot_top(body)
    loops = model.coarse_loops
    for is_top, sel in ((True, ~bottom), (False, bottom)):
        if sel.any():
            index = np.cumsum(sel) - 1  # a point's index among the selected ones
            openings = [index[loop] for loop in loops if sel[loop].all()]
            faces = index[model.coarse_faces[sel[model.coarse_faces].all(axis=1)]]
            x[sel], _, shaped = _align_piece(x[sel], lm, torso, is_top, guessed, None, legs, feet, openings,
                                             faces, leg_surface, arm_surface)
            if shaped is not None:  # no spring joins two pieces: each piece's shape stands alone
                shape[sel] = shaped
                sized = True
    return x, (shape if sized else None)


def _align_piece(x: np.ndarray, lm: BodyLandmarks, torso: np.ndarray, top: bool, guessed: bool,
                 scale: float | None, legs: dict[float, np.ndarray] | None, foot_y: float | None,
                 openings: list[np.ndarray], faces: np.ndarray,
                 leg_surface: dict[float, np.ndarray] | None = None,
                 arm_surface: dict[float, tuple[np.ndarray, np.ndarray]] | None = None
                 ) -> tuple[np.ndarray, float | None, np.ndarray | None]:
    """Global then local alignment of the points (k, 3) of one kind of piece (``top``: hung from the
    shoulders, else from the waist). ``scale``: the factor a guessed-units garment was already scaled by
    (None: decide it here from the girth); ``legs``: the body's leg axes (``leg_axes``), over which a
    bottom's legs are put; ``foot_y``: the top of the body's feet (``foot_top``), above which a trouser
    leg's hem is put; ``openings``: the pieces' boundary loops (index arrays into x), which tell a
    sleeve from a wide bodice or a cape (``sleeve_openings``); ``faces`` (f, 3) its triangles, in which a
    bottom's crotch is found; ``leg_surface``: the body's leg points (``leg_points``), the least girth a
    guessed-units bottom's legs keep; ``arm_surface``: the body's arms (``arm_surfaces``), the least girth a
    guessed-units top's sleeves get (``size_top``). Returns the aligned copy, the scale used (None if not
    guessed) and, if it was rescaled, its natural shape (k, 3) on this body (``align_sized``), else None."""
    x = x.copy()
    shaped = None
    level = lm.chest_y if top else lm.hips_y

    # --- global: centre x, place vertically, centre z
    x[:, 0] += lm.center_x - 0.5 * (x[:, 0].min() + x[:, 0].max())
    if top:
        # a top is centred on its bodice, not on its whole extent (a skirt flared to one side, a sleeve
        # raised higher than the other), first hung by its highest point to find the bodice's height
        x[:, 1] += lm.shoulder_y - x[:, 1].max()
        x[:, 0] += lm.center_x - bodice_centre_x(x, lm)
        dx = np.abs(x[:, 0] - lm.center_x)
        band = (dx > 0.5 * lm.shoulder_half) & (dx < 0.9 * lm.shoulder_half)
        garment_y = x[band, 1].max() if band.sum() >= 3 else x[:, 1].max()
        x[:, 1] += lm.shoulder_y + SHOULDER_CLEARANCE - garment_y
    else:
        x[:, 1] += lm.waist_y - x[:, 1].max()

    body_band = band_points(torso, level, lm.center_x, 2.0 * lm.shoulder_half)
    if guessed:
        anchor = np.array([lm.center_x, lm.shoulder_y if top else lm.waist_y, x[:, 2].mean()])
        sleeves = find_sleeves(x, faces, openings, lm) if top else {}
        if scale is None:
            scale = 1.0
            # a bottom is fitted by its waistband (what holds it up), just under the body's waist line
            fit_y, dy = (level, 0.04) if top else (lm.waist_y - BAND_BELOW_WAIST, BAND_BELOW_WAIST)
            # a top's girth is its bodice's: its sleeves hang beside the chest (a T-shirt at 0.7 of its
            # girth measured 0.98 of the body's chest round its sleeves, 0.82 without)
            bodice = ~sleeve_points(len(x), sleeves)
            g_band = band_points(x[bodice], fit_y, lm.center_x, 1.2 * lm.shoulder_half, dy)
            gg, bg = hull_girth(g_band), hull_girth(band_points(torso, fit_y, lm.center_x, 2.0 * lm.shoulder_half, dy))
            if gg > 0 and bg > 0:
                ratio = gg / bg
                if not 0.95 <= ratio <= 1.6:
                    scale = (GUESSED_UNITS_EASE if top else GUESSED_UNITS_BOTTOM_EASE) / ratio
        if top and sleeves:
            # sleeves narrower than the arms are widened even when the bodice fits
            sized = size_top(x, anchor, scale, lm, sleeves, arm_surface)
            if scale != 1.0 or not np.array_equal(sized, x):
                x, shaped = sized, sized.copy()
        elif scale != 1.0 and top:
            x = scale_girth_keep_sleeves(x, anchor, scale, lm, openings)
        elif scale != 1.0:
            # around the body only (x, z): the guessed unit already gives a wearable length (ingestion
            # checks it), and a garment modelled on a slimmer or broader body differs in girth; scaling the
            # length too made a MakeHuman outfit's trousers 1.4-1.9 x too long on medium and large bodies
            x[:, [0, 2]] = anchor[[0, 2]] + (x[:, [0, 2]] - anchor[[0, 2]]) * scale
        if scale != 1.0 and shaped is None:
            shaped = x.copy()  # its springs' natural lengths (what follows moves it rigidly, but the legs)

    g_band = band_points(x, level, lm.center_x, 0.8 * lm.shoulder_half)
    if len(g_band) and len(body_band):
        x[:, 2] += (0.5 * (body_band[:, 2].min() + body_band[:, 2].max())
                    - 0.5 * (g_band[:, 2].min() + g_band[:, 2].max()))

    # --- local: turn about X through the collar / waistband centre (paper 3.1)
    x = local_alignment(x, torso, lm, top)
    if not top:
        crotch = garment_crotch(x, faces, lm.center_x)
        if crotch is not None and crotch > lm.crotch_y - CROTCH_DROP:
            # a low-rise bottom (its top at the hips on the body it was made for), or one the turn lifted:
            # lowered until its crotch is under the body's, rather than cut the body's crotch with its seam
            x[:, 1] += lm.crotch_y - CROTCH_DROP - crotch
            crotch = lm.crotch_y - CROTCH_DROP
        if crotch is not None and legs is not None:
            # the girth scale is for the waistband, what holds the bottom up: the legs keep their own
            # girth (scaled, they start stretched by the scale all round and shrink back in the first
            # steps, unevenly: the MakeHuman trousers' hems slid off the large body's shins)
            if scale not in (None, 1.0):
                x = leg_girth(x, lm, legs, crotch, 1.0 / scale, leg_surface)
            shaped = x.copy() if shaped is not None else None
            x = fit_legs(x, lm, legs, crotch)
        if crotch is not None and foot_y is not None:
            x = clear_feet(x, crotch, foot_y)
    return x, scale, shaped


def back_ease(x: np.ndarray, torso: np.ndarray, lm: BodyLandmarks, y: float) -> float:
    """How far (m, >= 0) the back of a garment (points (k, 3)) larger than the body hangs behind the body's
    back at height ``y`` when it is centred on it: half its depth beyond the torso's there, in a band
    ``EASE_BAND`` high near the centre line; 0 for a garment no deeper than the body."""
    near = np.abs(x[:, 0] - lm.center_x) < 0.5 * lm.shoulder_half
    g = x[near & (np.abs(x[:, 1] - y) < EASE_BAND), 2]
    near_b = np.abs(torso[:, 0] - lm.center_x) < 0.5 * lm.shoulder_half
    b = torso[near_b & (np.abs(torso[:, 1] - y) < EASE_BAND), 2]
    if len(g) == 0 or len(b) == 0:
        return 0.0
    return max(0.0, 0.5 * ((g.max() - g.min()) - (b.max() - b.min())))


def local_alignment(x: np.ndarray, torso: np.ndarray, lm: BodyLandmarks, top: bool) -> np.ndarray:
    """The paper's rotation about X (see module doc); returns the turned copy of ``x`` (k, 3).

    For a top, the body point b is moved back by the garment's ease there (``back_ease``): the paper's
    construction puts the garment's rear-most point on the body's back, which for a garment larger than
    the body is a turn by its looseness, not by its tilt, and the turn about the collar swings the sleeves
    off the arms (the catalogue's long-sleeve L on the medium body, which it was made for: 5.3 degrees
    forward, its sleeves 5 cm in front of the forearms, which then came out through the sleeves' backs;
    every real top turned forward by 5-13 degrees). Bottoms keep the paper's construction: their band
    sits on the hips, and below it a flare or the crotch makes their depth no measure of their ease."""
    cx = lm.center_x
    near_centre = np.abs(x[:, 0] - cx) < 0.25 * lm.shoulder_half
    if near_centre.sum() < 3:
        return x
    c = x[near_centre][np.argmax(x[near_centre, 1])]
    y_lo = lm.waist_y if top else lm.hips_y - 0.1
    y_hi = lm.chest_y if top else lm.waist_y
    region = (np.abs(x[:, 0] - cx) < 0.5 * lm.shoulder_half) & (x[:, 1] > y_lo) & (x[:, 1] < y_hi)
    if region.sum() < 3:
        return x
    a = x[region][np.argmin(x[region, 2])]
    b = torso[np.argmin(np.linalg.norm(torso - a, axis=1))]
    if top:
        b = b - np.array([0.0, 0.0, back_ease(x, torso, lm, a[1])])
    u = (a - c)[1:]
    v = (b - c)[1:]
    if np.linalg.norm(u) < 1e-6 or np.linalg.norm(v) < 1e-6:
        return x
    # signed angle from u to v in the (y, z) plane; a turn about +x maps y -> z
    angle = np.arctan2(u[0] * v[1] - u[1] * v[0], u @ v)
    angle = float(np.clip(angle, -MAX_LOCAL_TURN, MAX_LOCAL_TURN))
    cs, sn = np.cos(angle), np.sin(angle)
    rot = np.array([[1, 0, 0], [0, cs, -sn], [0, sn, cs]])
    return c + (x - c) @ rot.T
