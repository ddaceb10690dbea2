"""Body parameters: measurements (cm) and pose (degrees), their ranges, and estimates of the optional ones.

The API speaks centimetres; ``build_body`` converts to metres. Ranges cover every person of the ANSUR II
sample (300 people, 150 men and 150 women; see the range comments) with a margin, so that real people of
other populations still fit.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass, fields, replace

# Every field: (min, max) in cm. Required: height, chest, waist, hips. The ANSUR II sample spans
# height 147.5-196.6, chest 78.3-125.2, waist 65.6-133.4, hips 84.7-130.6, biacromial breadth 31.2-45.0,
# arm length (acromion-radiale + radiale-stylion) 46.2-70.2, crotch height 66.5-95.9, neck 29.4-45.5,
# thigh 49.5-87.0, flexed biceps 23.8-45.6 (cm).
MEASUREMENT_RANGES: dict[str, tuple[float, float]] = {
    "height": (140.0, 210.0),
    "chest": (70.0, 150.0),
    "waist": (55.0, 150.0),
    "hips": (75.0, 150.0),
    "shoulder_width": (26.0, 55.0),
    "arm_length": (40.0, 80.0),
    "inseam": (55.0, 110.0),
    "neck": (25.0, 56.0),
    "thigh": (40.0, 100.0),
    "upper_arm": (18.0, 56.0),
}

MEASUREMENT_DESCRIPTIONS: dict[str, str] = {
    "height": "stature, floor to the top of the head, cm",
    "chest": "chest girth at nipple (bust-point) level, tape on the skin, cm",
    "waist": "waist girth at navel (omphalion) level, not the narrowest girth, cm",
    "hips": "hip girth at the level of greatest buttock protrusion, cm",
    "shoulder_width": "biacromial breadth, straight line between the two shoulder tips (acromions), cm",
    "arm_length": "acromion (shoulder tip) to wrist, along the straight arm, cm",
    "inseam": "crotch height, floor to crotch, standing, cm",
    "neck": "neck girth just below the larynx, cm",
    "thigh": "upper thigh girth just below the buttock crease, cm",
    "upper_arm": "upper-arm girth over the biceps (ANSUR II takes it flexed; the body is built with it), cm",
}

# Ratios that a plausible body keeps (cross-field sanity). The ANSUR II sample spans
# inseam/height 0.444-0.525, arm_length/height 0.309-0.374, thigh/hips 0.539-0.669, waist/chest
# 0.755-1.149, waist/hips 0.733-1.061, chest/hips 0.791-1.168, shoulder_width/chest 0.301-0.476,
# neck/chest 0.293-0.424, upper_arm/chest 0.266-0.392; the bounds add a wide margin.
RATIO_BOUNDS: dict[tuple[str, str], tuple[float, float]] = {
    ("inseam", "height"): (0.38, 0.56),
    ("arm_length", "height"): (0.26, 0.43),
    ("thigh", "hips"): (0.40, 0.80),
    ("waist", "chest"): (0.55, 1.50),
    ("waist", "hips"): (0.55, 1.40),
    ("chest", "hips"): (0.60, 1.50),
    ("shoulder_width", "chest"): (0.22, 0.60),
    ("neck", "chest"): (0.22, 0.55),
    ("upper_arm", "chest"): (0.18, 0.50),
}

# Least-squares fits over the 300 people of the ANSUR II sample (cm):
#   optional = c0 + c_h * height + c_c * chest + c_w * waist + c_p * hips.
# Residual RMS / max over the sample: shoulder_width 1.75 / 5.95, arm_length 1.81 / 5.41,
# inseam 2.35 / 6.83, neck 1.83 / 6.84, thigh 2.03 / 8.16, upper_arm 2.13 / 6.42 cm. Lengths follow
# height (arm 0.38 cm/cm, inseam 0.59 cm/cm), girths follow the nearest required girth (thigh 0.65 hips,
# neck and upper arm about 0.26 chest), which is what one expects anatomically.
OPTIONAL_FITS: dict[str, tuple[float, float, float, float, float]] = {
    "shoulder_width": (-2.8817, 0.2124, 0.1544, -0.0450, -0.0544),
    "arm_length": (-6.7200, 0.3846, 0.0012, 0.0110, -0.0149),
    "inseam": (-11.1861, 0.5875, -0.0569, -0.0120, 0.0013),
    "neck": (-3.1196, 0.1637, 0.2563, 0.0559, -0.1864),
    "thigh": (-5.0403, -0.0247, 0.0294, 0.0226, 0.6492),
    "upper_arm": (-12.4362, 0.0902, 0.2652, 0.0085, 0.0286),
}

REQUIRED = ("height", "chest", "waist", "hips")
OPTIONAL = ("shoulder_width", "arm_length", "inseam", "neck", "thigh", "upper_arm")

# Angles, degrees, each limb on its own (``_left`` / ``_right``: the body's left is towards +x).
# arm_angle: the upper arm's abduction, between it and the side of the torso in the frontal plane (0 =
# hanging down, 90 = T-pose; ``build_body`` raises an angle at which the arm would pass into the torso to
# where it rests against it). arm_forward: the arm so abducted then swung forwards and up about the
# shoulders' left-right axis (flexion; 90 = horizontal; it turns a T-pose arm about its own axis only).
# arm_rotation: the upper arm turned about its own axis (internal rotation; 90 = the elbow bends the forearm
# across the body instead of forwards, as for hands on hips; negative: external, the forearm bends up).
# elbow_bend: forearm flexion (0 = straight). wrist_bend: the hand turned at the wrist towards the palm
# (flexion), negative towards the back of the hand. leg_spread: the leg's abduction from vertical.
POSE_RANGES: dict[str, tuple[float, float]] = {
    "arm_angle_left": (0.0, 90.0), "arm_angle_right": (0.0, 90.0),
    "arm_forward_left": (0.0, 90.0), "arm_forward_right": (0.0, 90.0),
    "arm_rotation_left": (-90.0, 90.0), "arm_rotation_right": (-90.0, 90.0),
    "elbow_bend_left": (0.0, 120.0), "elbow_bend_right": (0.0, 120.0),
    "wrist_bend_left": (-90.0, 90.0), "wrist_bend_right": (-90.0, 90.0),
    "leg_spread_left": (0.0, 20.0), "leg_spread_right": (0.0, 20.0),
}
# The symmetric shorthand: one value for both sides of a joint (the fields before per-side poses).
POSE_SHORTHAND: dict[str, tuple[str, str]] = {
    name: (f"{name}_left", f"{name}_right")
    for name in ("arm_angle", "arm_forward", "arm_rotation", "elbow_bend", "wrist_bend", "leg_spread")
}
_JOINT_DESCRIPTIONS = {
    "arm_angle": "angle between the upper arm and the side of the torso, frontal plane (abduction), degrees "
                 "(0 = hanging, 90 = T-pose; raised, if lower, to where the arm rests against the torso)",
    "arm_forward": "the abducted arm swung forwards and up about the shoulders' left-right axis (flexion), "
                   "degrees (0 = in the frontal plane, 90 = horizontal)",
    "arm_rotation": "upper arm turned about its own axis (internal rotation), degrees: 0 = the elbow bends the "
                    "forearm forwards, 90 = across the body (hands on hips), -90 = upwards",
    "elbow_bend": "elbow flexion, degrees (0 = straight arm)",
    "wrist_bend": "hand turned at the wrist, degrees: towards the palm (flexion) positive, towards the back of "
                  "the hand negative",
    "leg_spread": "abduction of the leg from vertical, degrees",
}
POSE_DESCRIPTIONS: dict[str, str] = {
    **{f"{joint}_{side}": f"{side} {text}" for joint, text in _JOINT_DESCRIPTIONS.items()
       for side in ("left", "right")},
    **{joint: f"both sides at once (shorthand for {joint}_left and {joint}_right): {text}"
       for joint, text in _JOINT_DESCRIPTIONS.items()},
}


@dataclass(frozen=True)
class Pose:
    """Pose angles in degrees, each side its own (``POSE_RANGES``). The default A-pose keeps the arms clear
    of the torso below the armpit (30 degrees) and the knees apart (3 degrees per leg), as garments need.

    The symmetric shorthand (``arm_angle=40``, ... : ``POSE_SHORTHAND``) sets both sides of a joint and wins
    over the side fields given with it: ``Pose(arm_angle=40)``, ``replace(pose, elbow_bend=90)``."""

    arm_angle_left: float = 30.0
    arm_angle_right: float = 30.0
    arm_forward_left: float = 0.0
    arm_forward_right: float = 0.0
    arm_rotation_left: float = 0.0
    arm_rotation_right: float = 0.0
    elbow_bend_left: float = 0.0
    elbow_bend_right: float = 0.0
    wrist_bend_left: float = 0.0
    wrist_bend_right: float = 0.0
    leg_spread_left: float = 3.0
    leg_spread_right: float = 3.0
    arm_angle: InitVar[float | None] = None
    arm_forward: InitVar[float | None] = None
    arm_rotation: InitVar[float | None] = None
    elbow_bend: InitVar[float | None] = None
    wrist_bend: InitVar[float | None] = None
    leg_spread: InitVar[float | None] = None

    def __post_init__(self, *shorthand):
        for (left, right), value in zip(POSE_SHORTHAND.values(), shorthand):
            if value is not None:
                object.__setattr__(self, left, float(value))
                object.__setattr__(self, right, float(value))

    def as_dict(self) -> dict[str, float]:
        """Every side field, degrees (``POSE_RANGES`` order)."""
        return {name: float(getattr(self, name)) for name in POSE_RANGES}

    def side(self, side: str) -> "SidePose":
        """The angles of one side (``"left"`` | ``"right"``)."""
        return SidePose(**{joint: float(getattr(self, f"{joint}_{side}")) for joint in POSE_SHORTHAND})


@dataclass(frozen=True)
class SidePose:
    """One side's limb angles, degrees (the ``Pose`` fields of that side, without the suffix)."""

    arm_angle: float
    arm_forward: float
    arm_rotation: float
    elbow_bend: float
    wrist_bend: float
    leg_spread: float


def _named(**angles: float) -> dict[str, float]:
    return Pose(**angles).as_dict()


# Named poses the API and the page both know (the page lists them in this order), every side field given.
# hands_on_hips: elbows out, the forearms turned across the body onto the hips and the hands turned forwards
# at the wrist; the body lowers nothing: an arm that would press into the torso is raised (``build_body``)
# until the hand rests on the hip. arms_raised: upper arms level, forearms up. stride: a wide stance with
# the arms swung, one forwards (the legs have no forward swing in this model).
NAMED_POSES: dict[str, dict[str, float]] = {
    "a_pose": _named(),
    "arms_down": _named(arm_angle=0.0, leg_spread=1.0),
    "hands_on_hips": _named(arm_angle=38.0, arm_rotation=80.0, elbow_bend=100.0, wrist_bend=-90.0),
    "arms_raised": _named(arm_angle=90.0, arm_rotation=-90.0, elbow_bend=90.0),
    "stride": _named(arm_angle_left=20.0, arm_angle_right=25.0, arm_forward_left=35.0, elbow_bend_left=20.0,
                     elbow_bend_right=10.0, leg_spread_left=14.0, leg_spread_right=10.0),
}
NAMED_POSE_DESCRIPTIONS: dict[str, str] = {
    "a_pose": "arms 30 degrees out, legs slightly apart (the default)",
    "arms_down": "arms hanging, resting against the torso",
    "hands_on_hips": "elbows out, hands on the hips",
    "arms_raised": "upper arms level, forearms up",
    "stride": "a wide stance, the left arm swung forwards",
}


def pose_from(value: str | dict | Pose | None) -> Pose:
    """A ``Pose`` from a named pose (``NAMED_POSES``), a dict of angles (side fields and / or shorthand)
    or a ``Pose``; None: the default. Raises ValueError naming the known poses for an unknown name."""
    if value is None:
        return Pose()
    if isinstance(value, Pose):
        return value
    if isinstance(value, str):
        if value not in NAMED_POSES:
            raise ValueError(f"unknown pose '{value}': the named poses are {', '.join(NAMED_POSES)}")
        return Pose(**NAMED_POSES[value])
    return Pose(**value)


@dataclass(frozen=True)
class Measurements:
    """Body measurements in cm. The four girths and height are required; the others are estimated
    from them (``OPTIONAL_FITS``) when None."""

    height: float
    chest: float
    waist: float
    hips: float
    shoulder_width: float | None = None
    arm_length: float | None = None
    inseam: float | None = None
    neck: float | None = None
    thigh: float | None = None
    upper_arm: float | None = None

    def as_dict(self) -> dict[str, float | None]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def estimate_optional(name: str, height: float, chest: float, waist: float, hips: float) -> float:
    """ANSUR II least-squares estimate (cm) of optional measurement ``name`` from the required ones,
    clipped to its range."""
    c0, ch, cc, cw, cp = OPTIONAL_FITS[name]
    value = c0 + ch * height + cc * chest + cw * waist + cp * hips
    lo, hi = MEASUREMENT_RANGES[name]
    return min(max(value, lo), hi)


def complete(m: Measurements) -> Measurements:
    """``m`` with every optional measurement filled in (estimated where None)."""
    updates = {
        name: estimate_optional(name, m.height, m.chest, m.waist, m.hips)
        for name in OPTIONAL if getattr(m, name) is None
    }
    return replace(m, **updates)


def check_measurements(m: Measurements) -> list[str]:
    """Problems with ``m`` as messages naming the field and the allowed range (empty list: valid).
    Checks every given field against ``MEASUREMENT_RANGES`` and the ratios in ``RATIO_BOUNDS``
    (estimated optional fields are not checked against ratios: the fits keep them plausible)."""
    problems = []
    for name, value in m.as_dict().items():
        if value is None:
            continue
        lo, hi = MEASUREMENT_RANGES[name]
        if not lo <= value <= hi:
            problems.append(f"{name}={value:g} cm is outside [{lo:g}, {hi:g}] cm")
    if problems:
        return problems
    for (a, b), (lo, hi) in RATIO_BOUNDS.items():
        va, vb = getattr(m, a), getattr(m, b)
        if va is None or vb is None:
            continue
        ratio = va / vb
        if not lo <= ratio <= hi:
            problems.append(
                f"{a}/{b} = {va:g}/{vb:g} = {ratio:.3f} is implausible: it must be within [{lo:g}, {hi:g}] "
                f"(so {a} within [{lo * vb:.1f}, {hi * vb:.1f}] cm for {b}={vb:g} cm)"
            )
    return problems


def check_pose(p: Pose) -> list[str]:
    """Problems with ``p`` as messages naming the field and the range (empty list: valid)."""
    problems = []
    for name, (lo, hi) in POSE_RANGES.items():  # the shorthand is in the side fields already
        value = getattr(p, name)
        if not lo <= value <= hi:
            problems.append(f"{name}={value:g} degrees is outside [{lo:g}, {hi:g}] degrees")
    return problems
