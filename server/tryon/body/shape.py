"""Cross-section profiles of the body parts, driven by the measurements, and the pose placement.

Each part is described, in its own local frame, by a list of planar cross sections ("stations") at local
height y, from one closed end (a pole) to the other. A section is two rational quadratic halves (see
``nurbs.py``): half-width ``a`` either side of the centre (cx, cz), front depth ``f`` (+z), back depth ``b``,
corner weights ``wf`` / ``wb`` (sqrt(2)/2 = ellipse, larger = squarer). The limbs' local frames have their
axis along local +y from the proximal joint to the distal end; a rigid rotation and translation puts them
in the world. The torso and the head are built directly in the world frame (y up, facing +z).

Landmark heights are fractions of stature H taken from the ANSUR II summary statistics (Gordon et al.
2014, mean landmark height / mean stature, rounded): waist at omphalion 0.60 H, chest at nipple / bust
point 0.72 H, axilla 0.75 H, acromion 0.818 H, chin 0.87 H, knee joint 0.275 H; crotch height is the inseam.
Section proportions (breadth / girth about 0.33-0.34, depth / girth 0.24-0.27) are typical of the same
survey's breadth and depth measurements; the exact girths are then imposed by ``build.py``, which scales
the measured sections, so these ratios only shape the body.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from tryon.body.kernels import hull_perimeter_2d
from tryon.body.nurbs import ELLIPSE_WEIGHT, ring_controls, ring_matrix, sample_rings
from tryon.body.params import Measurements, Pose, complete

# Station table columns.
Y, A, F, B, CX, CZ, WF, WB = range(8)

# The six distinct part shapes; the right limbs are mirror images of the left ones.
SHAPE_NAMES = ("head", "torso", "upper_arm", "forearm", "thigh", "shin")

# Station index (in the tables of ``body_layout``) of each section the body is measured on; the mesh
# has a row exactly there. shoulder_width is a breadth (the torso's width at acromion level), the others girths.
MEASURED_STATIONS = {
    "torso": {"hips": 3, "waist": 5, "chest": 7, "shoulder_width": 9},
    "head": {"neck": 3},
    "upper_arm": {"upper_arm": 3},
    "thigh": {"thigh": 3},
}

ROUND = ELLIPSE_WEIGHT  # corner weight of an elliptic section
SQUARE = 0.85  # corner weight of a squarer section (torso, shoulders): flatter sides, fuller corners


@dataclass(frozen=True)
class PartShape:
    """One part in its local frame, and where the frame sits in the world.

    stations: (n, 8) float64, columns y, a, f, b, cx, cz, wf, wb (metres, weights unitless).
    rotation: (3, 3) local -> world; origin: (3,) metres. world = rotation @ local + origin.
    measured: measurement name -> station index whose section is that girth (scaled to it exactly).
    tilt: (n,) radians each station's section is turned about the local z axis through ``pivot`` (3,),
    local metres: the feet stay flat on the floor when the legs are spread.
    """

    stations: np.ndarray
    rotation: np.ndarray
    origin: np.ndarray
    measured: dict
    tilt: np.ndarray | None = None
    pivot: np.ndarray | None = None


def _station(y, a, f, b, cz=0.0, wf=ROUND, wb=ROUND, cx=0.0):
    return (y, a, f, b, cx, cz, wf, wb)


def _pole(y, cz=0.0, cx=0.0):
    return (y, 0.0, 0.0, 0.0, cx, cz, 1.0, 1.0)


def _ring(y, r, sa=1.0, sf=1.0, sb=1.0, cz=0.0, wf=ROUND, wb=ROUND):
    """Section of 'radius' r with per-direction factors."""
    return (y, r * sa, r * sf, r * sb, 0.0, cz, wf, wb)


@lru_cache(maxsize=4096)
def fitted_section(a: float, f: float, b: float, wf: float, wb: float, girth: float) -> tuple[float, float, float]:
    """(a, f, b) scaled so that the section's convex hull perimeter is ``girth`` (m), measured on a fine
    sampling. Placing the limbs against sections of the right size; ``build.py`` then makes the girth
    exact for the mesh's own sampling."""
    one = np.ones(1)
    ctrl = ring_controls(0 * one, a * one, f * one, b * one, 0 * one, 0 * one, wf * one, wb * one)
    pts = sample_rings(ctrl, ring_matrix(129))[0]
    k = girth / hull_perimeter_2d(np.ascontiguousarray(pts[:, [0, 2]]))
    return a * k, f * k, b * k


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_axis(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about unit ``axis`` by ``angle`` radians (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


@dataclass(frozen=True)
class BodyLayout:
    """The six part shapes plus skeleton landmarks (world, metres, before the final floor/stretch)."""

    parts: dict
    landmarks: dict


def body_layout(m: Measurements, pose: Pose, leg_scale: float = 1.0, side: str = "left") -> BodyLayout:
    """Stations and placements of head, torso and the left limbs for measurements ``m`` (cm) in ``pose``,
    the limbs posed with the angles of ``side`` ("left" | "right": ``build.py`` mirrors the right side's
    limbs, x -> -x; head and torso do not depend on the pose).

    leg_scale: factor on the thigh and shin lengths, which ``build.py`` solves for so that the soles
    reach the floor from the hip joints' height (spread legs need longer legs to keep the crotch height
    and the stature; the cubic sole cap also reaches a few millimetres below its pole)."""
    m = complete(m)
    limb = pose.side(side)
    H = m.height / 100.0
    C, W, P = m.chest / 100.0, m.waist / 100.0, m.hips / 100.0
    S, N, T, U = m.shoulder_width / 100.0, m.neck / 100.0, m.thigh / 100.0, m.upper_arm / 100.0
    L_arm, I = m.arm_length / 100.0, m.inseam / 100.0
    hs = H / 1.75  # size of hands and feet relative to a 1.75 m adult
    head_s = np.sqrt(H / 1.75)  # head size varies less than stature

    # ---- torso (world frame) ----------------------------------------------------------------------------
    y_c = I
    y_w = 0.600 * H
    y_h = y_c + min(0.045 * H, 0.45 * (y_w - y_c))  # greatest buttock protrusion, just above the crotch
    y_ch = 0.720 * H
    y_ax = 0.750 * H
    y_ac = 0.818 * H
    y_nb = 0.843 * H
    y_tp = 0.855 * H
    r_n = N / (2.0 * np.pi)

    belly = np.clip(W / P - 0.85, 0.0, 0.3)  # a waist large for the hips is a belly: deeper in front
    a_h, f_h, b_h = fitted_section(0.170 * P, (0.095 + 0.2 * belly) * P, 0.150 * P, 0.8, 0.8, P)  # belly down to here
    a_w, f_w, b_w = fitted_section(0.165 * W, (0.125 + 0.2 * belly) * W, 0.110 * W, 0.8, 0.8, W)
    a_c, f_c, b_c = fitted_section(0.170 * C, 0.125 * C, 0.120 * C, 0.8, SQUARE, C)
    t_belly = min(0.5 + 1.5 * belly, 0.9)  # a belly hangs: the front below the navel stays full
    cz_w = -0.72 * b_h + b_w  # lumbar curve: the back at the waist 28 % of the buttock depth forward
    cz_c = -0.92 * b_h + b_c  # shoulder blades almost in line with the buttocks
    cz_ac = cz_c - 0.25 * b_c  # shoulders sit back
    # Every part's poles lie on one line perpendicular to its sections: its axis (``part_axes``). Each
    # section then surrounds the axis, so the part is a radial function r(theta, z) about it, which is
    # what a cylinder map assumes (SPEC section 4).
    z_axis = cz_ac + 0.01  # the centre of the neck-base section
    torso = np.array([
        _pole(y_c, cz=z_axis),
        # below the hips the thighs carry the width: the torso closes towards the crotch
        _station(y_c + 0.2 * (y_h - y_c), 0.45 * a_h, 0.55 * f_h, 0.65 * b_h, cz=z_axis, wf=SQUARE, wb=SQUARE),
        _station(y_c + 0.55 * (y_h - y_c), 0.80 * a_h, 0.86 * f_h, 0.92 * b_h, cz=0.5 * z_axis, wf=SQUARE,
                 wb=SQUARE),
        _station(y_h, a_h, f_h, b_h, wf=0.8, wb=0.8),
        _station(0.5 * (y_h + y_w), 0.5 * (a_h + a_w), f_h + t_belly * (f_w - f_h), 0.5 * (b_h + b_w),
                 cz=0.5 * cz_w, wf=0.8, wb=0.8),
        _station(y_w, a_w, f_w, b_w, cz=cz_w, wf=0.8, wb=0.8),
        _station(0.5 * (y_w + y_ch), 0.49 * (a_w + a_c), 0.48 * (f_w + f_c), 0.5 * (b_w + b_c),
                 cz=0.5 * (cz_w + cz_c), wf=0.8, wb=0.8),
        _station(y_ch, a_c, f_c, b_c, cz=cz_c, wf=0.8, wb=SQUARE),
        _station(y_ax, a_c, 0.92 * f_c, b_c, cz=cz_c, wf=0.8, wb=SQUARE),
        _station(y_ac, 0.5 * S, 0.55 * f_c, 0.62 * b_c, cz=cz_ac, wf=SQUARE, wb=SQUARE),
        # trapezius: the shoulder line rises from the acromion to the side of the neck
        _station(y_ac + 0.55 * (y_nb - y_ac), 0.25 * S + 0.65 * r_n, 0.275 * f_c + 0.6 * r_n,
                 0.31 * b_c + 0.6 * r_n, cz=cz_ac + 0.005, wf=SQUARE, wb=SQUARE),
        _station(y_nb, 1.3 * r_n, 1.15 * r_n, 1.15 * r_n, cz=cz_ac + 0.01, wf=SQUARE, wb=SQUARE),
        _pole(y_tp, cz=z_axis),
    ])

    # ---- head and neck (world frame) --------------------------------------------------------------------
    hh = 0.13 * H  # chin to vertex
    y_chin = H - hh
    y_neck = max(y_chin - 0.025 * head_s, y_tp + 0.005)  # below the larynx, above the torso
    cz_n = cz_ac + 0.01
    cz_f = cz_n + 0.025 * head_s  # the skull sits forward of the neck
    z_head = cz_n
    hsz = head_s
    head = np.array([
        _pole(y_ac - 0.03, cz=z_head),
        _ring(y_ac - 0.03 + 0.4 * 0.018, 0.8 * 1.12 * r_n, cz=cz_n),  # rounded cap (sphere: 0.8 r at 0.4 r)
        _ring(y_ac - 0.012, 1.12 * r_n, cz=cz_n),
        _ring(y_neck, r_n, cz=cz_n),
        _station(y_chin + 0.02 * hh, 0.056 * hsz, 0.085 * hsz, 0.050 * hsz, cz=cz_f),
        _station(y_chin + 0.17 * hh, 0.064 * hsz, 0.095 * hsz, 0.065 * hsz, cz=cz_f),
        _station(y_chin + 0.35 * hh, 0.072 * hsz, 0.100 * hsz, 0.085 * hsz, cz=cz_f),
        _station(y_chin + 0.52 * hh, 0.076 * hsz, 0.095 * hsz, 0.097 * hsz, cz=cz_f),
        _station(y_chin + 0.70 * hh, 0.073 * hsz, 0.086 * hsz, 0.097 * hsz, cz=cz_f),
        _station(y_chin + 0.88 * hh, 0.057 * hsz, 0.060 * hsz, 0.075 * hsz, cz=cz_f),
        _pole(H, cz=z_head),
    ])

    # ---- arms (left arm, local frames, axis along local +y) ---------------------------------------------
    r_u = U / (2.0 * np.pi)
    r_d = 1.12 * r_u  # deltoid
    cap = min(0.95 * r_d, 0.045 * hs)  # the top of the arm reaches just above the acromion, not higher
    r_e = 0.82 * r_u  # elbow
    r_fa = 0.88 * r_u  # forearm, widest
    L1 = 0.56 * L_arm  # acromion to elbow (ANSUR II sample: 0.52-0.60 of the arm, mean 0.56)
    L2 = L_arm - L1
    acromion = np.array([0.5 * S, y_ac, cz_ac])
    joint = acromion + np.array([-0.018 * hs, -0.04 * hs, 0.0])  # glenohumeral centre
    # the upper arm: hanging (local +y down), abducted about z, swung forwards about x, turned about its axis
    alpha = np.radians(limb.arm_angle)
    rot_ua = (rot_x(-np.radians(limb.arm_forward)) @ rot_z(np.pi + alpha)
              @ rot_y(np.radians(limb.arm_rotation)))
    d_ua = rot_ua[:, 1]
    # distance joint -> elbow such that |acromion -> elbow| = L1
    o = acromion - joint
    do = float(d_ua @ o)
    l_ua = do + np.sqrt(max(do * do - o @ o + L1 * L1, 1e-9))
    elbow = joint + l_ua * d_ua
    upper_arm = np.array([
        _pole(-cap),
        _ring(-0.6 * cap, 0.8 * r_d),
        _ring(0.0, r_d, sa=0.95),
        _ring(0.5 * l_ua, r_u, sa=0.9, sf=1.05, sb=1.05),
        _ring(0.85 * l_ua, 0.86 * r_u),
        _ring(l_ua, r_e, sa=0.95),
        _ring(l_ua + 0.5 * r_e, 0.85 * r_e),
        _pole(l_ua + 0.9 * r_e),
    ])
    # the elbow bends about the upper arm's local x axis (unturned: forwards; turned 90 degrees: across)
    beta = np.radians(limb.elbow_bend)
    flex_axis = rot_ua[:, 0]
    rot_fa = rot_axis(flex_axis, beta) @ rot_ua
    d_fa = rot_fa[:, 1]
    wrist = elbow + L2 * d_fa
    forearm = np.array([
        _pole(-0.9 * r_e),
        _ring(-0.5 * r_e, 0.85 * r_e),
        _ring(0.0, r_e),
        _ring(0.25 * L2, r_fa, sa=0.95),
        _ring(0.65 * L2, 0.72 * r_fa, sa=0.9),
        _ring(L2, r_u, sa=0.38, sf=0.6, sb=0.6),  # wrist: flat, wide across the palm (local z)
        _station(L2 + 0.045 * hs, 0.016 * hs, 0.044 * hs, 0.044 * hs, wf=SQUARE, wb=SQUARE),
        _station(L2 + 0.10 * hs, 0.012 * hs, 0.041 * hs, 0.041 * hs, wf=SQUARE, wb=SQUARE),
        _station(L2 + 0.16 * hs, 0.009 * hs, 0.032 * hs, 0.032 * hs),
        _pole(L2 + 0.19 * hs),
    ])
    # the hand turned at the wrist: its sections about the local z axis through the wrist (flexion towards
    # the palm, which faces local +x: a hanging arm's palm faces the thigh), half of it at the wrist itself
    omega = np.radians(limb.wrist_bend)
    hand_tilt = -omega * np.array([0, 0, 0, 0, 0, 0.5, 1, 1, 1, 1]) if omega else None

    # ---- legs (left leg, local frames) ------------------------------------------------------------------
    r_t = fitted_section(0.9, 1.0, 1.1, ROUND, ROUND, T)[0] / 0.9  # the thigh section below: (0.9, 1, 1.1) r_t
    r_k = 0.62 * r_t  # knee
    r_c = 0.60 * r_t  # calf
    y_k = 0.275 * H
    # hip joint: the thigh's section at hip level (half-width 0.85 r_t) stays 1 cm inside the hips' side;
    # a spread leg swings its upper outer side up to hip level, so the joint moves in by r_t sin(spread)
    # to keep the thighs inside the hip tape (the flesh of a real hip gives way the same)
    gamma = np.radians(limb.leg_spread)
    hip_joint = np.array([min(0.5 * a_h, a_h - 0.85 * r_t - 0.01) - r_t * np.sin(gamma), y_h, 0.0])
    rot_leg = rot_z(np.pi + gamma)
    d_leg = rot_leg[:, 1]
    l_th = (y_h - y_k) * leg_scale
    knee = hip_joint + l_th * d_leg
    s_g = (y_h - y_c) + 0.02 * hs  # thigh girth just below the buttock crease
    thigh = np.array([
        _pole(-0.5 * r_t),
        _ring(-0.3 * r_t, 0.6 * r_t, sa=0.85),
        _ring(0.0, r_t, sa=0.85, sf=0.8, sb=0.95),  # inside the torso at hip level, flush at its side
        _ring(s_g, r_t, sa=0.9, sf=1.0, sb=1.1),
        _ring(s_g + 0.45 * (l_th - s_g), 0.82 * r_t, sa=0.92),
        _ring(l_th - 0.06 * hs, 0.66 * r_t, sa=0.95),
        _ring(l_th, r_k),
        _ring(l_th + 0.5 * r_k, 0.85 * r_k),
        _pole(l_th + 0.9 * r_k),
    ])
    l_sh = y_k * leg_scale  # knee to sole
    shin = np.array([
        _pole(-0.9 * r_k),
        _ring(-0.5 * r_k, 0.85 * r_k),
        _ring(0.0, r_k, sa=0.95),
        _ring(0.28 * l_sh, r_c, sa=0.85, sf=0.8, sb=1.15),
        _ring(0.62 * l_sh, 0.72 * r_c, sa=0.95, sf=0.9, sb=1.05),
        _station(l_sh - 0.075 * hs, 0.032 * hs, 0.034 * hs, 0.034 * hs),  # ankle
        _station(l_sh - 0.045 * hs, 0.041 * hs, 0.090 * hs, 0.050 * hs, cz=0.015 * hs),
        _station(l_sh - 0.018 * hs, 0.046 * hs, 0.170 * hs, 0.058 * hs, cz=0.015 * hs, wf=SQUARE),
        _pole(l_sh),
    ])

    eye = np.eye(3)
    zero = np.zeros(3)
    parts = {
        "head": PartShape(head, eye, zero, MEASURED_STATIONS["head"]),
        "torso": PartShape(torso, eye, zero, MEASURED_STATIONS["torso"]),
        "upper_arm": PartShape(upper_arm, rot_ua, joint, MEASURED_STATIONS["upper_arm"]),
        "forearm": PartShape(forearm, rot_fa, elbow, {}, tilt=hand_tilt, pivot=np.array([0.0, L2, 0.0])),
        "thigh": PartShape(thigh, rot_leg, hip_joint, MEASURED_STATIONS["thigh"]),
        "shin": PartShape(shin, rot_leg, knee, {}, tilt=np.array([0, 0, 0, 0, 0, -0.5, -1, -1, -1]) * gamma,
                          pivot=np.array([0.0, l_sh - 0.075 * hs, 0.0])),
    }
    landmarks = {
        "acromion": acromion, "shoulder_joint": joint, "elbow": elbow, "wrist": wrist,
        "hip_joint": hip_joint, "knee": knee, "crotch": np.array([0.0, y_c, 0.1 * b_h]),
        "levels": {"hips": y_h, "waist": y_w, "chest": y_ch, "acromion": y_ac, "neck": y_neck},
    }
    return BodyLayout(parts, landmarks)


# A mid-range adult whose station spacing fixes each part's station parameters (see ``station_params``).
REFERENCE = Measurements(height=172.0, chest=100.0, waist=88.0, hips=101.0)


@lru_cache(maxsize=1)
def station_params() -> dict[str, tuple[float, ...]]:
    """Fixed v parameter of every station of every part, in [0, 1].

    Chord length along the reference body's profile: the step between two stations is the largest
    displacement of the section's four extreme points (left, right, front, back), so that uniform samples
    in v are roughly evenly spaced on the surface and the cubic interpolation does not overshoot where a
    section moves sideways (chin over the neck, toes over the ankle). Fixed per part (not per person) so
    that the basis matrices can be cached per resolution."""
    layout = body_layout(REFERENCE, Pose())
    out = {}
    for name, part in layout.parts.items():
        st = part.stations
        extremes = np.stack([st[:, CX] - st[:, A], st[:, CX] + st[:, A], st[:, CZ] + st[:, F],
                             st[:, CZ] - st[:, B]], axis=1)
        step = np.hypot(np.diff(st[:, Y]), np.abs(np.diff(extremes, axis=0)).max(axis=1))
        t = np.concatenate([[0.0], np.cumsum(step)])
        out[name] = tuple(float(v) for v in t / t[-1])
    return out
