"""The Body: what the body stage hands to the simulation (see docs/ARCHITECTURE.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tryon.body.maps import PartMaps

PART_NAMES = (
    "head", "torso",
    "upper_arm_l", "upper_arm_r", "forearm_l", "forearm_r",
    "thigh_l", "thigh_r", "shin_l", "shin_r",
)


@dataclass(frozen=True)
class Body:
    """A built body. Metres, y up, feet on y = 0, facing +z, its left side towards +x.

    vertices (n, 3) float64; faces (f, 3) int32, counter-clockwise seen from outside.
    vertex_normals (n, 3), face_normals (f, 3): unit, outward.
    face_part (f,) int16: index into ``parts``.
    part_axes (P, 2, 3): each part's axis segment (start, end), metres.
    maps: per-part OBBs and cylinder maps for collision.
    requested / achieved: measurements in cm; levels: height (m) at which each girth was taken.
    estimated: the optional measurements that were not given and were estimated (cm).
    pose: the pose built, degrees (``Pose`` fields): the one asked for, except an arm angle too low for
    the arm to clear the torso, which is raised to where the arm rests against it.
    joints: the skeleton's joints (3,) m: ``shoulder_l``, ``elbow_l``, ``wrist_l``, ``hip_l``, ``knee_l`` and
    the same ``_r`` (the wrist is the joint, where the hand turns, not the end of the hand).
    resolution: the ``build_body`` resolution it was built at (None: not built by it, a test's or a scene's).
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray
    face_normals: np.ndarray
    face_part: np.ndarray
    parts: tuple[str, ...]
    part_axes: np.ndarray
    maps: PartMaps
    requested: dict
    achieved: dict
    levels: dict
    estimated: dict = field(default_factory=dict)
    pose: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    resolution: int | None = None

    @property
    def hands_turned(self) -> bool:
        """Whether either hand is turned at the wrist (``wrist_bend``)."""
        return bool(self.pose.get("wrist_bend_left") or self.pose.get("wrist_bend_right"))

    @property
    def vertex_part(self) -> np.ndarray:
        """(n,) int64: the part (``parts`` index) of every vertex, that of the last face using it."""
        out = np.zeros(len(self.vertices), dtype=np.int64)
        out[self.faces.reshape(-1)] = np.repeat(self.face_part, 3)
        return out
