"""Request and response schemas of ``POST /api/fit``: size advice over a style's sizes."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from tryon.api.schemas.bodies import MeasurementsIn, PoseIn
from tryon.fit.verdict import MAX_EASE_CM

Verdict = Literal["fits", "tight", "loose", "falls_off", "not_draped"]
Preference = Literal["slim", "regular", "relaxed"]


class FitRequest(BaseModel):
    """``POST /api/fit``: which size of a style fits a body built from these measurements and pose."""

    model_config = ConfigDict(extra="forbid")

    style: str = Field(min_length=1, max_length=40, description="style id (GET /api/styles)")
    measurements: MeasurementsIn = Field(description="body measurements, cm")
    pose: PoseIn = Field(default_factory=PoseIn, description="pose angles, degrees, or a named pose "
                                                             "(default: the A-pose)")
    preference: Preference = Field("regular", description="the fit the shopper likes: slim (a size under the "
                                                          "chart's, if its drape is not too tight), regular (the "
                                                          "chart's size, as its drape allows) or relaxed (a size "
                                                          "over, if it stays on)")


class SizeFitOut(BaseModel):
    size: str = Field(description="size label")
    garment_id: str = Field(description="catalogue id of this size: POST /api/tryon with it and the same "
                                        "measurements and pose answers this size's drape from the result cache")
    verdict: Verdict = Field(description="fits | tight (the cloth is stretched past its limit by the body, or a "
                                         "top's cloth is shorter than the chest) | loose (more ease than "
                                         f"{MAX_EASE_CM} cm at a girth) | falls_off (it slid off the shoulders or "
                                         "hips) | not_draped (not simulated: see reason)")
    ease_cm: dict[str, float | None] = Field(
        default_factory=dict, description="per body girth the garment covers (chest for tops and dresses, waist "
                                          "and hips for bottoms and dresses): the draped garment's tape girth "
                                          "minus the body's at the same level, cm (null: it does not cover the "
                                          "body there). About 2.8 cm of it is the cloth's offset from the skin")
    cloth_ease_cm: dict[str, float | None] = Field(
        default_factory=dict, description="per girth: the garment's tape girth there unstretched minus the "
                                          "body's, cm; negative = that much short (a top or dress is tight "
                                          "when short at the chest by more than its fabric takes fitted: 3 % "
                                          "for jersey, nothing for a woven)")
    too_tight: dict[str, int] = Field(default_factory=dict, description="springs stretched past their limit by "
                                                                        "the body, per body place")
    max_strain: float | None = Field(None, description="largest spring strain of the drape (length / natural "
                                                       "length - 1); null if not draped")
    stays_up: bool | None = Field(None, description="whether the garment stayed on the shoulders / hips; null if "
                                                    "not draped")
    slid_cm: float | None = Field(None, description="how far the garment's top ended under where it was put on, "
                                                    "cm (over 10: it does not stay up); null if not draped")
    ends_cm: dict[str, float] = Field(default_factory=dict, description="where the drape's ends lie, cm (POST "
                                                                       "/api/tryon's metrics.ends_cm)")
    length: list[str] = Field(default_factory=list, description="too long or too short, in words (also at the "
                                                                "end of reason)")
    reason: str = Field(description="the verdict in words")


class FitOut(BaseModel):
    style: str = Field(description="style id")
    preference: Preference = Field(description="the fit asked for")
    recommended: str | None = Field(description="with a size chart: the chart's size for these measurements, a "
                                                "size under it for a slim fit or over it for a relaxed one, moved "
                                                "up while its drape is too tight and down while it falls off; "
                                                "without one: the smallest size that is not too tight and leaves "
                                                "the fit's room. Null when no size is wearable (see reason)")
    reason: str = Field(description="why that size, or why none")
    notes: list[str] = Field(default_factory=list, description="where a larger size measured less room at a "
                                                                 "girth than the size under it, and why")
    sizes: list[SizeFitOut] = Field(description="every size of the style, in order")
    wall_seconds: float = Field(description="wall-clock time of this answer, s")
