"""The body's landmarks the alignment reads: shoulder, chest, waist, hip and crotch heights, the torso's centre
and width (``body_landmarks``), a part's points and the arm's joints. Metres, y up."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from tryon.body.types import Body

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


def part_index(body: Body, name: str) -> int | None:
    return body.parts.index(name) if name in body.parts else None


def body_landmarks(body: Body) -> BodyLandmarks:
    """Landmarks from the body's parts, axes and girth levels (estimated from the torso when absent)."""
    kt = part_index(body, "torso")
    torso_axis = body.part_axes[kt]
    y0, y1 = sorted((float(torso_axis[0, 1]), float(torso_axis[1, 1])))
    length = y1 - y0
    cx = float(torso_axis[:, 0].mean())
    kl, kr = part_index(body, "upper_arm_l"), part_index(body, "upper_arm_r")
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


def band_points(points: np.ndarray, y: float, cx: float, half_width: float, dy: float = 0.04) -> np.ndarray:
    sel = (np.abs(points[:, 1] - y) < dy) & (np.abs(points[:, 0] - cx) < half_width)
    return points[sel]


def hull_girth(points: np.ndarray) -> float:
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
    return part_points(body, part_index(body, "torso"))


def arm_joints(body: Body, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm's shoulder joint, elbow and wrist end (3,) each: the elbow halfway between the upper arm
    axis's end and the forearm axis's start (each runs past the joint into its rounded cap by the same
    length), the wrist end the forearm axis's end."""
    up = body.part_axes[part_index(body, f"upper_arm_{side}")]
    fore = body.part_axes[part_index(body, f"forearm_{side}")]
    return up[0].copy(), 0.5 * (up[1] + fore[0]), fore[1].copy()
