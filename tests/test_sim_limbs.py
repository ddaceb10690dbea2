"""The sleeves-and-legs metric (``sim/limbs.py``) on a synthetic limb: an upright cylinder of radius 4 cm."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.sim.limbs import MAX_GAP_DEG, around_part

A = np.array([0.0, 1.0, 0.0])  # the joint
B = np.array([0.0, 0.6, 0.0])  # the far end: a 40 cm part pointing down


def _ring(radius: float, y: float, start_deg: float = 0.0, span_deg: float = 360.0, n: int = 16,
          centre=(0.0, 0.0)) -> np.ndarray:
    a = np.radians(start_deg + span_deg * np.arange(n) / (n if span_deg == 360.0 else n - 1))
    return np.stack([centre[0] + radius * np.cos(a), np.full(n, y), centre[1] + radius * np.sin(a)], axis=1)


@pytest.fixture(scope="module")
def surface():
    ys = np.linspace(0.6, 1.0, 41)
    return np.concatenate([_ring(0.04, y, n=24) for y in ys])


def test_a_cuff_around_the_limb_is_around_it(surface):
    assert around_part(_ring(0.05, 0.8), A, B, surface)
    # tilted 40 degrees and flattened to an ellipse it still goes round
    ring = _ring(0.06, 0.8)
    ring[:, 0] *= 0.7
    ring[:, 1] += np.tan(np.radians(40)) * ring[:, 0]
    assert around_part(ring, A, B, surface)
    # over the far end (a hand, a foot) and a little past it
    assert around_part(_ring(0.05, 0.55), A, B, surface)


def test_an_opening_beside_the_limb_or_round_only_part_of_it_is_not(surface):
    assert not around_part(_ring(0.05, 0.8, centre=(0.15, 0.0)), A, B, surface)  # a cuff hanging beside it
    assert not around_part(_ring(0.05, 0.8, 0.0, 360.0 - MAX_GAP_DEG - 10.0), A, B, surface)  # a hand out of its side
    assert around_part(_ring(0.05, 0.8, 0.0, 360.0 - MAX_GAP_DEG + 30.0, n=32), A, B, surface)
    assert not around_part(_ring(0.3, 0.8), A, B, surface)  # a skirt-wide ring
    assert not around_part(_ring(0.05, 1.2), A, B, surface)  # above the joint, around nothing of this part
