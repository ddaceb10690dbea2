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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.spatial import ConvexHull, QhullError

from tryon.body.params import POSE_RANGES
from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.garment.topology import boundary_loops, cloth_distance, face_edge_ids
from tryon.sim.collision.collider import _rotation
from tryon.sim.pieces import bottom_mask, section_sides, union_root

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
# How fast a guessed-units top without sleeves widens at the shoulders, relative to its girth scale (x scale
# 1 + (scale - 1) x this at the shoulder line, blending in from the chest line): the bodies' shoulder joints
# are 1.12 x as far apart on the large body as on the medium, their chests 1.17 x as big (0.7 as fast). Scaled
# 1.49 x plainly to the large body's chest, the DiffAvatar strap dress's straps started beyond its
# shoulders and one slid down the arm; at 0.7 they end on the shoulders' edge, at 0.5 on the shoulders.
SHOULDER_GRADE = 0.5
# m: beyond a guessed-units top's bodice its depth scale fades to none over this distance (the armhole;
# see ``scale_girth_keep_sleeves``): over 5 cm an edge across it was stretched up to 1.7 x the scale
# (3.1 x on the MakeHuman blouse at scale 1.8), over 15 cm 1.0-1.05 x.
SLEEVE_BLEND = 0.15
# m: a guessed-units top's sleeve is measured in rings about this far apart over the cloth from its cuff
# (``sleeve_rings``), each of MIN_RING_POINTS points or more (the coarse MakeHuman blouse's sleeves have
# rings of one point: no girth to speak of). A sleeve is widened to at most MAX_SLEEVE_EASE x its girth (the
# MakeHuman blouse on the large body: 1.9 x at the cuff, made for a slimmer arm).
SLEEVE_RING = 0.04
MIN_RING_POINTS = 4
MAX_SLEEVE_EASE = 2.0
# Height bands between the body's waist and chest lines in which a top's centre line is found
# (``bodice_centre_x``).
CENTRE_BANDS = 5
# Largest local-alignment turn about X, radians: the construction is a correction, not a re-posing.
MAX_LOCAL_TURN = np.radians(15.0)
# m: half-height of the band around the rear-most point a in which a top's ease (its depth beyond the
# body's) is measured for the local turn (see ``local_alignment``).
EASE_BAND = 0.02
# m: how far in front of the shin's axis the body's surface counts as the foot (the ankle's radius is
# 3-4 cm, the foot reaches 11-17 cm forward below ~5 cm), and how far above the feet a trouser hem is put
# (with 1 cm, once the legs were shortened from the real crotch, the small body's trousers S caught the
# front of a hem on the instep: 88 springs over down its shin; with 2 or 3 cm none are).
FOOT_REACH = 0.06
FOOT_CLEARANCE = 0.02
# A sleeve's points lie beyond this many torso half-widths from the centre (past the bodice of a fitted top
# or dress), above the chest-to-waist mid level; a side with fewer than MIN_SLEEVE_POINTS such points has
# no sleeve. The torso's width, not the shoulder joints': the upper arm's axis starts in its rounded cap,
# which moves out by 2 cm as the arm comes down from 30 degrees to hanging, and 1.4 of the joints'
# half-width at arm angle 0 lay beyond the catalogue T-shirt M's cuffs (no sleeve found, no arm turned,
# the arms inside the bodice). 1.07 is 1.4 joint half-widths at the default 30 degrees on the small,
# medium and large bodies (within 1 mm).
SLEEVE_REACH = 1.07
MIN_SLEEVE_POINTS = 8
# A sleeve made on arms hanging at the sides (the DiffCloth dress's, whose cuffs hang at the hips) lies within
# the torso's half-width, where no sleeve is looked for: its cuff is an opening on one side centred more
# than this x the upper arm's length from the shoulder joint. On the medium body a sleeveless bodice's
# armhole is centred 0.14-0.3 of it from the joint (the catalogue's sleeveless dresses, the DiffAvatar strap
# dress), a short sleeve's cuff 0.73-0.86 (the catalogue's and DiffAvatar's T-shirts), the DiffCloth dress's 1.18.
HANGING_CUFF = 0.6
# An opening on one side of the body (a sleeve's cuff, an armhole, a trouser hem) has at least this fraction
# of its points on that side of the centre line (a neck, waist or hem opening runs round it).
OPENING_SHARE = 0.8
# m: an opening shorter round than this is a hole in the mesh: no wrist or ankle fits through it.
MIN_PERIMETER = 0.12
# Smallest difference between sleeve and arm angles worth posing the arms for, radians.
MIN_ARM_TURN = np.radians(6.0)
# A sleeve whose cuff's centre lies farther than CUFF_MISS x the cuff's mean radius from the arm's line is
# aimed through its cuff, however small the turn: the hand would start outside the cuff, across its rim,
# and end beside it, out through the side of the sleeve. On the catalogue this was the long-sleeve S on
# the medium body and the S and M on the large one, 2-6 degrees off (``tryon bench --only fit``: their
# shown-mesh strain 1.7 / 6.2 / 2.6 -> 0.4 / 0.5 / 0.4, the large M's 426 springs over -> 0).
CUFF_MISS = 1.0
# Smallest bend of a long sleeve at the elbow worth turning the forearm for, radians; a smaller bend is
# followed by the one shoulder turn along the whole sleeve. Measured on the small / medium / large bodies:
# the MakeHuman blouse's sleeves 38-53 degrees, the MakeHuman men's shirt 26-31, the catalogue's long
# sleeves 0-15 (their wide tops pull the upper part's centre off the arm's line). Turning the catalogue's
# 10-15 degree sleeves too changed 5 of its 27 long-sleeve drapes, none for the worse (springs over the
# target: large M 1063 -> 421, large L 672 -> 0; the others stay at 0).
MIN_ELBOW_TURN = np.radians(10.0)
# The upper part of a sleeve, whose centre line the upper arm is turned onto when the sleeve is bent: its
# points between these fractions of the upper arm's length from the shoulder joint.
UPPER_SLEEVE = (0.4, 0.9)
# The upper part's points lie beyond this many torso half-widths: a ring round the upper arm, whose inner
# side is nearer the torso than the sleeve points SLEEVE_REACH finds. At 1.0 the ring's centre lay off the
# arm and the long-sleeves S and L on arms raised to 90 degrees ended with 273 and 496 springs over; at 0.9
# and 0.95 with none.
RING_REACH = 0.95
# A sleeve has a forearm part when its far opening is at least this fraction of the forearm's length
# off the upper arm (beyond the elbow, or beside it when the sleeve is bent; a short sleeve ends round the
# upper arm).
FOREARM_SLEEVE = 0.2
# Largest elbow turn, radians: the elbow's range of flexion (the body's own pose range) and 30 degrees
# more, for a sleeve bent another way than the body's forearm (the catalogue's long-sleeve M, made
# 10 degrees bent, is 129 degrees off a forearm bent 120 degrees).
MAX_ELBOW_TURN = np.radians(POSE_RANGES["elbow_bend"][1] + 30.0)
# m: a bottom's crotch is put at least this far below the body's (a low-rise pair of trousers, whose top
# sits at the hips, is lowered from the waist until it is); the crotch seam then hangs clear of the body.
CROTCH_DROP = 0.02
# A bottom has legs when its crotch is higher than this fraction of its height above its hem (shorts:
# ~0.3, trousers ~0.75; a skirt's section never parts).
MIN_LEG_FRACTION = 0.15
# m: the crotch is looked for in sections this far apart; a piece of a section counts with this many
# edges crossed or more (a leg of the coarse trousers crosses ~25).
CROTCH_STEP = 0.01
MIN_SECTION_EDGES = 3
# m: height of the bands in which a trouser leg's centre is measured, and the height below the crotch
# over which the leg's shift onto the body's leg blends in.
LEG_BIN = 0.08
LEG_BLEND = 0.10
# m: smallest offset between a trouser leg's centre and the body's leg axis worth moving the legs for:
# a leg within 5 cm still has the body's leg inside it (the catalogue's trousers, made for a reference
# body, are 0-4.3 cm off on the small, medium and large bodies, and moving them changed their drapes both
# ways; the MakeHuman outfits' trousers are 12-22 cm off).
MIN_LEG_SHIFT = 0.05
# A guessed-units bottom's legs keep their own girth, not the waistband's scale, but never less than this
# times the body's leg at each height (the MakeHuman T-shirt outfit's trousers end mid-calf, narrower than a
# large body's calf).
LEG_EASE = 1.1


@dataclass(frozen=True)
class BodyLandmarks:
    """Heights (m, y) and positions of the body used for alignment."""

    center_x: float
    shoulder_y: float  # top of the shoulders, between neck and arm
    shoulder_half: float  # half the distance between the shoulder joints, m
    torso_half: float  # the torso's largest distance from the centre line, m (the same in every pose)
    chest_y: float
    waist_y: float
    hips_y: float
    shoulder_l: np.ndarray  # (3,) left shoulder joint (+x)
    shoulder_r: np.ndarray
    crotch_y: float  # lowest point of the torso between the legs


@dataclass(frozen=True)
class ArmPlan:
    """Arm turns (radians) about each shoulder joint that put each arm along its sleeve; 0 when no turn is
    needed. ``left_axis`` / ``right_axis`` (3,) unit: the axis of each turn (right-handed); the default,
    the body's z axis (+z for the left arm, towards +x, and -z for the right), makes the angles plain
    abductions in the frontal plane."""

    left: float
    right: float
    left_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    right_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    # Forearm turns (radians) about each elbow, after the shoulder turn, for a sleeve bent at the elbow;
    # each axis is given in the arm's rest pose (the shoulder turn carries it along with the upper arm).
    left_elbow: float = 0.0
    right_elbow: float = 0.0
    left_elbow_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    right_elbow_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    # The far opening (point ids into the garment's coarse points) of each turned arm's sleeve, if known.
    left_cuff: np.ndarray | None = None
    right_cuff: np.ndarray | None = None


def _part(body: Body, name: str) -> int | None:
    return body.parts.index(name) if name in body.parts else None


def body_landmarks(body: Body) -> BodyLandmarks:
    """Landmarks from the body's parts, axes and girth levels (estimated from the torso when absent)."""
    kt = _part(body, "torso")
    torso_axis = body.part_axes[kt]
    y0, y1 = sorted((float(torso_axis[0, 1]), float(torso_axis[1, 1])))
    length = y1 - y0
    cx = float(torso_axis[:, 0].mean())
    kl, kr = _part(body, "upper_arm_l"), _part(body, "upper_arm_r")
    sh_l = body.part_axes[kl, 0].copy()
    sh_r = body.part_axes[kr, 0].copy()
    if sh_l[0] < sh_r[0]:
        sh_l, sh_r = sh_r, sh_l
    half = 0.5 * abs(sh_l[0] - sh_r[0])
    face_in = np.isin(body.face_part, [kt, kl, kr])
    verts = body.vertices[np.unique(body.faces[face_in])]
    dx = np.abs(verts[:, 0] - cx)
    band = (dx > 0.5 * half) & (dx < 0.9 * half)
    shoulder_y = float(verts[band, 1].max()) if band.any() else float(sh_l[1])
    levels = body.levels or {}
    return BodyLandmarks(
        center_x=cx,
        shoulder_y=shoulder_y,
        shoulder_half=half,
        torso_half=float(np.abs(part_points(body, kt)[:, 0] - cx).max()),
        chest_y=float(levels.get("chest", y0 + 0.72 * length)),
        waist_y=float(levels.get("waist", y0 + 0.40 * length)),
        hips_y=float(levels.get("hips", y0 + 0.15 * length)),
        shoulder_l=sh_l,
        shoulder_r=sh_r,
        crotch_y=float(part_points(body, kt)[:, 1].min()),
    )


def _band(points: np.ndarray, y: float, cx: float, half_width: float, dy: float = 0.04) -> np.ndarray:
    sel = (np.abs(points[:, 1] - y) < dy) & (np.abs(points[:, 0] - cx) < half_width)
    return points[sel]


def _girth(points: np.ndarray) -> float:
    """Perimeter (m) of the convex hull of the points' (x, z) projection (a tape-measure girth)."""
    if len(points) < 3:
        return 0.0
    try:
        return float(ConvexHull(points[:, [0, 2]]).area)  # in 2-D, ``area`` is the perimeter
    except QhullError:  # all points on a line: no girth to speak of
        return 0.0


def part_points(body: Body, k: int) -> np.ndarray:
    """(m, 3) vertices of the body part with index ``k``."""
    return body.vertices[np.unique(body.faces[body.face_part == k])]


def torso_points(body: Body) -> np.ndarray:
    """(m, 3) vertices of the torso part."""
    return part_points(body, _part(body, "torso"))


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

    body_band = _band(torso, level, lm.center_x, 2.0 * lm.shoulder_half)
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
            g_band = _band(x[bodice], fit_y, lm.center_x, 1.2 * lm.shoulder_half, dy)
            gg, bg = _girth(g_band), _girth(_band(torso, fit_y, lm.center_x, 2.0 * lm.shoulder_half, dy))
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

    g_band = _band(x, level, lm.center_x, 0.8 * lm.shoulder_half)
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


class Sleeve(NamedTuple):
    """A top's sleeve found over the cloth (``find_sleeves``): every point's cloth distance (k,) m from its
    cuff, and the armpit's (m); the sleeve is the points nearer the cuff than the armpit."""

    distance: np.ndarray
    armpit: float


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


def find_sleeves(x: np.ndarray, faces: np.ndarray, openings: list[np.ndarray], lm: BodyLandmarks
                 ) -> dict[float, Sleeve]:
    """Each side's sleeve of a top (points x (k, 3), faces (f, 3), boundary loops ``openings``), keyed by
    side (+1.0: the body's left): the opening on that side (``side_opening``) farthest from the shoulder
    joint is its cuff if it hangs from an armpit (``armpit_distance``). By the cloth, not by reach: a
    T-shirt at 0.7 of its girth has its sleeves within ``SLEEVE_REACH`` (it was scaled as if it had none,
    its girth measured round its sleeves), a sleeveless armhole or a cape's hem has no armpit."""
    out = {}
    for sign, joint in ((1.0, lm.shoulder_l), (-1.0, lm.shoulder_r)):
        ends = [loop for loop in openings if side_opening(x[loop], lm, sign)]
        found = armpit_distance(x, faces, far_opening(x, ends, joint), lm) if ends else None
        if found is not None:
            out[sign] = found
    return out


def sleeve_points(n: int, sleeves: dict[float, Sleeve]) -> np.ndarray:
    """(n,) bool: the points of the ``sleeves`` (``find_sleeves``), from the armpit down."""
    out = np.zeros(n, dtype=np.bool_)
    for sleeve in sleeves.values():
        out |= sleeve.distance < sleeve.armpit
    return out


@njit(cache=True, nogil=True)
def _joining_face(faces, a, b, n):
    """Joining the corners of the triangles ``faces`` (f, 3) in their order: the index of the face that
    first joins the points a and b, and (n,) bool: the points joined to b before it; (-1, none, 0) if
    none does. Also how many points were joined to a before it."""
    parent = np.arange(n)
    size = np.ones(n, dtype=np.int64)
    for i in range(faces.shape[0]):
        ra, rb = union_root(parent, a), union_root(parent, b)
        r0, r1, r2 = (union_root(parent, faces[i, 0]), union_root(parent, faces[i, 1]),
                      union_root(parent, faces[i, 2]))
        if ra != rb and (ra == r0 or ra == r1 or ra == r2) and (rb == r0 or rb == r1 or rb == r2):
            joined = np.empty(n, dtype=np.bool_)
            for v in range(n):
                joined[v] = union_root(parent, v) == rb
            return i, joined, size[ra]
        for c in range(1, 3):
            r0, rc = union_root(parent, faces[i, 0]), union_root(parent, faces[i, c])
            if r0 != rc:
                parent[rc] = r0
                size[r0] += size[rc]
    return -1, np.zeros(n, dtype=np.bool_), 0


def armpit_distance(x: np.ndarray, faces: np.ndarray, cuff: np.ndarray, lm: BodyLandmarks) -> Sleeve | None:
    """The sleeve of a top (points x (k, 3), faces (f, 3)) whose cuff is the opening ``cuff`` (point ids),
    if it hangs from an armpit, else None. Faces added from the lowest up (by their highest corner), the
    armpit is where the part of the top below first joins the cuff's lowest point to the hem (the lowest
    point near the centre line): just before, the part joined to the hem is the bodice below the armpit,
    reached from the cuff over the cloth through the armpit, so the least cloth distance of its points is
    the armpit's. A sleeveless armhole's lowest point joins the bodice with its first face, a sleeve's cuff
    only after ``MIN_SLEEVE_POINTS`` of the sleeve have joined it; a sleeve held out level has none."""
    y = x[:, 1]
    near = np.abs(x[:, 0] - lm.center_x) < 0.5 * lm.shoulder_half
    if not near.any():
        return None
    hem = int(np.flatnonzero(near)[np.argmin(y[near])])
    low = int(cuff[np.argmin(y[cuff])])
    order = np.argsort(y[faces].max(axis=1), kind="stable")
    face, bodice, sleeve_size = _joining_face(np.ascontiguousarray(faces[order], dtype=np.int64), low, hem, len(x))
    if face < 0 or sleeve_size < MIN_SLEEVE_POINTS:
        return None
    d = cloth_distance(x, faces, cuff)
    return Sleeve(d, float(d[bodice].min()))


def ring_index(d: np.ndarray, armpit: float) -> tuple[np.ndarray, float]:
    """The ring round a sleeve each point lies in (k,) int (-1: beyond the armpit's ring), by its cloth
    distance ``d`` (k,) m from the cuff, the rings ``SLEEVE_RING`` or so apart from the cuff (ring 0) to
    the armpit (the last); and their spacing, m."""
    count = max(1, int(round(armpit / SLEEVE_RING)))
    spacing = armpit / count
    inside = d <= armpit + 0.5 * spacing
    return np.where(inside, np.rint(np.where(inside, d, 0.0) / spacing), -1).astype(np.int64), spacing


def sleeve_rings(x: np.ndarray, sleeve: Sleeve, joint: np.ndarray):
    """The rings round a sleeve (``ring_index``) of ``MIN_RING_POINTS`` points or more: (their ids (n,),
    centres (n, 3), unit tangents (n, 3) towards the armpit, radii (n,) m: the mean distance of a ring's
    points from its centre across the sleeve, and their places along the arm (n,) m from the shoulder
    ``joint`` (3,): the armpit ring centre's distance from it, then on down the ring centres). None with
    fewer than two rings."""
    ring, _ = ring_index(sleeve.distance, sleeve.armpit)
    inside = ring >= 0
    ring = ring[inside]
    counts = np.bincount(ring)
    ids = np.flatnonzero(counts >= MIN_RING_POINTS)
    if len(ids) < 2:
        return None
    sums = np.stack([np.bincount(ring, weights=x[inside, j]) for j in range(3)], axis=1)
    centres = sums[ids] / counts[ids, None]
    tangents = np.gradient(centres, ids, axis=0)
    tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-12)
    kept = np.full(len(counts), -1)
    kept[ids] = np.arange(len(ids))
    k = kept[ring]
    mine = k >= 0
    rel = x[inside][mine] - centres[k[mine]]
    across = rel - np.einsum("ij,ij->i", rel, tangents[k[mine]])[:, None] * tangents[k[mine]]
    radii = np.bincount(k[mine], weights=np.linalg.norm(across, axis=1), minlength=len(ids)) / counts[ids]
    steps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    along = float(np.linalg.norm(centres[-1] - joint)) + np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])
    return ids, centres, tangents, radii, along


def fit_sleeve(out: np.ndarray, x: np.ndarray, bodice: np.ndarray, sleeve: Sleeve, joint: np.ndarray,
               arm: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """``out`` (k, 3) with one sleeve of the top's points x (k, 3) moved with its armhole: by the move of
    its armpit ring's points from x to ``bodice`` (k, 3: the bodice's scale of every point), and widened
    about its rings' centres (``sleeve_rings``) to no less than ``LEG_EASE`` x the arm's girth along it
    (``arm``: the arm's joints and surface, ``arm_surfaces``; at most ``MAX_SLEEVE_EASE``), blending in
    from the bodice's scale at the armpit over ``SLEEVE_BLEND`` down the sleeve (or its whole length, if
    shorter). Unchanged if its rings are not found."""
    rings = sleeve_rings(x, sleeve, joint)
    if rings is None:
        return out
    ids, centres, tangents, radii, along = rings
    ring, spacing = ring_index(sleeve.distance, sleeve.armpit)
    armhole = ring == ids[-1]
    shift = (bodice[armhole] - x[armhole]).mean(axis=0)
    factor = np.ones(len(ids))
    if arm is not None:
        skin = arm_radii(arm[1], arm[0], along)
        factor = np.where(skin > 0, np.clip(LEG_EASE * skin / np.maximum(radii, 1e-9), 1.0, MAX_SLEEVE_EASE), 1.0)
    d = sleeve.distance
    weight = np.clip((sleeve.armpit - d) / min(SLEEVE_BLEND, sleeve.armpit), 0.0, 1.0)
    sel = weight > 0
    r = ids * spacing
    ds = d[sel]
    centre = np.stack([np.interp(ds, r, centres[:, j]) for j in range(3)], axis=1)
    tangent = np.stack([np.interp(ds, r, tangents[:, j]) for j in range(3)], axis=1)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    rel = x[sel] - centre
    across = rel - np.einsum("ij,ij->i", rel, tangent)[:, None] * tangent
    moved = x[sel] + shift + (np.interp(ds, r, factor) - 1.0)[:, None] * across
    out = out.copy()
    out[sel] = bodice[sel] + weight[sel, None] * (moved - bodice[sel])
    return out


def arm_surfaces(body: Body) -> dict[float, tuple[np.ndarray, np.ndarray]] | None:
    """Each arm's joints (3, 3) (shoulder, elbow, wrist end: ``arm_joints``) and its surface points (m, 3),
    upper arm and forearm, keyed by side (+1.0: the left arm, towards +x; -1.0: the right); None if the
    body has no forearms."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        ku, kf = _part(body, f"upper_arm_{side}"), _part(body, f"forearm_{side}")
        if ku is None or kf is None:
            return None
        out[sign] = (np.array(arm_joints(body, side)), np.concatenate([part_points(body, ku), part_points(body, kf)]))
    return out


def arm_radii(points: np.ndarray, joints: np.ndarray, along: np.ndarray) -> np.ndarray:
    """Median distance (m) of an arm's surface points (m, 3) from its axis (the polyline ``joints`` (3, 3):
    shoulder, elbow, wrist end) in bands ``LEG_BIN`` long about the lengths ``along`` (h,) m down the axis
    from the shoulder joint; 0 where a band has none (past the wrist)."""
    place, dist, start = [], [], 0.0
    for a, b in zip(joints[:-1], joints[1:]):
        length = float(np.linalg.norm(b - a))
        u = np.clip((points - a) @ (b - a) / length ** 2, 0.0, 1.0)
        dist.append(np.linalg.norm(points - a - u[:, None] * (b - a), axis=1))
        place.append(start + u * length)
        start += length
    nearer = np.argmin(np.stack(dist), axis=0)  # a point belongs to the nearer of the two segments
    place, dist = np.choose(nearer, place), np.choose(nearer, dist)
    on_axis = (place > 0.0) & (place < start)
    out = np.zeros(len(along))
    for k, t in enumerate(along):
        near = on_axis & (np.abs(place - t) < 0.5 * LEG_BIN)
        if near.any():
            out[k] = float(np.median(dist[near]))
    return out


def sleeve_mask(x: np.ndarray, lm: BodyLandmarks, sign: float, reach: float = SLEEVE_REACH) -> np.ndarray:
    """(k,) bool: the points (k, 3) of the sleeve on one side (``sign`` +1: the body's left, towards +x):
    beyond ``SLEEVE_REACH`` x the torso's half-width from the centre (past the bodice of a fitted top or
    dress), above the chest-to-waist mid level."""
    beyond = (x[:, 0] - lm.center_x) * sign > reach * lm.torso_half
    return beyond & (x[:, 1] > 0.5 * (lm.chest_y + lm.waist_y))


def sleeve_openings(x: np.ndarray, lm: BodyLandmarks, sign: float, loops: list[np.ndarray],
                    upper: np.ndarray | None = None) -> list[np.ndarray]:
    """The openings (``loops``: boundary loops, index arrays into the points x (k, 3)) on one side (``sign``
    +1: the body's left) whose centre lies beyond ``SLEEVE_REACH`` x the torso's half-width, all of their
    points among ``upper`` (k,) bool if given: a sleeve's cuff. A cuff may hang below the level
    ``sleeve_mask`` takes sleeve points above, so only the reach counts here. The centre, not all the
    points: a short sleeve's cuff is a ring round the arm whose inner side may lie within the reach (the
    catalogue's T-shirts S-L on the large body: 57-71 % of their points beyond it), while a sleeveless
    bodice's armhole, however wide, is centred within it (at most 0.95 of the reach on the catalogue's
    three bodies; the cuffs at least 1.07)."""
    out = []
    for loop in loops:
        if upper is not None and not upper[loop].all():
            continue
        if (x[loop, 0].mean() - lm.center_x) * sign > SLEEVE_REACH * lm.torso_half:
            out.append(loop)
    return out


def side_opening(points: np.ndarray, lm: BodyLandmarks, sign: float) -> bool:
    """Whether an opening, its points (q, 3) in order round it, is one a limb fits through on one side of the
    body (``sign`` +1: the body's left): at least ``MIN_PERIMETER`` round, ``OPENING_SHARE`` of its points on
    that side of the centre line (a sleeve's cuff, an armhole, a trouser hem; not a neck, waist or hem)."""
    if len(points) < 3:
        return False
    if float(np.linalg.norm(points - np.roll(points, 1, axis=0), axis=1).sum()) < MIN_PERIMETER:
        return False
    return bool(((points[:, 0] - lm.center_x) * sign > 0).mean() >= OPENING_SHARE)


def arm_misses(cuff: np.ndarray, joint: np.ndarray, arm: np.ndarray) -> bool:
    """Whether an arm from the shoulder ``joint`` (3,) along the unit direction ``arm`` (3,) misses the
    opening whose points are ``cuff`` (q, 3): the opening's centre lies farther from the arm's line than
    ``CUFF_MISS`` x its mean radius."""
    centre = cuff.mean(axis=0)
    radius = float(np.linalg.norm(cuff - centre, axis=1).mean())
    rel = centre - joint
    return float(np.linalg.norm(rel - (rel @ arm) * arm)) > CUFF_MISS * radius


def hanging_cuff(body: Body, side: str, x: np.ndarray, lm: BodyLandmarks, sign: float, loops: list[np.ndarray],
                 upper: np.ndarray) -> np.ndarray | None:
    """The cuff (point ids into x (k, 3)) of a sleeve hanging beside the torso on one side (``side`` "l" |
    "r", ``sign`` +1 for the body's left), or None: of the openings of the pieces over the shoulders
    (``upper`` (k,) bool) on that side (``side_opening``), the one farthest below the shoulder joint, if
    its centre is more than ``HANGING_CUFF`` x the upper arm's length from the joint and the arm would miss
    it (``arm_misses``). A sleeveless bodice's armhole is centred near the joint."""
    if _part(body, f"upper_arm_{side}") is None:
        return None
    joint, elbow, _ = arm_joints(body, side)
    reach = HANGING_CUFF * float(np.linalg.norm(elbow - joint))
    arm = arm_direction(body, side)
    best, best_drop = None, 0.0
    for loop in loops:
        if not upper[loop].all():
            continue
        p = x[loop]
        if not side_opening(p, lm, sign):
            continue
        centre = p.mean(axis=0)
        if np.linalg.norm(centre - joint) < reach or not arm_misses(p, joint, arm):
            continue
        drop = joint[1] - centre[1]
        if drop > best_drop:
            best, best_drop = loop, drop
    return best


def has_sleeves(x: np.ndarray, lm: BodyLandmarks) -> bool:
    """Whether the top's points (k, 3) reach out like a sleeve (``MIN_SLEEVE_POINTS`` or more) on each
    side. Reach alone: the side of a bodice wider than the body's shoulders reaches as far, and only an
    opening out there (``sleeve_openings``) tells them apart."""
    return all(sleeve_mask(x, lm, sign).sum() >= MIN_SLEEVE_POINTS for sign in (1.0, -1.0))


def garment_crotch(x: np.ndarray, faces: np.ndarray, cx: float) -> float | None:
    """Height (m) of a bottom's crotch, to ``CROTCH_STEP``: the highest level, down from its top, whose
    section has a piece on each side of the centre line x = ``cx`` (``pieces.section_sides``); None for a
    skirt, whose section never parts. Its points (k, 3), its faces (f, 3). The lowest point near the
    centre line, used before, was the catalogue trousers' knees (their legs hang within 2 cm of each other
    down to there) and the shorts' hems (no crotch: shorts were taken for a skirt)."""
    y0, y1 = float(x[:, 1].min()), float(x[:, 1].max())
    edges, face_edges = face_edge_ids(faces)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    for y in np.arange(y1 - CROTCH_STEP, y0, -CROTCH_STEP):
        if all(section_sides(x, faces, face_edges, edges, float(y), cx, MIN_SECTION_EDGES)):
            return float(y) if y - y0 > MIN_LEG_FRACTION * (y1 - y0) else None
    return None


def leg_axes(body: Body) -> dict[float, np.ndarray] | None:
    """Each leg's axis as a polyline (3, 3) from the hip joint through the knee to the ankle, keyed by
    side (+1.0: the left leg, towards +x; -1.0: the right); None if the body has no legs."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        kt, ks = _part(body, f"thigh_{side}"), _part(body, f"shin_{side}")
        if kt is None or ks is None:
            return None
        thigh, shin = body.part_axes[kt], body.part_axes[ks]
        out[sign] = np.array([thigh[0], 0.5 * (thigh[1] + shin[0]), shin[1]])
    return out


def leg_points(body: Body) -> dict[float, np.ndarray]:
    """Each leg's surface points (m, 3), thigh and shin, keyed by side as ``leg_axes``."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        parts = [k for k in (_part(body, f"thigh_{side}"), _part(body, f"shin_{side}")) if k is not None]
        out[sign] = np.concatenate([part_points(body, k) for k in parts]) if parts else np.empty((0, 3))
    return out


def leg_radii(points: np.ndarray, axis: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Median horizontal distance (m) of a leg's surface points (m, 3) from its axis (``leg_axes``, a
    polyline running down) in bands ``LEG_BIN`` high about ``heights`` (h,); 0 where a band has none."""
    centres = axis_at(axis, heights)
    out = np.zeros(len(heights))
    for b, y in enumerate(heights):
        near = points[np.abs(points[:, 1] - y) < 0.5 * LEG_BIN]
        if len(near):
            out[b] = float(np.median(np.linalg.norm(near[:, [0, 2]] - centres[b], axis=1)))
    return out


def axis_at(axis: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """(h, 2) x, z (m) of a leg's axis (``leg_axes``, a polyline running down) at ``heights`` (h,) m."""
    ay = axis[::-1, 1]  # the polyline runs downwards: reverse it for np.interp
    return np.stack([np.interp(heights, ay, axis[::-1, c]) for c in (0, 2)], axis=1)


def _leg_bands(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float):
    """The height bands (``LEG_BIN``) of a bottom's points (k, 3) below ``crotch`` and each trouser leg in
    them: (edges (n_bins + 1,), centres (n_bins,), {side sign: (leg mask (k,), its centre in each band
    (n_bins, 2) x, z, the body leg's axis there (n_bins, 2))}), or None when a leg has a band without
    points (shorts too short for the bands, a skirt)."""
    y = x[:, 1]
    low = float(y.min())
    n_bins = max(2, int(np.ceil((crotch - low) / LEG_BIN)))
    edges = np.linspace(low, crotch, n_bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    found = {}
    for sign, axis in legs.items():
        leg = (sign * (x[:, 0] - lm.center_x) > 0) & (y < crotch)
        if leg.sum() < 3 * n_bins:
            return None
        centre = _leg_centres(x, leg, edges)
        if centre is None:
            return None
        found[sign] = (leg, centre, axis_at(axis, centres))
    return edges, centres, found


def _band_of(heights: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """The band (index) each height (m) falls in, bands bounded by ``edges`` (n_bins + 1,)."""
    return np.clip(np.searchsorted(edges, heights) - 1, 0, len(edges) - 2)


def _band_mean(band: np.ndarray, values: np.ndarray, n_bins: int) -> np.ndarray:
    """(n_bins,) mean of the values in each band (every band must hold one)."""
    return np.bincount(band, weights=values, minlength=n_bins) / np.bincount(band, minlength=n_bins)


def _leg_centres(x: np.ndarray, leg: np.ndarray, edges: np.ndarray) -> np.ndarray | None:
    """(n_bins, 2) x, z of the leg's (mask ``leg``) centre in each band, or None if a band is empty."""
    n_bins = len(edges) - 1
    b = _band_of(x[leg, 1], edges)
    if (np.bincount(b, minlength=n_bins) == 0).any():
        return None
    return np.stack([_band_mean(b, x[leg, c], n_bins) for c in (0, 2)], axis=1)


def leg_girth(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float, girth: float,
              leg_surface: dict[float, np.ndarray] | None = None) -> np.ndarray:
    """A bottom's points (k, 3) with each trouser leg scaled by ``girth`` about its centres, around the leg
    (x, z), blending in over ``LEG_BLEND`` below the crotch (undoing a guessed-units girth scale,
    ``_align_piece``), but not to less than ``LEG_EASE`` x the body's leg (``leg_surface``: its points by
    side, ``leg_points``): a hem too narrow for the calf would start inside it. ``crotch``: the garment's
    (``garment_crotch``); ``legs``: the body's leg axes (``leg_axes``). Unchanged without two legs."""
    bands = _leg_bands(x, lm, legs, crotch)
    if bands is None or girth == 1.0:
        return x
    edges, centres, found = bands
    x = x.copy()
    for sign, (leg, centre, _) in found.items():
        blend = np.clip((crotch - x[leg, 1]) / LEG_BLEND, 0.0, 1.0)[:, None]
        mids = np.stack([np.interp(x[leg, 1], centres, centre[:, j]) for j in range(2)], axis=1)
        rel = x[leg][:, [0, 2]] - mids
        radius = _band_mean(_band_of(x[leg, 1], edges), np.linalg.norm(rel, axis=1), len(centres))
        skin = leg_radii(leg_surface[sign], legs[sign], centres) if leg_surface is not None else 0.0
        factor = np.interp(x[leg, 1], centres, np.clip(LEG_EASE * skin / radius, girth, 1.0))
        x[np.flatnonzero(leg)[:, None], [0, 2]] = mids + rel * (1.0 + blend * (factor[:, None] - 1.0))
    return x


def fit_legs(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float) -> np.ndarray:
    """Move each trouser leg of the bottom points (k, 3) over the body's leg. First the leg is turned,
    rigidly, from its own direction (a line through its centres, the mean of its points in bands) onto the
    body leg's, about its centre at the crotch; then its centre at each height is moved onto the body's leg
    axis. Both blend in over ``LEG_BLEND`` below the crotch so the seat does not move. A garment modelled on
    a body standing with its feet further apart (MakeHuman) or closer together (the catalogue's trousers on
    legs spread 20 degrees) otherwise starts with the body's shins outside its legs, and the collision pulls
    the legs across (twisted or splayed legs). Moving the centres alone shears a leg: on legs spread 20
    degrees the trousers M started with 816 springs over their limits, strained up to 69 %. ``crotch``: its
    height (``garment_crotch``). Nothing moves when no leg is off by ``MIN_LEG_SHIFT``."""
    bands = _leg_bands(x, lm, legs, crotch)
    if bands is None:
        return x
    edges, centres, found = bands
    if max(np.abs(target - centre).max() for _, centre, target in found.values()) < MIN_LEG_SHIFT:
        return x
    x = x.copy()
    for sign, (leg, centre, target) in found.items():
        blend = np.clip((crotch - x[leg, 1]) / LEG_BLEND, 0.0, 1.0)[:, None]
        # the leg's direction: a line x, z = a + b y through the centres of the bands below the blend
        below = centres < crotch - LEG_BLEND
        if below.sum() >= 2:
            slope = np.polyfit(centres[below], centre[below], 1)[0]  # (2,) dx/dy, dz/dy
            own = -np.array([slope[0], 1.0, slope[1]])
            own /= np.linalg.norm(own)
            body_dir = legs[sign][-1] - legs[sign][0]
            body_dir /= np.linalg.norm(body_dir)
            turn_axis = np.cross(own, body_dir)
            sin_a = float(np.linalg.norm(turn_axis))
            if sin_a > 1e-6:
                turn = _rotation(turn_axis / sin_a, float(np.arctan2(sin_a, own @ body_dir)))
                top = np.array([np.interp(crotch, centres, centre[:, 0]), crotch,
                                np.interp(crotch, centres, centre[:, 1])])
                x[leg] += blend * ((x[leg] - top) @ turn.T + top - x[leg])
                centre = _leg_centres(x, leg, edges)
        d = target - centre
        for j, c in enumerate((0, 2)):
            x[leg, c] += blend[:, 0] * np.interp(x[leg, 1], centres, d[:, j])
    return x


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


def foot_top(body: Body) -> float | None:
    """Height (m) of the top of the feet: the highest point of the shins' surface more than ``FOOT_REACH``
    in front of their axis at its height, in their lower half (the instep); None if the body has no
    shins."""
    tops = []
    for side in ("l", "r"):
        k = _part(body, f"shin_{side}")
        if k is None:
            return None
        v = part_points(body, k)
        (_, y0, z0), (_, y1, z1) = body.part_axes[k]  # knee to ankle
        axis_z = z0 + (z1 - z0) * np.clip((v[:, 1] - y0) / (y1 - y0), 0.0, 1.0)
        ahead = (v[:, 2] - axis_z > FOOT_REACH) & (v[:, 1] < 0.5 * (y0 + y1))  # not the knee cap
        if ahead.any():
            tops.append(float(v[ahead, 1].max()))
    return max(tops) if tops else None


def clear_feet(x: np.ndarray, crotch: float, foot_y: float) -> np.ndarray:
    """A bottom's points (k, 3) whose legs reach below ``foot_y`` + ``FOOT_CLEARANCE`` (trousers made for a
    taller body, or whose hem lies on the floor) with the legs shortened from the crotch down, uniformly,
    so that the hem starts just above the feet: a hem placed through the feet starts with each foot
    through the leg's front (the springs across the instep, which growth cannot undo: no point is inside),
    and the foot keeps the leg caught. The legs' springs, compressed, lengthen again in the first steps,
    and the hem comes down around the foot. ``crotch``: its height (``garment_crotch``). Nothing changes
    for shorts."""
    target = foot_y + FOOT_CLEARANCE
    hem = float(x[:, 1].min())
    if hem >= target or crotch <= target:
        return x
    x = x.copy()
    legs = x[:, 1] < crotch
    x[legs, 1] = crotch - (crotch - x[legs, 1]) * (crotch - target) / (crotch - hem)
    return x


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


def arm_angle(body: Body, side: str) -> float:
    """Abduction of the upper arm (radians): its axis direction's angle from straight down, in x-y."""
    k = _part(body, f"upper_arm_{side}")
    d = body.part_axes[k, 1] - body.part_axes[k, 0]
    return float(np.arctan2(abs(d[0]), -d[1]))


def plan_arms(body: Body, x: np.ndarray, category: str, faces: np.ndarray | None = None,
              loops: list[np.ndarray] | None = None, piece: np.ndarray | None = None) -> ArmPlan:
    """Turns that put each arm along its sleeve, measured from the aligned garment points (k, 3).

    Sleeve points: points of the pieces over the shoulders (``faces`` (f, 3), if given, tells the pieces
    apart; a bottom has no sleeves) beyond ``SLEEVE_REACH`` x the torso half-width from the centre (past the
    bodice of a fitted top or dress), above the chest-to-waist mid level. The sleeve direction is from
    the shoulder joint to their centroid, in 3-D: a sleeve made on a body whose arms hang further forward
    (DiffAvatar's long-sleeve shirt: 9 cm in front of this body's arm at the cuff, with a 5 cm cuff
    radius) is missed by an arm turned only in the frontal plane, which then cuts through the sleeve's
    back and bunches it on the upper arm. The turn is about the axis normal to both the arm (shoulder to
    wrist) and the sleeve direction.

    A sleeve only a few degrees off the arm (under ``MIN_ARM_TURN``) is still turned if the arm would miss
    its cuff (``CUFF_MISS``): then the arm is aimed through the cuff's centre. ``loops``: the boundary loops
    of ``faces`` if known (``GarmentModel.coarse_loops``); ``piece`` (k,): the points'
    ``pieces.piece_labels`` if known.

    A long sleeve bent at the elbow (``bent_sleeve_turns``) is followed in two turns instead: the upper
    arm onto the sleeve's upper part, then the forearm about the elbow onto the sleeve's far opening; a
    straight arm turned at the shoulder only cuts through such a sleeve below the elbow.
    A sleeve made on arms hanging at the sides lies within the torso's width, with no points out there: the
    arm is aimed through its cuff (``hanging_cuff``), an opening on that side far below the shoulder joint.
    No sleeve (bottoms, too few points, or no opening out there: a sleeveless bodice wider than the body's
    shoulders, whose armhole is centred near the joint): no turn.
    """
    if category == "bottom":
        return ArmPlan(0.0, 0.0)
    lm = body_landmarks(body)
    upper = np.ones(len(x), dtype=np.bool_) if faces is None else ~bottom_mask(x, faces, category, piece)
    if loops is None:
        loops = boundary_loops(faces, len(x)) if faces is not None else []
    out, cuffs = {}, {}
    for side, sign, joint in (("l", 1.0, lm.shoulder_l), ("r", -1.0, lm.shoulder_r)):
        sel = upper & sleeve_mask(x, lm, sign)
        default_axis = (0.0, 0.0, sign)
        out[side] = (0.0, default_axis, 0.0, default_axis)
        cuffs[side] = None
        ends = sleeve_openings(x, lm, sign, loops, upper) if sel.sum() >= MIN_SLEEVE_POINTS else []
        if not ends and (faces is not None or sel.sum() < MIN_SLEEVE_POINTS):
            # no sleeve reaching out with an opening out there. Maybe the side of a bodice wider than the
            # body's shoulders (a dress two sizes too big), not a sleeve: turning the arm onto it would carry
            # the armhole down the arm. But a sleeve made on arms at the sides hangs beside the torso: the
            # arm is aimed through its cuff
            hanging = hanging_cuff(body, side, x, lm, sign, loops, upper)
            if hanging is not None:
                cuffs[side] = hanging
                turn, axis = _turn_between(arm_direction(body, side), x[hanging].mean(axis=0) - joint)
                out[side] = (turn, axis, 0.0, default_axis)
            continue
        if ends:
            cuffs[side] = far_opening(x, ends, joint)
        bent = bent_sleeve_turns(body, side, x, upper & sleeve_mask(x, lm, sign, RING_REACH), cuffs[side])
        if bent is not None:
            out[side] = bent
            continue
        sleeve = x[sel].mean(axis=0) - joint
        arm = arm_direction(body, side)
        if ends and _part(body, f"forearm_{side}") is not None:
            # a short sleeve (its cuff round the upper arm) is along the upper arm, however bent the elbow
            _, elbow, _ = arm_joints(body, side)
            if (x[cuffs[side]].mean(axis=0) - joint) @ (elbow - joint) < (elbow - joint) @ (elbow - joint):
                arm = (elbow - joint) / np.linalg.norm(elbow - joint)
        turn, axis = _turn_between(arm, sleeve)
        misses_cuff = False
        if ends:
            # the arm must go through the cuff: aim at the centre of the far opening if the arm misses it
            far = x[cuffs[side]]
            misses_cuff = arm_misses(far, joint, arm)
            if misses_cuff:
                turn, axis = _turn_between(arm, far.mean(axis=0) - joint)
        if misses_cuff or turn >= MIN_ARM_TURN:
            out[side] = (turn, axis, 0.0, default_axis)
    (lt, la, le, lea), (rt, ra, re, rea) = out["l"], out["r"]
    return ArmPlan(left=lt, right=rt, left_axis=la, right_axis=ra, left_elbow=le, right_elbow=re,
                   left_elbow_axis=lea, right_elbow_axis=rea, left_cuff=cuffs["l"], right_cuff=cuffs["r"])


def _turn_between(a: np.ndarray, b: np.ndarray) -> tuple[float, tuple[float, float, float]]:
    """Angle (radians) and unit axis of the shortest turn taking direction ``a`` (3,) to ``b`` (3,)."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    normal = np.cross(a, b)
    length = float(np.linalg.norm(normal))
    if length < 1e-9:
        return 0.0, (0.0, 0.0, 1.0)
    return float(np.arctan2(length, a @ b)), tuple(float(c) for c in normal / length)


def arm_joints(body: Body, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm's shoulder joint, elbow and wrist end (3,) each: the elbow halfway between the upper arm
    axis's end and the forearm axis's start (each runs past the joint into its rounded cap by the same
    length), the wrist end the forearm axis's end."""
    up = body.part_axes[_part(body, f"upper_arm_{side}")]
    fore = body.part_axes[_part(body, f"forearm_{side}")]
    return up[0].copy(), 0.5 * (up[1] + fore[0]), fore[1].copy()


def far_opening(x: np.ndarray, ends: list[np.ndarray], joint: np.ndarray) -> np.ndarray:
    """Of a sleeve's openings ``ends`` (index arrays into the points x (k, 3)), the one whose centre is
    farthest from the shoulder ``joint`` (3,): its cuff."""
    return max(ends, key=lambda loop: float(np.linalg.norm(x[loop].mean(axis=0) - joint)))


def bent_sleeve_turns(body: Body, side: str, x: np.ndarray, sleeve: np.ndarray, cuff_ids: np.ndarray | None
                      ) -> tuple[float, tuple, float, tuple] | None:
    """(shoulder turn, its axis, elbow turn, its axis in the arm's rest pose) that put the upper arm along
    the sleeve's upper part (the centroid of its points ``UPPER_SLEEVE`` of the upper arm's length from
    the shoulder joint) and then the forearm, turned about the elbow, through the centre of the sleeve's
    far opening ``cuff_ids`` (point ids; ``far_opening``, None if the sleeve has no opening); ``sleeve``
    (k,) bool marks the sleeve's points. None when the sleeve is not a long sleeve bent by
    ``MIN_ELBOW_TURN`` to ``MAX_ELBOW_TURN`` (then one shoulder turn along the whole sleeve is enough), or
    the body has no forearm."""
    if _part(body, f"forearm_{side}") is None:
        return None
    joint, elbow, wrist = arm_joints(body, side)
    upper_len = float(np.linalg.norm(elbow - joint))
    fore_len = float(np.linalg.norm(wrist - elbow))
    if cuff_ids is None:
        return None
    cuff = x[cuff_ids].mean(axis=0)
    r = np.linalg.norm(x - joint, axis=1)
    ring = sleeve & (r > UPPER_SLEEVE[0] * upper_len) & (r < UPPER_SLEEVE[1] * upper_len)
    if ring.sum() < MIN_SLEEVE_POINTS:
        return None
    turn, axis = _turn_between(elbow - joint, x[ring].mean(axis=0) - joint)
    rot = _rotation(np.asarray(axis), turn)
    posed_elbow = joint + rot @ (elbow - joint)
    if _off_segment(cuff, joint, posed_elbow) < FOREARM_SLEEVE * fore_len:
        return None
    bend, bend_axis = _turn_between(rot @ (wrist - elbow), cuff - posed_elbow)
    if not MIN_ELBOW_TURN <= bend <= MAX_ELBOW_TURN:
        return None
    rest_axis = tuple(float(c) for c in rot.T @ np.asarray(bend_axis))
    return turn, axis, bend, rest_axis


def _off_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) of the point p (3,) from the segment a-b (3,) each."""
    t = float(np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0))
    return float(np.linalg.norm(p - a - t * (b - a)))


def arm_direction(body: Body, side: str) -> np.ndarray:
    """(3,) unit direction from the shoulder joint to the wrist (the end of the forearm's axis, else of
    the upper arm's)."""
    k = _part(body, f"upper_arm_{side}")
    kf = _part(body, f"forearm_{side}")
    end = body.part_axes[kf, 1] if kf is not None else body.part_axes[k, 1]
    d = end - body.part_axes[k, 0]
    return d / np.linalg.norm(d)
