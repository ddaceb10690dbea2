"""POST /api/bodies (a body from measurements and pose), GET /api/bodies/ranges (fields for sliders)."""

from __future__ import annotations

import json

import numpy as np
from fastapi import APIRouter, Query
from fastapi.responses import Response

from tryon.api.export import MEDIA_TYPES, json_bytes, mesh_arrays, mesh_bytes
from tryon.api.schemas.bodies import (
    API_MAX_RESOLUTION,
    DEFAULT_MEASUREMENTS,
    BodyOut,
    BodyRequest,
    POSE_FIELD_RANGES,
    MeshFormatBody,
    NamedPoseOut,
    RangeOut,
    RangesOut,
    to_body_params,
)
from tryon.body.build import DEFAULT_RESOLUTION, MIN_RESOLUTION, build_body
from tryon.body.params import (
    MEASUREMENT_DESCRIPTIONS,
    MEASUREMENT_RANGES,
    NAMED_POSE_DESCRIPTIONS,
    NAMED_POSES,
    POSE_DESCRIPTIONS,
    REQUIRED,
    Pose,
    complete,
    Measurements,
)
from tryon.body.types import Body

router = APIRouter(tags=["bodies"])

# RGBA per part for GLB vertex colours (skin tones, limbs a shade apart so the parts can be told apart).
PART_COLOURS = np.array([
    [224, 172, 140, 255], [232, 190, 160, 255],
    [214, 160, 128, 255], [214, 160, 128, 255], [204, 150, 118, 255], [204, 150, 118, 255],
    [222, 176, 146, 255], [222, 176, 146, 255], [212, 166, 136, 255], [212, 166, 136, 255],
], dtype=np.uint8)


def body_json(body: Body, requested_pose: dict) -> dict:
    """The JSON answer of ``POST /api/bodies`` (see ``BodyOut``) for a body built in ``requested_pose``
    (degrees); arrays left as numpy (``json_bytes``), the same content as ``export.mesh_json`` (vertices
    rounded to 0.01 mm)."""
    out = mesh_arrays(body.vertices, body.faces, decimals=5)
    out["parts"] = list(body.parts)
    out["face_part"] = np.ascontiguousarray(body.face_part)
    out["measurements"] = {
        "requested": body.requested,
        "achieved": body.achieved,
        "levels": {k: round(v, 5) for k, v in body.levels.items()},
        "estimated": {k: round(v, 3) for k, v in body.estimated.items()},
    }
    out["pose"] = {"requested": requested_pose, "achieved": body.pose}
    return out


def body_glb(body: Body) -> bytes:
    """The body as GLB, vertex colours by part."""
    return mesh_bytes(body.vertices, body.faces, "glb", colors=PART_COLOURS[body.vertex_part % len(PART_COLOURS)])


@router.post(
    "/bodies",
    response_model=BodyOut,
    responses={200: {"content": {MEDIA_TYPES["glb"]: {}}, "description": "the body (JSON or GLB)"},
               422: {"description": "a measurement or pose out of range, or an implausible combination"}},
)
def create_body(
    request: BodyRequest,
    format: MeshFormatBody = Query("json", description="json (mesh + measurements) or glb (binary glTF)"),
) -> Response:
    """Build the body for the measurements (cm) and pose (degrees): metres, y up, feet on y = 0, facing +z.
    The JSON answer gives the achieved measurements of the built mesh beside the requested ones, and the
    pose built beside the one asked for (an arm angle too low for the arm to clear the torso is raised to
    where the arm rests against it)."""
    m, pose = to_body_params(request.measurements, request.pose)
    body = build_body(m, pose, request.resolution)
    if format == "glb":
        return Response(body_glb(body), media_type=MEDIA_TYPES["glb"],
                        headers={"X-Body-Measurements": json.dumps(body.achieved, separators=(",", ":")),
                                 "X-Body-Pose": json.dumps(body.pose, separators=(",", ":"))})
    return Response(json_bytes(body_json(body, request.pose.angles())), media_type="application/json")


@router.get("/bodies/ranges", response_model=RangesOut)
def body_ranges() -> RangesOut:
    """Every measurement and pose field with its range, unit and default (for building sliders; the pose's
    shorthand fields have no default: they set both sides), and the named poses with their angles."""
    estimated = complete(Measurements(**DEFAULT_MEASUREMENTS))
    measurements = {
        name: RangeOut(min=lo, max=hi, default=DEFAULT_MEASUREMENTS.get(name), unit="cm",
                       required=name in REQUIRED, description=MEASUREMENT_DESCRIPTIONS[name])
        for name, (lo, hi) in MEASUREMENT_RANGES.items()
    }
    pose_defaults = Pose().as_dict()
    pose = {
        name: RangeOut(min=lo, max=hi, default=pose_defaults.get(name), unit="degrees", required=False,
                       description=POSE_DESCRIPTIONS[name])
        for name, (lo, hi) in POSE_FIELD_RANGES.items()
    }
    return RangesOut(
        measurements=measurements,
        pose=pose,
        named_poses={name: NamedPoseOut(description=NAMED_POSE_DESCRIPTIONS[name], angles=angles)
                     for name, angles in NAMED_POSES.items()},
        estimated_defaults={k: round(getattr(estimated, k), 1) for k in MEASUREMENT_RANGES if k not in REQUIRED},
        resolution=RangeOut(min=MIN_RESOLUTION, max=API_MAX_RESOLUTION, default=DEFAULT_RESOLUTION, unit="",
                            required=False, description="grid intervals across the front of the torso"),
    )
