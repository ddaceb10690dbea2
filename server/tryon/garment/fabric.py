"""Fabrics: measured stiffness and weight of the cloth a garment is made of, in SI units.

The figures are the lowest-strain rows of Wang, O'Brien and Ramamoorthi 2011, "Data-driven elastic models for
cloth: modeling and measurement" (ACM TOG 30(4):71), as distributed with ARCSim (``materials/*.json``; the
loader doubles the stored coefficients): the stretch stiffness c11 (warp) and c22 (weft), the shear stiffness
c33, in N/m (force per unit width per unit strain), and the bending stiffness in N m. Springs do not know which
way the threads run in an arbitrary mesh, so the model is isotropic: stretch is the mean of warp and weft.

What the cloth does with them (``spring_stiffness``; the springs' passes, ``sim.constraints``): between its
natural length and its strain limit a spring pulls back with k (l - l0), k from the fabric; at the strain limit
(``SimSettings.strain_limit``) the fabric locks and the spring goes no further. A jersey hanging 30 cm under its
own weight is under ~0.55 N/m of tension, ~1 % strain at 51 N/m; a woven cotton twill at 4 kN/m barely
stretches at all; both still reach their limit where a body stretches them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tryon.garment.springs import SHEAR, STRUCTURAL


@dataclass(frozen=True)
class Fabric:
    """One fabric. density kg/m^2; stretch, shear N/m (isotropic: per unit width, per unit strain); bending
    N m (recorded with the measurement; the springs' bending stays the spring model's ``compression``
    fraction: a spring across a fold shortens with the square of the fold angle, so no linear spring carries
    a bending modulus); source: where the figures come from. comfort_stretch: how much shorter than the body
    (a fraction of its girth) a garment of this fabric may be cut and still be worn as fitted, not tight: a
    knit is cut with a few per cent of negative ease in a fitted top or dress, a woven with none (a fitting
    convention, not a measurement; ``fit.verdict``)."""

    name: str
    density: float
    stretch: float
    shear: float
    bending: float
    source: str
    comfort_stretch: float = 0.0


_WANG_2011 = "Wang, O'Brien, Ramamoorthi 2011 (ARCSim materials/{}.json, lowest-strain row, x2)"

FABRICS: dict[str, Fabric] = {
    # T-shirt knit, 60 % cotton 40 % polyester: c11 16.59, c22 34.48, c33 36.86 (x2)
    "jersey": Fabric("jersey", 0.187, (33.18 + 68.96) / 2, 73.72, 2.0e-5, _WANG_2011.format("gray-interlock"),
                     comfort_stretch=0.03),
    # trousers' woven, 65 % cotton 35 % polyester: c11 2016.6, c22 2035.0, c33 104.8 (x2)
    "cotton-twill": Fabric("cotton-twill", 0.220, (4033.1 + 4069.9) / 2, 209.5, 1.6e-4,
                           _WANG_2011.format("royal-target")),
    # jeans, 99 % cotton 1 % spandex: c11 205.35, c22 1013.89, c33 53.39 (x2)
    "denim": Fabric("denim", 0.324, (410.7 + 2027.8) / 2, 106.8, 7.0e-5, _WANG_2011.format("11oz-black-denim")),
}

# The fabric of a garment that names none, by category: knit tops and dresses, woven bottoms.
DEFAULT_FABRIC = {"top": "jersey", "dress": "jersey", "bottom": "cotton-twill"}

# A spring of a regular triangle lattice of any spacing carries k = sqrt(3) / 2 x the sheet's stiffness per
# unit width (a lattice of springs k has E = 2 k / sqrt(3)): the springs' stiffness in N/m does not change with
# the mesh's resolution.
LATTICE = math.sqrt(3.0) / 2.0


def fabric_named(name: str | None, category: str) -> Fabric:
    """The fabric ``name``, or the category's default for None. ValueError naming the fabrics for another."""
    key = name or DEFAULT_FABRIC.get(category, "jersey")
    if key not in FABRICS:
        raise ValueError(f"fabric must be one of {', '.join(FABRICS)}, not {key!r}")
    return FABRICS[key]


def spring_stiffness(kind: np.ndarray, fabric: Fabric) -> np.ndarray:
    """(s,) N/m: each spring's stiffness from its kind (s,) (structural: stretch, shear: shear, bending: 0,
    see ``Fabric``), ``LATTICE`` x the fabric's."""
    k = np.zeros(len(kind))
    k[kind == STRUCTURAL] = LATTICE * fabric.stretch
    k[kind == SHEAR] = LATTICE * fabric.shear
    return k
