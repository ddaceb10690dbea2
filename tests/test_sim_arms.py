"""The sleeves carried with the arms as they turn back (``sim/arms.py``): skinning weights measured over the
cloth from the cuff, on a synthetic sleeve with a flap of bodice hanging beside it."""

from __future__ import annotations

import numpy as np

from tryon.garment.topology import cloth_distance
from tryon.sim.arms import CARRY_RAMP, ELBOW_RAMP, sleeve_weights

JOINT = np.array([0.0, 1.0, 0.0])
ELBOW = np.array([0.0, 0.7, 0.0])  # a 30 cm upper arm hanging straight down
WRIST = np.array([0.0, 0.45, 0.0])
RING = 12


def _sleeve_and_flap():
    """A tube of radius 6 cm from the shoulder joint down to the wrist (rings every 2.5 cm), and a
    flap sewn to its top ring hanging down beside it, 10-11 cm from its axis (the bodice under the armpit).
    Returns points (k, 3), faces (f, 3), the cuff's point ids, the flap's point ids."""
    ts = np.arange(0.0, 0.575, 0.025)
    a = 2 * np.pi * np.arange(RING) / RING
    tube = np.concatenate([np.stack([0.06 * np.cos(a), np.full(RING, 1.0 - t), 0.06 * np.sin(a)], axis=1)
                           for t in ts])
    faces = []
    for i in range(len(ts) - 1):
        for j in range(RING):
            p, q = i * RING + j, i * RING + (j + 1) % RING
            faces += [(p, q, p + RING), (q, q + RING, p + RING)]
    # the flap: two columns hanging from top-ring points 5 and 6 (the side towards -x), moved out to 10 cm
    top = tube[[5, 6]]
    flap = [top * [10 / 6, 1, 10 / 6] - [0, t, 0] for t in np.arange(0.025, 0.5, 0.025)]
    flap = np.concatenate(flap)
    base = len(tube)
    prev = [5, 6]
    for i in range(len(flap) // 2):
        cur = [base + 2 * i, base + 2 * i + 1]
        faces += [(prev[0], prev[1], cur[0]), (prev[1], cur[1], cur[0])]
        prev = cur
    x = np.concatenate([tube, flap])
    cuff = np.arange((len(ts) - 1) * RING, len(ts) * RING)
    return x, np.array(faces), cuff, np.arange(base, len(x))


def test_cloth_distance_runs_over_the_cloth_not_through_the_air():
    x, faces, cuff, flap = _sleeve_and_flap()
    d = cloth_distance(x, faces, cuff)
    assert np.all(d[cuff] == 0.0)
    # a flap point beside the elbow is 10 cm from the sleeve in the air but reached round the armhole
    i = flap[np.argmin(np.abs(x[flap, 1] - 0.7))]
    assert d[i] > 0.55 + 0.25


def test_sleeve_weights_ramp_down_the_sleeve_and_leave_the_bodice():
    x, faces, cuff, flap = _sleeve_and_flap()
    on_arm, on_fore = sleeve_weights(x, faces, cuff, JOINT, ELBOW, WRIST)
    down = 1.0 - x[:, 1]  # m below the shoulder joint, along the arm
    tube = np.ones(len(x), dtype=bool)
    tube[flap] = False
    upper = 0.3
    # the cap and armhole stay with the bodice, the sleeve below them goes with the arm
    assert np.all(on_arm[tube & (down < CARRY_RAMP[0] * upper - 0.005)] == 0.0)
    assert np.all(on_arm[tube & (down > CARRY_RAMP[1] * upper + 0.005)] == 1.0)
    # the forearm's share is 0 above the elbow's ramp and 1 below it
    assert np.all(on_fore[tube & (down < upper * (1 - ELBOW_RAMP) - 0.005)] == 0.0)
    assert np.all(on_fore[tube & (down > upper * (1 + ELBOW_RAMP) + 0.005)] == 1.0)
    # the flap hangs beside the arm but is bodice: never carried
    assert np.all(on_arm[flap] == 0.0)
