"""A garment's springs packed for the passes, made once per garment model and settings and shared by its drapes.

What a drape's ``start`` needs that depends only on the garment and the settings, not on the body: the file's
pieces, the springs in block order (``blocks.split_springs``), their packed table (strain
limits, a bottom's waistband at the band limit, the fabric's stiffness for the substep) and the substeps. No
drape writes them (the table is read-only: a drape changes its own copy, ``DrapeState.table``; the others go
to the kernels, which would compile again for read-only arrays), so the drapes of one garment (an advice's,
the service's workers') share them. A garment sized to its body (guessed units) or a tucked top gathered into
its bottom is a new model, packed for that drape.
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from tryon.garment.model import GarmentModel
from tryon.garment.springs import STRUCTURAL
from tryon.sim.blocks import split_springs
from tryon.sim.constraints import pack_springs
from tryon.sim.pieces import piece_labels, waistband_mask
from tryon.sim.settings import SimSettings

# models packed and kept: the catalogue's 30 garments and the service's uploads. An entry holds its model weakly
# (the catalogue decides which models stay in memory) and is found only while that model lives: a new model given
# a dead one's id is packed anew
KEPT = 64


@dataclass(frozen=True)
class PackedSprings:
    """piece (k,) int64: which separate piece of the file each coarse point belongs to; springs (s, 2) int64,
    rest (s,) m, kind (s,) int64 in block order; mass (k,) kg; limits (3,) strain limits by kind; ends (s, 2)
    uint32 and table (s, 5): the springs packed for the passes (``constraints.pack_springs``; a waistband's at
    the band limit, the fabric's k h^2 per pass); blocks (3,) int64 (``blocks.split_springs``); n_sub substeps of
    h s with per_sub passes each."""

    piece: np.ndarray
    springs: np.ndarray
    rest: np.ndarray
    kind: np.ndarray
    mass: np.ndarray
    limits: np.ndarray
    ends: np.ndarray
    table: np.ndarray
    blocks: np.ndarray
    n_sub: int
    per_sub: int
    h: float


_KEPT: OrderedDict[tuple, tuple[weakref.ref, PackedSprings]] = OrderedDict()
_LOCK = threading.Lock()


def packed_springs(model: GarmentModel, settings: SimSettings) -> PackedSprings:
    """``model``'s springs packed for ``settings`` (see the module doc), from the cache when it has them."""
    key = (id(model), settings.strain_limit, settings.compression, settings.band_limit, settings.time_step,
           settings.substeps, settings.passes)
    with _LOCK:
        hit = _KEPT.get(key)
        if hit is not None and hit[0]() is model:
            _KEPT.move_to_end(key)
            return hit[1]
    packed = _pack(model, settings)
    with _LOCK:
        _KEPT[key] = (weakref.ref(model), packed)
        while len(_KEPT) > KEPT:
            _KEPT.popitem(last=False)
    return packed


def _pack(model: GarmentModel, settings: SimSettings) -> PackedSprings:
    piece = piece_labels(model.coarse_faces, len(model.mass))  # a file's separate garments (an outfit's)
    limits = settings.limits_array()
    # a large garment's springs in two blocks that share no point (its passes then run on two threads)
    order, blocks = split_springs(model.springs, model.coarse_vertices)
    springs = np.ascontiguousarray(model.springs[order], dtype=np.int64)
    rest = np.ascontiguousarray(model.rest[order], dtype=np.float64)
    kind = np.ascontiguousarray(model.kind[order], dtype=np.int64)
    mass = np.ascontiguousarray(model.mass, dtype=np.float64)
    ends, table = pack_springs(springs, rest, kind, limits, settings.compression_array())
    # a bottom's waistband stretches less than its cloth (``band_limit``; its structural springs: the
    # band's hoop and height). Only the solver holds it so: the metrics judge each spring by its type's
    # limit, so a band too small for its waist shows springs over where it is stretched past the cloth's.
    band = waistband_mask(model.coarse_vertices, model.coarse_faces, model.meta.category, model.coarse_loops,
                          piece)
    band_springs = (kind == STRUCTURAL) & band[springs[:, 0]] & band[springs[:, 1]]
    table[band_springs, 0] = rest[band_springs] * (1.0 + settings.band_limit)
    # substeps ("small steps", Macklin et al. 2019): the passes are spread over substeps of the time step,
    # which converges much further per pass than repeating passes on one large step
    n_sub = max(1, min(settings.substeps, settings.passes))
    per_sub = max(1, settings.passes // n_sub)
    h = float(settings.time_step) / n_sub
    # the fabric's elasticity (``constraints._spring_pass``): k h^2 / passes per substep, h the substep
    table[:, 4] = model.stiffness[order] * (h * h / per_sub)
    table.flags.writeable = False  # the one a drape would write: its own copy is ``DrapeState.table``
    return PackedSprings(piece=piece, springs=springs, rest=rest, kind=kind, mass=mass, limits=limits, ends=ends,
                         table=table, blocks=blocks, n_sub=n_sub, per_sub=per_sub, h=h)
