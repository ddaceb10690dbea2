"""The solver's knobs that are not a request's to choose: one frozen object beside ``SimSettings``.

``SimSettings`` holds what a caller may set per try-on (time step, substeps, friction, strain limits, ...).
``Tuning`` holds how the method itself works: when a point is tested again, how the relaxation decides it is
done, the guards. Each field carries its unit and why it has its value. ``drape`` takes one (``TUNING`` by
default); a benchmark or test that needs another passes ``dataclasses.replace(TUNING, ...)`` instead of
patching module globals. The figures quoted below are from ``tryon bench --only fit`` (90 catalogue drapes)
and ``--only poses`` unless said otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Tuning:
    """How the step loop and the relaxation work (``run.py``'s module doc tells the story they belong to).

    rest_move: m. A point that moved less than this since its last collision test (and was not in contact)
        is not tested again: the body is static, so it is still outside the offset body, i.e. at least
        margin - 0.1 mm clear of the real one.
    part_reach: m. How far beyond the aligned garment's bounding box a body part must be to be never tested
        (the garment can fall or slide a little; a part further than this cannot be reached before rest).
        A cloth dropped from high above a collider (the bench's ball scene) needs more.
    pin_steps: steps for which points pushed out at alignment stay pinned when growth is off.
    grow_reach: ratio. A tangled start grows only the body parts that reach at most this many times their
        median radius from their axis (``start.growing_parts``): a part grown from its axis sweeps its far
        reaches through the cloth around it, and a foot, 4 times the shin's median radius from the shin's axis
        (the head and every other part 2 at most), lengthened forward through the trouser hem or the skirt lying
        on the floor before it (the coarse points pushed aside, the triangles between them pierced: the shown
        mesh pushed out round the toes stretched 0.32-1.8 on the 158 cm body's trousers S, L and XXL). Cloth
        that starts in a part not grown is pushed out to its nearest surface (outward, for a leg wrapped round
        a calf or a hem in an instep).
    min_polish_rounds, max_polish_rounds: the relaxation after the loop runs at least MIN rounds (one step's
        substeps each), then until every spring meets the strain target (``metrics.allowed_length``), at most
        MAX, or until it stalls (below). A band that must stretch a little to sit on a large body climbs slowly:
        the L skirt and shorts on the large body need 81 and 193 rounds; with at most 300 and the stall rule they
        meet the target, and the drapes that cannot (S / M garments on the large body) stop after 33-67 rounds.
    stall_rounds, stall_progress: a search that has not brought its figure down to PROGRESS x its lowest in
        STALL rounds gives up. The relaxation's figure is the count of springs over the target (a garment too
        small for the body there: its springs stay over whatever the rounds); the settle's the larger of its
        speed and force over their tolerances (``SimSettings.rest_speed``, ``rest_force``; STALL counted in
        steps of ``REFERENCE_STEP``): points caught between the collision and their springs in a cycle longer
        than two steps never balance (the medium body's trousers XL fallen round its feet: 16 of 1,511 points
        at 0.5 cm/s, held there for 300 steps). Such a drape ends unbalanced (metrics ``balanced``).
    settle_drag: 1/s, air drag once the drape's motion is over (``SimSettings.rest_energy``): in its settle, until
        its forces balance (``rest_speed``, ``rest_force``), and in the relaxation after it. Heavy next to the
        fall's (``SimSettings.air_drag``, 1/s): a hem's swing (a 30 cm pendulum, 5.7 rad/s, critically damped at
        11/s) dies in a few steps instead of ringing for a hundred (the T-shirt M stepped on past its mean-energy
        rest at 1/s still moved up to 0.4 mm a step 100 steps later); on nine catalogue drapes slow to settle,
        12/s and 25/s took about as many steps in all, 6/s 6-9 % more (a stiffer drag slows a creep as much
        as it stops a swing). Light enough that the motion the constraints start keeps
        going in the relaxation (a waistband climbs back up to where it fits in 10-40 rounds instead of
        hundreds of passes without momentum), yet a cloth pulled up off a table by the springs at its rim comes
        to a stop (0 and 10/s left bumps of 2 mm and 1.7 cm on the table test at 0.05 s; 20/s: 0.2 mm).
    relax_move_quantile, relax_max_move: m. The relaxation is kept for each piece of the file that it moved
        less than ``relax_max_move`` at the ``relax_move_quantile`` of the piece's coarse points. A garment
        far too small for its body has no nearby place where its springs meet the target, and without
        gravity the relaxation carries it to wherever they come closest (a MakeHuman blouse on the medium
        body bunched around the neck, 90 % of its points moved up to 55 cm; MakeHuman trousers down to the
        knees, 26 cm). The catalogue's drapes move 90 % of their points at most 12 cm, most under 2 cm.
    order_refresh: steps between re-sorting the springs from the top down for the hanging-stretch sweep
        (the garment's vertical order changes slowly once it hangs).
    near: m. Points outside the offset body but closer than this get a contact plane for the step's
        constraint passes (so the springs cannot pull them in between two collision tests).
    plane_reuse: m. A contact plane is reused (no map query) while the point stays this close to where it
        touched (within 1 cm on a 5 cm arm the plane lies at most 1 mm off the surface).
    floor_y: m, the floor the body stands on (its feet are on y = 0); trouser legs and long hems rest on it.
    floor_under_sole: put the floor under the offset body's soles: a floor inside the offset body would
        trap a trouser hem between the floor and the sole's rim, stretching its springs without end.
    sweep_every_substep: the top-down stretch sweep runs after every substep (True) or once per step
        (half the cost, but bottoms then slide off the hips; after every second substep the 90 catalogue
        drapes need 17-23 % more steps).
    tear_guard, tear_passes: the largest spring length / natural length the step's last sweeps allow
        (issue 5: never beyond 3x), and at most how many such sweeps (they stop as soon as one finds nothing
        to do). Rarely active in a normal drape (a few short springs for a few steps: a cuff round a hand, a
        trouser hem caught under a sole); it keeps a garment far too small for its body from being stretched
        without bound.
    frame_depth: m, how deep a point may get into the body within a step: a point without a contact plane
        that moved more than the collision margin plus this since its collision test is tested again after
        the next substep's prediction (``collision.movers``), and a contact point deeper than this in the real
        body at the step's end is taken out (``step._out_of_the_body``). Issue 26's bound for any streamed
        frame: 2 mm.
    unseen_pinch_steps: steps after a fresh drape's start-up during which its frames are not shown while a point
        is more than ``frame_depth`` inside the body (``settle.showing``): the growth leaves a trouser crotch
        pinched between the thighs up to 12.5 mm in, drawn out by its springs within 1-6 steps on the
        catalogue. A bound, so that a pinch that stays (a garment too small there) does not hold back the stream.
    unfold_per_pass: m, in a re-posed drape the most a pass lengthens a compressed spring by (``pack_springs``'
        cap; 0 = none). Cloth crushed in a fold (the inside of a bent elbow: structural springs down to 2 % of
        their length) sprang open at once when the fold opened, every pass putting each spring back to its
        length: in the first step of a re-pose 1,148 of the long-sleeve's points moved over 15 mm, up to
        155 mm, and some were pulled 3 cm into the body. Capped, the fold opens over a few steps.
    contact_weight: inverse-mass factor of points in contact during the constraint passes: points on the
        body count as heavier, so hanging cloth hangs from them instead of dragging them in.
    contact_passes: extra Gauss-Seidel passes per substep over the springs with both ends on the body (a
        waistband around the hips, a bodice over the chest), stretch only: their hoop tension is what holds
        a garment up; with one pass of the whole cloth per substep it stretched 15-25 % before friction held
        it, so bottoms came to rest 1-2 cm too low. One pass rather than two: as accurate, with fewer steps
        to rest; none: 3-7 % more steps and springs left over on the large body.
    untangle_step: m, the most a round of contour minimisation (``collision/untangle.py``) moves a point of a
        crossing of the cloth through itself; 0 = none. On the shown mesh (below) 2 mm left 1,515 crossings over
        the fit bench's 90 drapes, 3 mm 1,269, 4 mm 1,180, the shown mesh then 4.5 and 4.6 mm from where the
        simulated one puts it (99th percentile of its vertices; 4.0 without the untangling).
    shown_untangle_rounds: at most this many rounds of it in each of the shown mesh's rounds but the last
        (``full_mesh.follow_coarse``), stopping at the first that finds no crossing. The fit bench's shown
        crossings: one round 2,921 (39 drapes with none), 5 rounds 1,798, 10 rounds 1,269 (63 with none), 15
        1,163; what is left follows the simulated mesh's own crossings, centimetres deep. A drape's shown mesh
        takes 8 ms (median of the 90, one thread) without the untangling, 16 ms with one round, 21 ms with up to
        ten (45 ms at the 90th percentile: the tangled ones; a round after the first looks only where points
        moved, ``untangle.untangle_mesh``).
    untangle_every: steps between two rounds of it on the simulated mesh in the step loop (then the relaxation runs
        one a round while it makes progress); 0 = the shown mesh's rebuild only. Only there by default: with the
        shown mesh's rounds it takes the fit bench's crossings only from 1,269 to 1,043 (body through 31 -> 35),
        and on a garment that arrives crossed through itself in hundreds of places (a long-sleeve made with its
        sleeves inside the torso) where its cuffs end (forearm or upper arm) flips with a 5 % change of
        ``untangle_step``.
    self_thickness: m, the cloth's thickness for its contact with itself (``collision/self_contact.py``): each
        point-triangle and edge-edge pair of the simulated mesh that passed through each other within a step goes
        back to its side, and one nearer than this is pushed apart to it; 0 = none. Off by default: at 1 mm it
        takes the fit bench's crossings 12,754 -> 8,886 (the fallen trousers crumpled on the floor still crossed)
        with every fit and poses target as without it, but costs 1.19-2.29x a drape's time to rest (median 1.49,
        ``tryon bench --only selfcontact``), lets body through 1 -> 8 shown vertices, and on outfits the layers'
        pushes cross a garment through itself outside it (layer-penetrating vertices 0 -> 66); ``docs/limits.md``.
    self_passes: at most this many Gauss-Seidel passes of it at a step's end (fewer once one pushes nothing).
    self_margin: m, how much further than ``self_thickness`` apart the pairs it lists may be
        (``contact_pairs.SelfContact``): a point may stray half of it before its pairs are listed again. 2 cm or
        3 cm (fewer lists, more pairs) cost more on the shorts XXL than 1 cm.
    folded_below: ratio. A spring the alignment leaves shorter than (1 - this) x its natural length starts
        folded: no compression correction until it is that long again (``start``; trouser legs shortened to
        start above the feet). 0.1 %: far under the strain limits, far over the rounding of a rigid move.
    """

    rest_move: float = 1e-4
    part_reach: float = 0.15
    pin_steps: int = 5
    grow_reach: float = 2.5
    min_polish_rounds: int = 3
    max_polish_rounds: int = 300
    stall_rounds: int = 30
    stall_progress: float = 0.9
    settle_drag: float = 20.0
    relax_move_quantile: float = 0.9
    relax_max_move: float = 0.15
    order_refresh: int = 20
    near: float = 0.005
    plane_reuse: float = 0.01
    floor_y: float = 0.001
    floor_under_sole: bool = True
    sweep_every_substep: bool = True
    tear_guard: float = 2.5
    tear_passes: int = 100
    frame_depth: float = 0.002
    unseen_pinch_steps: int = 10
    contact_weight: float = 0.2
    contact_passes: int = 1
    unfold_per_pass: float = 0.0005
    untangle_step: float = 0.003
    shown_untangle_rounds: int = 10
    untangle_every: int = 0
    self_thickness: float = 0.0
    self_passes: int = 3
    self_margin: float = 0.01
    folded_below: float = 1e-3


TUNING = Tuning()
