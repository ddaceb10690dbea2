"""The parametric NURBS body (SPEC section 2): measurements and pose in, a ``Body`` out.

``params`` (Measurements, Pose, ranges, estimates), ``nurbs`` (evaluation), ``shape`` (cross sections and
placement), ``build`` (``build_body``), ``measure`` (tape-measure girths), ``maps`` (OBBs, cylinder maps),
``survey`` (all people of an ANSUR II CSV through ``build_body``).
"""

from tryon.body.build import DEFAULT_RESOLUTION, build_body
from tryon.body.params import MEASUREMENT_RANGES, POSE_RANGES, Measurements, Pose
from tryon.body.types import PART_NAMES, Body

__all__ = ["DEFAULT_RESOLUTION", "MEASUREMENT_RANGES", "POSE_RANGES", "PART_NAMES", "Body", "Measurements", "Pose",
           "build_body"]
