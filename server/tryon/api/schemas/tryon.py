"""Request and response schemas of ``POST /api/tryon`` (and the ``WS /ws/tryon`` request).

Every field has its range (ge / le) and unit; a value out of range is refused (422) naming the field.
Measurements and pose are the body's own schemas (``tryon.api.schemas.bodies``).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, model_validator

from tryon.api.schemas.bodies import MeasurementsIn, PoseIn
from tryon.sim.metrics import SLID_LIMIT_CM
from tryon.sim.outfit import MAX_GARMENTS
from tryon.sim.settings import SimSettings

_DEFAULT = SimSettings()
MeshFormatTryOn = Literal["json", "glb"]


class SimSettingsIn(BaseModel):
    """Simulation settings a client may choose (the rest keep their defaults, see ``SimSettings``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    time_step: float = Field(_DEFAULT.time_step, ge=0.005, le=0.1,
                             description="time step, s (the paper uses 0.05 s); range [0.005, 0.1]")
    passes: int = Field(_DEFAULT.passes, ge=1, le=50,
                        description="constraint passes per time step, a multiple of substeps; range [1, 50]")
    substeps: int = Field(_DEFAULT.substeps, ge=1, le=16,
                          description="substeps per time step the passes are spread over; range [1, 16]")
    simplification: float = Field(_DEFAULT.simplification, ge=0.05, le=1.0,
                                  description="simplification degree B = simulated / original garment vertices "
                                              "(the paper: 0.2-0.3); range [0.05, 1]")
    max_steps: int = Field(_DEFAULT.max_steps, ge=1, le=3000,
                           description="step limit (the run stops earlier once the garment is at rest); "
                                       "range [1, 3000]")

    @model_validator(mode="after")
    def _passes_fill_the_substeps(self) -> "SimSettingsIn":
        """A setting means what it says: each substep runs passes / substeps spring passes, so passes must be a
        multiple of substeps (20 passes on 16 substeps would run 16)."""
        if self.passes % self.substeps:
            lower = max(self.substeps, self.passes // self.substeps * self.substeps)
            raise ValueError(f"passes ({self.passes}) must be a multiple of substeps ({self.substeps}): each substep "
                             f"runs passes / substeps spring passes (try passes {lower}, or substeps that divide "
                             f"{self.passes})")
        return self

    def to_settings(self) -> SimSettings:
        return SimSettings(time_step=self.time_step, passes=self.passes, substeps=self.substeps,
                           simplification=self.simplification, max_steps=self.max_steps)


# Most poses one motion may ask for (each is a drape to rest: ~0.3-1 s of a worker).
MAX_POSES = 10
GarmentId = Annotated[str, StringConstraints(min_length=1, max_length=64)]


class TryOnRequest(BaseModel):
    """``POST /api/tryon``: a catalogue garment, or an outfit of up to three, on a body built from
    measurements and pose."""

    model_config = ConfigDict(extra="forbid")

    garment_id: GarmentId | None = Field(None, description="catalogue id (GET /api/garments) of one garment; "
                                                           "or give garment_ids")
    garment_ids: list[GarmentId] | None = Field(
        None, min_length=1, max_length=MAX_GARMENTS,
        description=f"an outfit: 1 to {MAX_GARMENTS} catalogue ids, innermost first (a T-shirt before the "
                    "long-sleeve over it), at most one bottom; each garment collides with the body and with the "
                    "garments under it. The answer then has one mesh per garment (garments)")
    tuck: Literal["out", "in"] = Field(
        "out", description="an outfit's top over its bottom: out (the top's hem falls over the waistband) or in "
                           "(the bottom's band holds the innermost top's hem inside)")
    measurements: MeasurementsIn = Field(description="body measurements, cm")
    pose: PoseIn = Field(default_factory=PoseIn, description="pose angles, degrees (each side its own, or the "
                                                             "shorthand for both), or a named pose: see GET "
                                                             "/api/bodies/ranges")
    settings: SimSettingsIn = Field(default_factory=SimSettingsIn, description="simulation settings")
    poses: list[PoseIn] | None = Field(
        None, min_length=2, max_length=MAX_POSES,
        description=f"a motion: 2 to {MAX_POSES} poses (named or angles), instead of pose; the garment is draped "
                    "in the first, then carried to each next one and draped on from where it is. format=glb: "
                    "an animated GLB (one morph target per pose after the first, one second per pose); json: "
                    "the first pose's answer and each pose's metrics (poses). One garment (garment_id)")

    @model_validator(mode="after")
    def _one_garment_or_an_outfit(self) -> "TryOnRequest":
        if (self.garment_id is None) == (self.garment_ids is None):
            raise ValueError("give either garment_id (one garment) or garment_ids (an outfit), not "
                             + ("both" if self.garment_id is not None else "neither"))
        if self.poses is not None and "pose" in self.model_fields_set:
            raise ValueError("give either pose (one pose) or poses (a motion), not both")
        if self.poses is not None and self.garment_ids is not None:
            raise ValueError("poses (a motion) takes one garment (garment_id), not an outfit (garment_ids)")
        if "tuck" in self.model_fields_set and self.garment_ids is None:
            raise ValueError("tuck is how an outfit's top meets its bottom: give it with garment_ids, not with one "
                             "garment (garment_id)")
        if self.garment_ids is not None and len(set(self.garment_ids)) < len(self.garment_ids):
            raise ValueError("garment_ids: each garment at most once")
        return self

    @property
    def ids(self) -> list[str]:
        """The garments asked for, innermost first (one for ``garment_id``)."""
        return [self.garment_id] if self.garment_ids is None else list(self.garment_ids)

    @property
    def outfit(self) -> bool:
        """Whether the answer is an outfit's (``garment_ids`` given, even with one id)."""
        return self.garment_ids is not None


class MeshOut(BaseModel):
    vertices: list[list[float]] = Field(description="(n, 3) fitted garment vertices, m")
    faces: list[list[int]] = Field(description="(f, 3) triangles")


class LimbOpeningOut(BaseModel):
    opening: str = Field(description="'left arm' | 'right arm' | 'left leg' | 'right leg': a sleeve, armhole "
                                     "or trouser leg opening on that side")
    around: str | None = Field(description="the body part it ended around ('upper_arm_l', 'forearm_l' with the "
                                           "hand, 'thigh_l', 'shin_l' with the foot, ...), or null")
    past_end: bool = Field(description="around no part but past the limb's end (a sleeve longer than the arm)")
    ok: bool = Field(description="around its limb or past its end")


class TryOnMetricsOut(BaseModel):
    steps: int = Field(description="time steps simulated")
    sim_seconds: float = Field(description="simulated time, s")
    wall_seconds: float = Field(description="wall-clock time of this answer, s: the simulation's, or for an "
                                            "answer from the result cache (cached: true) the look-up's")
    simulation_wall_seconds: float = Field(0.0, description="wall-clock time of the simulation that made this "
                                                            "result, s (the first time it was asked for)")
    cached: bool = Field(False, description="true if this answer is an earlier identical request's result (REST "
                                            "or WebSocket), served from the result cache without simulating")
    rest_reached: bool = Field(description="whether the garment came to rest before the step limit")
    balanced: bool = Field(description="whether it ended at rest within the stated tolerances: 99 % of its "
                                       f"simulated points slower than {_DEFAULT.rest_speed * 1000:g} mm/s and the "
                                       f"forces on them balanced to {_DEFAULT.rest_force:g} N/kg; false when a few "
                                       "points kept moving in a cycle, or the run stopped before")
    rest_speed_mm_s: float | None = Field(description="the 99th percentile of its simulated points' speed over the "
                                                      "last two steps, mm/s; null if it never settled")
    unbalanced_force: float | None = Field(description="the 99th percentile of the force on its simulated points "
                                                       "that is not balanced, over the last two steps, N/kg; null "
                                                       "if it never settled")
    penetrating_vertices: int = Field(description="garment vertices inside the body by more than 2 mm")
    max_penetration_mm: float = Field(description="deepest garment vertex inside the body, mm")
    motion_max_penetration_mm: float | None = Field(
        None, description="a re-pose (a live pose update, or a motion's pose after the first): the deepest any "
                          "simulated (coarse) garment point went inside the body over every step of the way there, "
                          "the body as it was at that step (its limbs moving), mm; null for a drape that did not "
                          "move (a try-on, a motion's first pose). A re-pose draped afresh (redraped) keeps the "
                          "re-pose's")
    body_through_vertices: int = Field(0, description="the opposite fault, on the shown mesh: body vertices that "
                                                      "poke out through the garment by more than 2 mm where it "
                                                      "covers them (the outermost cloth along the skin's normal "
                                                      "lies under the skin: skin shows through)")
    max_body_through_mm: float = Field(0.0, description="how far the deepest of those pokes out, mm (measured up "
                                                        "to 20 mm)")
    max_strain: float = Field(description="largest spring strain (length / natural length - 1)")
    strain: list[float] = Field(description="per garment vertex: largest strain of its springs")
    display_max_strain: float = Field(0.0, description="largest strain of the fitted (displayed) mesh's own "
                                                        "edges and quad diagonals: how far the shown mesh stretches")
    self_crossings: int = Field(0, description="edges of the shown mesh through one of its own triangles (the "
                                               "cloth through itself, in a fold); 0 for cloth that never passes "
                                               "through itself")
    strain_by_kind: dict[str, dict] = Field(default_factory=dict,
                                            description="per spring type: max strain, its limit, springs over")
    too_tight: dict[str, int] = Field(default_factory=dict,
                                      description="where the garment is too small for the body, per body place "
                                                  "(a limb part, or 'torso chest' / 'torso waist' / 'torso hips'): "
                                                  "springs with both ends on the body held over their limit, or "
                                                  "edges of the shown mesh there stretched past the cloth's "
                                                  "loosest limit (the shear limit) by more than 1 %")
    verdict: Literal["fits", "tight", "loose", "falls_off"] | None = Field(
        None, description="the drape's one verdict, judged on the shown mesh as POST /api/fit judges a size: fits | "
                          "tight (too_tight somewhere, or a top's cloth shorter than the chest) | loose | falls_off "
                          "(stays_up false); null from a run that was not judged")
    verdict_reason: str | None = Field(None, description="the verdict in words, with the length if too long or "
                                                         "too short")

    openings_on_limbs: bool | None = Field(None, description="whether every sleeve, armhole and trouser leg "
                                                             "ends around its own arm or leg (or hangs past "
                                                             "its end); null for a garment with none")
    limb_openings: list[LimbOpeningOut] = Field(default_factory=list,
                                                description="each such opening and where it ended")
    ends_cm: dict[str, float] = Field(default_factory=dict, description="where the garment ends on the body, cm, "
                                                                       "on the shown mesh: sleeve_l / sleeve_r "
                                                                       "past the wrist (long sleeves), leg_l / leg_r "
                                                                       "above the ankle bone (full-length legs), hem "
                                                                       "below the hips line (tops)")
    length: list[str] = Field(default_factory=list, description="too long or too short, in words: 'too long: the "
                                                                "sleeves end 7 cm past the wrists'")
    slid_cm: float = Field(0.0, description="how far the garment slid down the body from where it was put on: "
                                            "the largest drop of the highest point of any of its pieces, cm")
    stays_up: bool = Field(True, description=f"whether it slid down no more than {SLID_LIMIT_CM:g} cm (false: it "
                                             "does not stay on the shoulders or hips, e.g. a waistband wider than "
                                             "the hips)")
    sized_to_body: bool = Field(False, description="true if the garment's units were guessed and it was sized to "
                                                   "this body (its chest girth 1.15 x the body's, a bottom's "
                                                   "waistband the body's waist): its fit then says nothing of "
                                                   "the size it was made in")
    layer_penetrating_vertices: int | None = Field(None, description="a garment file of a top and a bottom (draped "
                                                                     "as layers, the top over the bottom): vertices of "
                                                                     "one piece more than 2 mm on the wrong side of the "
                                                                     "other; absent for a garment of one piece")
    max_layer_penetration_mm: float | None = Field(None, description="the deepest of those, mm")
    pose: dict[str, float] = Field(default_factory=dict,
                                   description="pose angles of the body draped on, degrees: as asked, except an arm "
                                               "angle too low for the arm to clear the torso, raised to where the "
                                               "arm rests against it")


class PoseResultOut(BaseModel):
    pose: dict[str, float] = Field(description="the pose built, degrees")
    metrics: TryOnMetricsOut = Field(description="the fit in that pose, at rest")


class TryOnOut(BaseModel):
    garment: MeshOut
    metrics: TryOnMetricsOut
    poses: list[PoseResultOut] | None = Field(None, description="a motion (request poses): each pose's fit, in "
                                                                "order; garment and metrics are the first pose's")


class OutfitGarmentOut(BaseModel):
    garment_id: str = Field(description="catalogue id")
    layer: int = Field(description="0 = innermost; each garment lies over the ones with lower layers")
    vertices: list[list[float]] = Field(description="(n, 3) fitted garment vertices, m")
    faces: list[list[int]] = Field(description="(f, 3) triangles")
    metrics: TryOnMetricsOut = Field(description="this garment's fit, as for a single try-on")


class OutfitMetricsOut(BaseModel):
    steps: int = Field(description="time steps simulated (the outfit's loop)")
    sim_seconds: float = Field(description="simulated time, s")
    wall_seconds: float = Field(description="wall-clock time of this answer, s (see TryOnMetricsOut)")
    simulation_wall_seconds: float = Field(0.0, description="wall-clock time of the simulation, s")
    cached: bool = Field(False, description="true if served from the result cache")
    rest_reached: bool = Field(description="whether every garment came to rest before the step limit")
    tuck: str = Field(description="out | in: the top's hem over or under the bottom's band")
    layers: list[str] = Field(description="garment ids, innermost first, as layered (tuck applied)")
    penetrating_vertices: int = Field(description="garment vertices inside the body by more than 2 mm, all "
                                                  "garments")
    layer_penetrating_vertices: int = Field(description="vertices of an outer garment more than 2 mm on the "
                                                        "body's side of a garment under it")
    max_layer_penetration_mm: float = Field(description="the deepest of those, mm")
    tuck_as_asked: bool | None = Field(None, description="whether the innermost top's cloth at the bottom's band "
                                                         "lies outside it (tuck out) or inside it (in); null "
                                                         "without a top and a bottom, or a top ending above "
                                                         "the band")


class OutfitOut(BaseModel):
    garments: list[OutfitGarmentOut] = Field(description="one mesh per garment, innermost first")
    metrics: OutfitMetricsOut
