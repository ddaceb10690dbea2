"""Request and response schemas for bodies; ``MeasurementsIn`` / ``PoseIn`` are shared with the try-on.

Every field carries its range (ge / le, from ``tryon.body.params``) and its unit. A value out of range is
refused (422) with a message that names the field and the range; implausible combinations (an inseam
longer than the legs can be, a waist twice the chest) are refused with the ratio that failed.
"""

from __future__ import annotations

import json
import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, create_model, field_validator, model_validator

from tryon.body.build import DEFAULT_RESOLUTION, MIN_RESOLUTION
from tryon.body.params import (
    MEASUREMENT_DESCRIPTIONS,
    MEASUREMENT_RANGES,
    OPTIONAL,
    POSE_DESCRIPTIONS,
    NAMED_POSES,
    POSE_RANGES,
    POSE_SHORTHAND,
    REQUIRED,
    Measurements,
    Pose,
    check_measurements,
)

# Largest resolution the API builds (~113,000 vertices): a bound on the work one request can ask for.
API_MAX_RESOLUTION = 100
# Measurements of a mid-range adult: the ANSUR II sample means (cm), rounded. Sliders start here.
DEFAULT_MEASUREMENTS = {"height": 169.0, "chest": 100.0, "waist": 90.0, "hips": 102.0}
MeshFormatBody = Literal["json", "glb"]


def _range_check(kind: str, ranges: dict, unit: str):
    """A 'before' validator refusing numbers out of range with a message naming field and range (the
    ge / le constraints stay on the fields for the schema, and as a backstop)."""

    def check(cls, value, info: ValidationInfo):
        if isinstance(value, (bool, str)):  # JSON true or "170": not taken as 1 or 170
            raise ValueError(f"{kind}.{info.field_name} must be a number ({unit}), got {json.dumps(value)}")
        if isinstance(value, (int, float)):
            if not math.isfinite(value):  # NaN / Infinity / 1e400 (Python's json reads them)
                raise ValueError(f"{kind}.{info.field_name} must be a finite number ({unit}), got {value}")
            lo, hi = ranges[info.field_name]
            if not lo <= value <= hi:
                raise ValueError(f"{kind}.{info.field_name}={value:g} {unit} is outside the range [{lo:g}, {hi:g}] {unit}")
        return value

    return check


def _measurement_fields() -> dict:
    fields = {}
    for name in REQUIRED + OPTIONAL:
        lo, hi = MEASUREMENT_RANGES[name]
        desc = f"{MEASUREMENT_DESCRIPTIONS[name]}; range [{lo:g}, {hi:g}] cm"
        if name in REQUIRED:
            fields[name] = (float, Field(ge=lo, le=hi, description=desc, examples=[DEFAULT_MEASUREMENTS[name]]))
        else:
            fields[name] = (float | None, Field(default=None, ge=lo, le=hi,
                                                description=desc + "; estimated from the required ones if omitted"))
    return fields


class _MeasurementsBase(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    _in_range = field_validator("*", mode="before")(classmethod(_range_check("measurements", MEASUREMENT_RANGES, "cm")))

    @model_validator(mode="after")
    def _plausible(self):
        problems = check_measurements(Measurements(**self.model_dump()))
        if problems:
            raise ValueError("; ".join(problems))
        return self


MeasurementsIn = create_model(
    "MeasurementsIn",
    __base__=_MeasurementsBase,
    __doc__="Body measurements in cm (tape on the skin, as the ANSUR II survey takes them).",
    **_measurement_fields(),
)


# Every field a pose object may give: the side fields and the symmetric shorthand, each with its range.
POSE_FIELD_RANGES: dict[str, tuple[float, float]] = {
    **POSE_RANGES, **{name: POSE_RANGES[left] for name, (left, _) in POSE_SHORTHAND.items()},
}


def _pose_fields() -> dict:
    defaults = Pose()
    fields = {}
    for name, (lo, hi) in POSE_FIELD_RANGES.items():
        default = getattr(defaults, name) if name in POSE_RANGES else None
        desc = f"{POSE_DESCRIPTIONS[name]}; range [{lo:g}, {hi:g}] degrees"
        if name in POSE_RANGES:
            desc += f"; default {default:g}"
        fields[name] = (float | None, Field(default=None, ge=lo, le=hi, description=desc))
    return fields


class _PoseBase(BaseModel):
    """Validated pose: a named pose (a string, ``NAMED_POSES``) or angles. After validation every side field
    holds its angle (the shorthand expanded, the defaults filled in) and the shorthand fields are None, so
    ``model_dump()`` is the same for every way of asking for one pose (the result cache's key)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False,
                              json_schema_extra={"description": "pose angles in degrees, or the name of a pose: "
                                                                + ", ".join(NAMED_POSES)})

    _in_range = field_validator("*", mode="before")(classmethod(_range_check("pose", POSE_FIELD_RANGES, "degrees")))

    @model_validator(mode="before")
    @classmethod
    def _named(cls, data):
        if isinstance(data, str):
            if data not in NAMED_POSES:
                raise ValueError(f"unknown pose '{data}': the named poses are {', '.join(NAMED_POSES)}")
            return dict(NAMED_POSES[data])
        return data

    @model_validator(mode="after")
    def _expand(self):
        for name, sides in POSE_SHORTHAND.items():
            value = getattr(self, name)
            if value is None:
                continue
            given = [side for side in sides if getattr(self, side) is not None]
            if given:
                raise ValueError(f"pose.{name} (both sides) and pose.{given[0]} given together: give either "
                                 f"{name} or {' and '.join(sides)}")
            for side in sides:
                setattr(self, side, value)
            setattr(self, name, None)
        defaults = Pose()
        for name in POSE_RANGES:
            if getattr(self, name) is None:
                setattr(self, name, getattr(defaults, name))
        return self

    def angles(self) -> dict[str, float]:
        """Every side field, degrees."""
        return {name: float(getattr(self, name)) for name in POSE_RANGES}


PoseIn = create_model("PoseIn", __base__=_PoseBase,
                      __doc__="Pose angles in degrees, each side on its own, or a named pose.", **_pose_fields())


def to_body_params(measurements: BaseModel, pose: BaseModel | None = None) -> tuple[Measurements, Pose]:
    """The body stage's ``Measurements`` and ``Pose`` from the validated schemas (pose None: default)."""
    m = Measurements(**measurements.model_dump())
    p = Pose(**pose.angles()) if pose is not None else Pose()
    return m, p


class BodyRequest(BaseModel):
    """``POST /api/bodies``: measurements (cm), pose (degrees), mesh resolution."""

    model_config = ConfigDict(extra="forbid")

    measurements: MeasurementsIn = Field(description="body measurements, cm")
    pose: PoseIn = Field(default_factory=PoseIn, description="pose angles, degrees, or a named pose ("
                                                             + ", ".join(NAMED_POSES) + ")")
    resolution: int = Field(default=DEFAULT_RESOLUTION, ge=MIN_RESOLUTION, le=API_MAX_RESOLUTION,
                            description=f"grid intervals across the front of the torso; about 11.3 * resolution^2 "
                                        f"vertices ({DEFAULT_RESOLUTION}: ~10,000)")


class BodyMeasurementsOut(BaseModel):
    requested: dict[str, float] = Field(description="measurements as given, cm")
    achieved: dict[str, float] = Field(description="measurements of the built mesh, cm (girths: convex hull "
                                                   "perimeter of the plane section of the torso / part)")
    levels: dict[str, float] = Field(description="height above the floor of the chest, waist and hip girths, m")
    estimated: dict[str, float] = Field(description="optional measurements that were estimated, cm")


class BodyPoseOut(BaseModel):
    requested: dict[str, float] = Field(description="pose angles as asked, every side field (the shorthand or a "
                                                    "named pose expanded), degrees")
    achieved: dict[str, float] = Field(description="pose angles of the built body, degrees: as given, except an "
                                                   "arm angle too low for the arm to clear the torso, raised to "
                                                   "where the arm rests against it")


class BodyOut(BaseModel):
    """The body mesh: metres, y up, feet on y = 0, facing +z, its left arm towards +x."""

    vertices: list[list[float]] = Field(description="(n, 3) vertex positions, m")
    faces: list[list[int]] = Field(description="(f, 3) triangles, counter-clockwise seen from outside")
    parts: list[str] = Field(description="part names; face_part indexes this list")
    face_part: list[int] = Field(description="(f,) part index of every face")
    measurements: BodyMeasurementsOut
    pose: BodyPoseOut


class RangeOut(BaseModel):
    min: float
    max: float
    default: float | None = Field(description="slider start; null: estimated from the required measurements")
    unit: str
    required: bool
    description: str


class NamedPoseOut(BaseModel):
    description: str
    angles: dict[str, float] = Field(description="every side field of the pose, degrees")


class RangesOut(BaseModel):
    measurements: dict[str, RangeOut] = Field(description="every measurement field, cm")
    pose: dict[str, RangeOut] = Field(description="every pose field, degrees: each side's own (arm_angle_left, "
                                                  "...), then the shorthand for both sides (arm_angle, ...)")
    named_poses: dict[str, NamedPoseOut] = Field(description="the poses a request may name (\"pose\": "
                                                             "\"hands_on_hips\"), with their angles")
    estimated_defaults: dict[str, float] = Field(description="optional measurements estimated for the defaults, cm")
    resolution: RangeOut = Field(description="mesh resolution of POST /api/bodies")
