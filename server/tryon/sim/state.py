"""A drape in progress, in three parts as in Newton: the model (what ``start`` fixed: the garment's springs
packed for the passes, the time step), the state (what a step moves) and the control (the body as it moves:
its growth, the arms' turn, a re-pose's motion).

Struct of arrays over the k simulated (coarse) points of the garment, s springs and q body parts; every
kernel of the loop reads and writes these arrays in place. ``start`` builds a ``Drape``; ``step.step(model,
state, control)`` reads the model, applies the control's schedule for that step and moves the state;
``relax`` and ``finish`` end it (``run.py`` tells how they fit together).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.arm_plan import ArmPlan
from tryon.sim.arms import ArmSchedule
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.packed import PackedSprings
from tryon.sim.settings import SimSettings
from tryon.sim.tuning import Tuning


def _no_springs() -> np.ndarray:
    return np.empty((0, 2), dtype=np.uint32)


def _no_blocks() -> np.ndarray:
    return np.zeros(3, dtype=np.int64)


def _packed(name: str) -> property:
    """A ``DrapeModel`` property reading its packed springs' field ``name`` (``packed.PackedSprings``)."""
    return property(lambda self: getattr(self.packed, name), doc=f"``packed.{name}``")


@dataclass(frozen=True)
class DrapeModel:
    """What the steps read and never move: the garment, its springs packed for the passes, the time step.

    garment: the garment's model (resized to the body when its units were guessed: ``sized``); settings,
    tuning. packed: the garment's springs packed for the passes (``packed.PackedSprings``, made once per garment
    and settings and shared with its other drapes), whose fields this model reads as its own: piece, springs,
    rest, kind, mass, limits, ends, table, blocks, n_sub, per_sub, h (the drape's own copy of the table, which the
    steps read, is ``DrapeState.table``). openings: the sleeves' and trouser legs' openings; placed_tops (pieces,)
    m: each piece's top at placement (how far it slid). floor_y m.
    """

    garment: GarmentModel
    settings: SimSettings
    tuning: Tuning
    packed: PackedSprings
    openings: list
    placed_tops: np.ndarray
    floor_y: float
    sized: bool

    @property
    def reach(self) -> float:
        """m: the collision's margin plus ``tuning.frame_depth``: how far a point may move between two of its
        collision tests, and how deep in the body a pinched point may be left (``collide_points``' hold_depth)."""
        return self.settings.collision_margin + self.tuning.frame_depth

    @property
    def two_threads(self) -> bool:
        """Whether the springs run in two blocks (the points' kernels then run on two threads too)."""
        return bool(self.blocks[2])


# the packed springs' fields, read through the model (``DrapeModel.packed``)
for _field in ("piece", "springs", "rest", "kind", "mass", "limits", "ends", "table", "blocks", "n_sub", "per_sub",
               "h"):
    setattr(DrapeModel, _field, _packed(_field))


@dataclass
class BodyControl:
    """The body as the drape sees it, and its schedule over the start-up steps.

    body: the body in its real pose; collider: that body as the collision sees it at this step (it grows,
    the arms turn); arms: the arms' turn back from the sleeves' pose (``plan``), or a re-pose's motion from
    the old pose (``moving``); parts (q,) int64: the body parts tested. grow_steps: steps over which the body
    grows (0: the garment started clear of it); startup: steps before the body is complete (growth, arms
    turning); pinned_until, saved_inv_mass (k,) 1/kg: points pinned at the start while growth is off, freed
    at that step.
    """

    body: Body
    collider: BodyCollider
    arms: ArmSchedule
    plan: ArmPlan
    parts: np.ndarray
    grow_steps: int
    startup: int
    pinned_until: int
    saved_inv_mass: np.ndarray | None
    moving: bool


@dataclass
class DrapeState:
    """What a step changes.

    x, x_prev (k, 3) m: positions now and one step before (Verlet); inv_mass (k,) 1/kg (0 = pinned);
    contact (k,) bool: pushed out of the body by the last collision; has_plane (k,) bool, plane_point (k, 3) m,
    plane_normal (k, 3) unit: each point's contact plane, if any; push (k,) m: the pushes summed over a
    substep's passes (for friction); active (k,) bool: the points the step's collision tests; reused (k,) bool:
    contacts that only re-projected onto their plane; x_checked (k, 3) m: where each point was last tested;
    x_step (k, 3) m: positions at the end of the last step; held (k,) bool: held in a pinch between two parts
    this step; moves (4, k, 3) m: each point's move in the last four steps, the last first; movers (k,) bool:
    work space of the within-step test (``collision.movers``); layer_has (k,) bool, layer_point (k, 3) m,
    layer_normal (k, 3): contact planes on a garment under this one (an outfit's layer collision), taken where
    stricter than the body's.
    The step's spring subsets, carried between steps: body_ends, body_table (the contact passes' springs, both
    ends on the body), ordered_ends, ordered_lmax (every spring from the top down, refreshed every
    ``tuning.order_refresh`` steps) and sweep_ends, sweep_lmax (the hanging springs the top-down sweep visits),
    each with its blocks (body_blocks, ordered_blocks, sweep_blocks).
    step: steps done; energy J/kg: the last step's kinetic energy per kilogram; settling: the drape's motion is
    over (``settings.rest_energy``) and it settles under heavy drag; speed m/s, force N/kg: in the settle, the 99th
    percentiles of its points' speed and of the force on them not balanced, over the last two steps; balanced:
    both under their tolerances at this step (``settings.rest_speed``, ``rest_force``); settle_best, settle_best_at:
    the lowest of the larger of the two over its tolerance so far and the step it came (the settle's stall test);
    rest_reached: balanced once, or the settle stalled (``step._at_rest``). collided: how many points the last
    collision moved. started:
    ``time.perf_counter()`` at the start. motion_depth m: a re-posed drape's deepest coarse point inside the
    body as it was at each step (``settle``). shown_from: the first step of a fresh drape shown to a caller
    (``settle.showing``), 0 before it. self_contact: the pairs the cloth's contact with itself tests
    (``contact_pairs.SelfContact``), made at its first call when ``tuning.self_thickness`` asks for it.
    table (s, 5): the springs packed as this drape's passes use them (``DrapeModel.table``, but the compression
    column zero for the springs folded or gathered, the fourth a re-pose's cap on how fast a fold opens); folded
    (q,) int64: the springs the alignment left shorter than their natural length (``start``), whose compression
    correction is off until the cloth is drawn back to that length (``step``).
    """

    x: np.ndarray
    x_prev: np.ndarray
    inv_mass: np.ndarray
    contact: np.ndarray
    has_plane: np.ndarray
    plane_point: np.ndarray
    plane_normal: np.ndarray
    push: np.ndarray
    active: np.ndarray
    reused: np.ndarray
    x_checked: np.ndarray
    x_step: np.ndarray
    held: np.ndarray
    moves: np.ndarray
    movers: np.ndarray
    layer_has: np.ndarray
    layer_point: np.ndarray
    layer_normal: np.ndarray
    body_ends: np.ndarray = field(default_factory=_no_springs)
    body_table: np.ndarray = field(default_factory=lambda: np.empty((0, 5)))
    body_blocks: np.ndarray = field(default_factory=_no_blocks)
    ordered_ends: np.ndarray = field(default_factory=_no_springs)
    ordered_lmax: np.ndarray = field(default_factory=lambda: np.empty(0))
    ordered_blocks: np.ndarray = field(default_factory=_no_blocks)
    sweep_ends: np.ndarray = field(default_factory=_no_springs)
    sweep_lmax: np.ndarray = field(default_factory=lambda: np.empty(0))
    sweep_blocks: np.ndarray = field(default_factory=_no_blocks)
    step: int = 0
    energy: float = 0.0
    settling: bool = False
    speed: float = float("inf")
    force: float = float("inf")
    balanced: bool = False
    settle_best: float = float("inf")
    settle_best_at: int = 0
    rest_reached: bool = False
    collided: int = 0
    started: float = 0.0
    motion_depth: float = 0.0
    shown_from: int = 0
    self_contact: object | None = None
    table: np.ndarray = field(default_factory=lambda: np.empty((0, 5)))
    folded: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    @classmethod
    def at(cls, x: np.ndarray, inv_mass: np.ndarray, started: float = 0.0) -> DrapeState:
        """The state of points at rest at ``x`` (k, 3) m (taken, not copied) with ``inv_mass`` (k,)."""
        k = len(x)
        return cls(x=x, x_prev=x.copy(), inv_mass=inv_mass, contact=np.zeros(k, dtype=np.bool_),
                   has_plane=np.zeros(k, dtype=np.bool_), plane_point=np.zeros((k, 3)), plane_normal=np.zeros((k, 3)),
                   push=np.zeros(k), active=np.ones(k, dtype=np.bool_), reused=np.zeros(k, dtype=np.bool_),
                   x_checked=x.copy(), x_step=x.copy(), held=np.zeros(k, dtype=np.bool_),
                   moves=np.zeros((4, k, 3)),
                   movers=np.zeros(k, dtype=np.bool_), layer_has=np.zeros(k, dtype=np.bool_),
                   layer_point=np.zeros((k, 3)), layer_normal=np.zeros((k, 3)), started=started)

    @property
    def layer_planes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(layer_has, layer_point, layer_normal), as an outfit's layer collision fills them."""
        return self.layer_has, self.layer_point, self.layer_normal

    @property
    def planes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(has_plane, plane_point, plane_normal), as the collision fills them."""
        return self.has_plane, self.plane_point, self.plane_normal


@dataclass(frozen=True)
class Drape:
    """One drape: its model, its state and its control (the body)."""

    model: DrapeModel
    state: DrapeState
    control: BodyControl
