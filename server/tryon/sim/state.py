"""A drape in progress: the scene ``start`` fixes (``Drape``) and the state each step moves (``DrapeState``).

Struct of arrays over the k simulated (coarse) points of the garment, s springs and q body parts; every
kernel of the loop reads and writes these arrays in place. ``start`` builds a ``Drape``, ``step`` advances
its state by one time step, ``relax`` and ``finish`` end it (``run.py`` tells how they fit together).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.arm_plan import ArmPlan
from tryon.sim.arms import ArmSchedule
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.settings import SimSettings
from tryon.sim.tuning import Tuning


@dataclass
class DrapeState:
    """What a step changes.

    x, x_prev (k, 3) m: positions now and one step before (Verlet); inv_mass (k,) 1/kg (0 = pinned);
    contact (k,) bool: pushed out of the body by the last collision; has_plane (k,) bool, plane_point (k, 3) m,
    plane_normal (k, 3) unit: each point's contact plane, if any; push (k,) m: the pushes summed over a
    substep's passes (for friction); active (k,) bool: the points the step's collision tests; reused (k,) bool:
    contacts that only re-projected onto their plane; x_checked (k, 3) m: where each point was last tested;
    x_step (k, 3) m: positions at the end of the last step; held (k,) bool: held in a pinch between two parts
    this step; moves (2, k, 3) m: each point's move in the last step and in the one before; movers (k,) bool:
    work space of the within-step test (``collision.movers``); layer_has (k,) bool, layer_point (k, 3) m, layer_normal (k, 3): contact
    planes on a garment under this one (an outfit's layer collision), taken where stricter than the body's.
    step: steps done; rest_run: consecutive steps under the rest energy; rest_reached; energy J/kg: the last
    step's kinetic energy per kilogram; collided: how many points the last collision moved.
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
    step: int = 0
    rest_run: int = 0
    rest_reached: bool = False
    energy: float = 0.0
    collided: int = 0

    @classmethod
    def at(cls, x: np.ndarray, inv_mass: np.ndarray) -> DrapeState:
        """The state of points at rest at ``x`` (k, 3) m (taken, not copied) with ``inv_mass`` (k,)."""
        k = len(x)
        return cls(x=x, x_prev=x.copy(), inv_mass=inv_mass, contact=np.zeros(k, dtype=np.bool_),
                   has_plane=np.zeros(k, dtype=np.bool_), plane_point=np.zeros((k, 3)), plane_normal=np.zeros((k, 3)),
                   push=np.zeros(k), active=np.ones(k, dtype=np.bool_), reused=np.zeros(k, dtype=np.bool_),
                   x_checked=x.copy(), x_step=x.copy(), held=np.zeros(k, dtype=np.bool_),
                   moves=np.zeros((2, k, 3)),
                   movers=np.zeros(k, dtype=np.bool_), layer_has=np.zeros(k, dtype=np.bool_),
                   layer_point=np.zeros((k, 3)), layer_normal=np.zeros((k, 3)))

    @property
    def layer_planes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(layer_has, layer_point, layer_normal), as an outfit's layer collision fills them."""
        return self.layer_has, self.layer_point, self.layer_normal

    @property
    def planes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(has_plane, plane_point, plane_normal), as the collision fills them."""
        return self.has_plane, self.plane_point, self.plane_normal


@dataclass
class Drape:
    """One drape: what ``start`` fixed, and its ``state``.

    body, model (resized to the body when its units were guessed: ``sized``), settings, tuning.
    collider: the body as this drape sees it (grows, arms turn); arms: the arms' turn back from the sleeves'
    pose (``plan``); parts (q,) int64: the body parts tested. piece (k,) int64: which separate piece of the
    file each point belongs to (an outfit's garments). springs (s, 2) int64, rest (s,) m, kind (s,) int64,
    mass (k,) kg, limits (3,) strain limits by kind; ends (s, 2) uint32 and table (s, 5): the springs packed
    for the passes (a waistband's at the band limit), the springs in block order and blocks (3,) int64 their
    blocks (``blocks.split_springs``: a large garment's passes run on two threads). openings: sleeves' and
    trouser legs' openings; placed_tops: each piece's top at placement (how far it slid). floor_y m; n_sub
    substeps of h s with per_sub passes each. grow_steps: steps over which the body grows (0: the garment
    started clear of it); startup: steps before the body is complete (growth, arms turning); pinned_until,
    saved_inv_mass: points pinned at the start while growth is off. The step's spring subsets, carried between
    steps: body_ends, body_table (the contact passes' springs, both ends on the body), ordered_ends,
    ordered_lmax (every spring from the top down, refreshed every ``tuning.order_refresh`` steps) and
    sweep_ends, sweep_lmax (the hanging springs the top-down sweep visits), each with its blocks (body_blocks,
    ordered_blocks, sweep_blocks).
    started: ``time.perf_counter()`` at the start.
    moving: a re-posed drape (``start``'s ``motion``: the body moves from another pose while the garment steps
    on); for these ``run.settle`` measures after every step how deep the garment's coarse points are inside
    the body as it is at that step, and ``motion_depth`` (m) keeps the deepest (``motion_max_penetration_mm``).
    shown_from: the first step of a fresh drape shown to a caller (``run.showing``), 0 before it.
    self_contact: the pairs the cloth's contact with itself tests (``contact_pairs.SelfContact``), made at its
    first call when ``tuning.self_thickness`` asks for it; None otherwise.
    """

    body: Body
    model: GarmentModel
    settings: SimSettings
    tuning: Tuning
    collider: BodyCollider
    arms: ArmSchedule
    plan: ArmPlan
    parts: np.ndarray
    piece: np.ndarray
    springs: np.ndarray
    rest: np.ndarray
    kind: np.ndarray
    mass: np.ndarray
    limits: np.ndarray
    ends: np.ndarray
    table: np.ndarray
    blocks: np.ndarray
    openings: list
    placed_tops: np.ndarray
    floor_y: float
    n_sub: int
    per_sub: int
    h: float
    grow_steps: int
    startup: int
    pinned_until: int
    saved_inv_mass: np.ndarray | None
    sized: bool
    state: DrapeState
    body_ends: np.ndarray = field(default_factory=lambda: np.empty((0, 2), dtype=np.uint32))
    body_table: np.ndarray = field(default_factory=lambda: np.empty((0, 5)))
    body_blocks: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=np.int64))
    ordered_ends: np.ndarray = field(default_factory=lambda: np.empty((0, 2), dtype=np.uint32))
    ordered_lmax: np.ndarray = field(default_factory=lambda: np.empty(0))
    ordered_blocks: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=np.int64))
    sweep_ends: np.ndarray = field(default_factory=lambda: np.empty((0, 2), dtype=np.uint32))
    sweep_lmax: np.ndarray = field(default_factory=lambda: np.empty(0))
    sweep_blocks: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=np.int64))
    started: float = 0.0
    moving: bool = False
    motion_depth: float = 0.0
    shown_from: int = 0
    self_contact: object | None = None

    @property
    def reach(self) -> float:
        """m: the collision's margin plus ``tuning.frame_depth``: how far a point may move between two of its
        collision tests, and how deep in the body a pinched point may be left (``collide_points``' hold_depth)."""
        return self.settings.collision_margin + self.tuning.frame_depth
