"""Settling a drape: ``step`` until it is at rest, then ``relax`` and ``finish`` it (``settle``), for a fresh
drape (``run.drape``: ``start`` then this) and a re-posed one (``repose.repose`` then this) alike, and which of
its steps a caller is shown (``showing``).

Both ``run`` and ``repose`` build on this module, which imports neither: a fresh drape on a body whose hands
are turned is draped straight and then re-posed (``repose.fresh_drape``), so ``run`` imports ``repose``, never
the other way round.
"""

from __future__ import annotations

import numpy as np

from tryon.sim.finish import TryOnResult, finish
from tryon.sim.metrics import deepest_inside
from tryon.sim.relax import relax
from tryon.sim.state import Drape
from tryon.sim.step import step_drape

__all__ = ["settle", "showing"]

def settle(d: Drape, on_frame=None, give_way=None, start_up: bool = False) -> tuple[TryOnResult | None, bool]:
    """Step ``d`` until it is at rest (or ``settings.max_steps``, or until ``on_frame(step, x)``, called after
    every step, returns False), then relax and finish it: (the result, False). A fresh drape (``drape``) and a
    re-posed one (``repose.repose``) alike. ``give_way()``: asked after every step once the body's start-up
    motion is over; True ends the settle there without a result: (None, True). A re-posed drape
    (``d.control.moving``) has its coarse points' depth inside the body measured after every step
    (``metrics.deepest_inside``, the body as it is at that step), the deepest kept in ``d.state.motion_depth``:
    the result's ``motion_max_penetration_mm``.

    A fresh drape's start-up (``d.control.startup`` steps: the body grown into the garment from half its girth,
    the arms turned back from the sleeves) is not handed to ``on_frame``: its body is not the one a caller draws
    beside the frames, and the garment would be shown up to 8 cm into it (the catalogue on three bodies,
    ``tryon bench --only fit``: median 16 mm), nor are the few steps after it while cloth the start-up left
    pinched between two parts is still inside the body (``showing``). A re-posed drape's start-up is its body's
    motion, which a caller draws in step (``api.live``'s ``body_pose``): shown. ``start_up=True`` hands every step
    over (a checker that watches the whole run: the stability stress)."""
    stopped = False
    for _ in range(d.model.settings.max_steps):
        at_rest = step_drape(d)
        if d.control.moving:  # a re-pose: how deep the cloth is inside the body as it is at this step
            d.state.motion_depth = max(d.state.motion_depth, deepest_inside(d.control.collider, d.state.x))
        shown = start_up or d.control.moving or showing(d)
        if on_frame is not None and shown and on_frame(d.state.step, d.state.x) is False:
            stopped = True
            break
        if at_rest:
            break
        if give_way is not None and d.state.step > d.control.startup and give_way():
            return None, True
    return finish(d, relax(d), stopped), False


def showing(d: Drape) -> bool:
    """Whether a fresh drape's step just taken is one a caller is shown (``settle``'s ``on_frame``): not during the
    start-up, nor in the ``tuning.unseen_pinch_steps`` steps after it while a point is still more than
    ``tuning.frame_depth`` inside the body; from the first step shown on, every step.

    The start-up's growth leaves cloth pinched between two parts (a trouser crotch between the thighs) up to
    12.5 mm inside the body, held there (``hold_pinched``: pushed, it would flip between the parts) until its
    springs draw it out, 1 to 6 steps later on the catalogue: 8 of the 90 drapes of ``tryon bench --only fit``
    showed such a frame (the small body's trousers S and L; the large body's dress L and XL, trousers XL and XXL,
    shorts L and XL). Any point, not only a held one: the step the body reaches its full size may leave a
    point just past the bound that the next step takes out (the small body's trousers L: 2.6 mm). The steps are
    the same either way; only the stream starts later."""
    st = d.state
    if st.step <= d.control.startup:
        return False
    if d.state.shown_from:
        return True
    if st.step <= d.control.startup + d.model.tuning.unseen_pinch_steps:
        if d.control.collider.depth(st.x, d.control.parts).max() > d.model.tuning.frame_depth:
            return False
    d.state.shown_from = st.step
    return True
