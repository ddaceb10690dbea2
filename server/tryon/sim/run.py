"""One try-on: ``start`` (align), ``step`` (integrate, collide, constrain) until at rest, ``relax``, ``finish``.

The four phases live in their own modules (``start.py``, ``step.py``, ``relax.py``, ``finish.py``) over one
``state.Drape``; ``drape`` runs them in order. The knobs a request sets are ``SimSettings``; the method's own
(lower-case names below) are ``tuning.Tuning``.

State is flat arrays: positions x (k, 3), previous positions (k, 3), inverse masses (k,), the model's
springs (s, 2) / rest lengths (s,) / kinds (s,), strain limits per kind. Python only loops over steps and
substeps; every loop over particles or springs is a numba kernel.

One step (time_step dt) is ``substeps`` substeps of dt / substeps ("small steps": the passes spread over
substeps converge much further than the same passes on one step). Each substep:
1. Verlet prediction with gravity and air drag (eq. 1);
2. first substep only: collision against the offset body (paper 3.3-3.4, ``collision/``), which pushes
   points out (eq. 4) and leaves a contact plane for each point pushed or within ``near`` of the body;
   contacts still within ``plane_reuse`` of where they touched only reuse their plane (no map query);
   later substeps push onto the planes, with friction on the predicted motion; a point pinched between two
   parts (pushed out of each into the other: cloth between touching thighs) is held where the step began
   (``hold_pinched``, once the body no longer grows or turns); in later substeps, a point without a plane that
   has moved more than the margin plus ``frame_depth`` since its test (cloth landing fast, a point the
   springs pull in) is tested again the same way (``collision/movers.py``); at the step's end a contact
   point more than ``frame_depth`` inside the body (slid along its plane into another part where two
   overlap) is taken out (``step._out_of_the_body``), so no frame has cloth deeper than that but a pinched
   point held where it was and one the tear guard (below) pulls in;
3. the strain-limited springs (eq. 2-3), ``passes / substeps`` Gauss-Seidel passes, each followed by the
   contact planes (springs and contacts converge together);
4. the top-down sweep for hanging cloth (``sweep_downward``: a sagging free end follows the point above
   it; springs with both ends on the body are left to the contact passes), the planes again, then
   Coulomb friction from the summed contact pushes (a band's hoop tension on the hips is what holds a
   skirt up) and the floor.
After the step a guard keeps every spring under ``tear_guard`` x its natural length (never active in a
normal drape; it keeps a garment far too small for its body from being stretched without bound). Where the
shown mesh's triangles went through its own folds they are taken back out as it is rebuilt
(``collision/untangle.py``; on the simulated mesh too if ``Tuning.untangle_every`` asks).

The loop ends in two phases (``step._at_rest``): once the cloth's mean kinetic energy is low (``rest_energy``: its
fall is over) it settles under heavy drag (``Tuning.settle_drag``) until 99 % of its points move slower than
``rest_speed`` and the forces on them balance to ``rest_force`` (the metrics' ``balanced``), or until that stops
improving; on the mean energy alone a hem still swung at 10-25 cm/s.

Start-up, for garments that begin tangled with the body (sleeves at another angle than the arms, a
garment modelled on another body):
- the arms are posed along the sleeves (``plan_arms``) and turned back to their real pose over the first
  steps (``arms.ArmSchedule``), carrying the sleeves with them, instead of cutting through them;
- if any garment point is still inside the body, the body grows from ``grow_from`` of its radius to full
  size over ``grow_steps`` steps (each part scaled toward its axis; Houdini Vellum Drape does the same),
  pushing the cloth out the way it came in rather than teleporting points through the body; a part that
  reaches far from its axis (a foot from the shin's) keeps its full size (``start.growing_parts``);
- during these start-up steps gravity is off: a garment held by shoulders or hips would otherwise slide
  down a body that is not yet its full size. It falls into place once the body is complete;
- the paper instead pushes such points out and pins them; pinning them for good would hold the garment
  unnaturally, so when growth is disabled (grow_steps = 0) pushed points are pinned only for the first
  ``pin_steps`` steps and then released.

Points at rest cost almost nothing: a point that moved less than ``rest_move`` since it was last found
outside the (static) body, and is not in contact, cannot be inside it by more than that, so its
collision test is skipped; a contact at rest only re-projects onto its plane.

After the loop, a relaxation: the same substeps with gravity and friction off and the settle's drag, from rest (a point
pinched between two parts held, as in the steps), until every spring meets the strain target (or progress stalls, or
``max_polish_rounds`` steps). At rest under gravity the Gauss-Seidel passes leave the springs that hold the garment
up (a waistband on the hips, cloth over the shoulders) a few % over their limits, and a band that sagged too low
cannot shorten without climbing back up the body, a coordinated motion that damped passes make only a little of per
round (hundreds of rounds). Without gravity the over-long springs are the only force left (and only they act:
stretch-only, so no compression pushes cloth up off the body); with little drag the motion they start is kept
(momentum: the heavy-ball acceleration of an iterative solver), so the band climbs to where it fits in 10-40 rounds.
The garment moves only as far as its over-stretch asks: on the medium body a median 1-6 mm per point and up to 1-3
cm, but up to 7-10 cm where a long sleeve or a trouser hem was stretched along the limb and shortens up it. A
garment far too small for the body has no such place nearby, and the relaxation carries it off (a blouse up around
the neck, trousers down to the knees): for each piece of the file of which it moved a tenth of the points more than
``relax_max_move`` it is dropped, and the loop's result for that piece is kept with its springs over the target
reported (metrics ``relaxed``, ``relax_move_mm``: the largest piece's 90th percentile move, the largest move). Then
the full mesh is rebuilt from the coarse one (``full_mesh``: the re-attachment, a few stretch passes over the full
mesh's own springs, and its vertices pushed out of the offset body too), so the displayed mesh neither stretches
beyond the cloth nor penetrates.

The floor (y = ``floor_y``) is put under the offset body's soles, so a trouser hem on the floor beside a
foot is not caught between the floor and the sole's offset rim.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.finish import TryOnResult
from tryon.sim.outfit import drape_pieces, piece_categories
from tryon.sim.repose import fresh_drape
from tryon.sim.settings import SimSettings
from tryon.sim.settle import settle, showing
from tryon.sim.start import start
from tryon.sim.tuning import TUNING, Tuning

# settle and showing live in settle.py (repose builds on them too); named here for the callers of run.settle
__all__ = ["FrameCallback", "TryOnResult", "drape", "settle", "showing"]

# (step, coarse positions (k, 3) m) after each step; returning False stops the loop (the relaxation and the
# result still follow)
FrameCallback = Callable[[int, np.ndarray], bool]


def drape(body: Body, model: GarmentModel, settings: SimSettings = SimSettings(),
          on_frame: FrameCallback | None = None, initial: np.ndarray | None = None,
          tuning: Tuning = TUNING) -> TryOnResult:
    """Drape ``model`` on ``body``; see the module doc. ``initial`` (k, 3) replaces the alignment (tests and
    stress scenes start from given positions)."""
    if initial is None and (categories := piece_categories(model)) is not None:
        # a file of a top and a bottom (a MakeHuman outfit): its pieces as layers, the top over the bottom
        return drape_pieces(body, model, categories, settings, on_frame, tuning)
    if initial is None and body.hands_turned:
        return fresh_drape(body, model, settings, tuning, on_frame)[1]
    return settle(start(body, model, settings, tuning, initial), on_frame)[0]

