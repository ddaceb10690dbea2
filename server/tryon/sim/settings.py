"""Simulation settings: every knob of one try-on, in SI units, with the reason for its default."""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

# s: the time step the counts in steps (min_steps, grow_steps) are given in (``steps_of``).
REFERENCE_STEP = 0.02


@dataclass(frozen=True)
class SimSettings:
    """Settings of one drape.

    time_step: s. Default 0.02 s: position-based Verlet with strain limits is stable at the paper's
        0.05 s too (allowed up to 0.1 s), but a smaller step lets the collision catch fast cloth and gives
        a smoother drape for about the same wall time to rest (fewer passes needed per step).
    passes: constraint (strain-limit) passes per step (paper: several), spread over the substeps.
    substeps: each step is cut into this many substeps (at most ``passes``), collision detection once per
        step and the springs and contact planes every substep: "small steps" converge much further per
        pass than repeated passes on one step. Default 16 x 1 pass: with 8 x 1 or 16 passes on 4
        substeps, skirts, shorts and trousers slid off the hips of a medium body (measured on the
        catalogue); 16 x 1 holds them and brings every catalogue garment to rest in 50-220 steps.
    simplification: B, kept / original garment vertices of the simulated coarse mesh (paper: 20-30 %);
        used by the caller to pick the cached model variant.
    max_steps: hard step limit.
    gravity: m/s^2, along -y.
    air_drag: 1/s, linear drag on velocity (v *= 1 - air_drag * dt each step): about 1 s relaxation,
        enough to damp swinging without visibly slowing the fall.
    collision_margin: m, how far the body is offset outward along its normals (paper 3.3): 4 mm keeps the
        coarse cloth's triangles (2-3 cm edges, sagging < 2.3 mm over a 5 cm arm) out of the real body.
    contact_offset: m, lambda of eq. 4: where a pushed point lands beyond the offset surface.
    friction_static, friction_kinetic: Coulomb coefficients of cloth on skin (cotton on skin ~0.5-0.6):
        a contact sticks while its tangential motion in a step is below friction_static x its depth, so a
        garment stays on shoulders and hips instead of creeping off them.
    rest_energy: J/kg (= m^2/s^2): the drape's motion is over and its settle begins (``step._at_rest``) once the
        mean kinetic energy per kilogram of cloth, sum(m v^2 / 2) / sum(m) with v the displacement over the last
        two steps / (2 time_step) (a point flipping between two places every step goes nowhere), is under this;
        1e-3 J/kg = an rms speed of 4.5 cm/s. Not the end: a mean lets a hem still swing at 10-25 cm/s (from
        there to its balanced end the T-shirt M on the medium body moves 1.5 mm rms and up to 9 mm; a sleeveless
        dress XL on the small body, still sliding, 6.4 mm rms and up to 2.9 cm).
    rest_speed, rest_force: the settle (heavy drag, ``Tuning.settle_drag``) ends the drape when 99 % of its points
        move slower than ``rest_speed`` m/s and the force on each of them is balanced to within ``rest_force``
        N/kg (1: a tenth of its weight), both over the last two steps (a point flipping between two places every
        step is balanced on average). Then the T-shirt M, trousers M and sleeveless dress M on the 172 cm body
        end 0.06-0.12 mm rms (0.4-1.1 mm at most) from where they are 150 steps on, against 1.0-1.7 mm rms (7.4-18
        mm at most) ended on the mean energy alone, in 4-5 more steps (41-52 before); the 90 drapes of ``tryon
        bench --only fit`` in 20 % more steps in all. Half these tolerances took 12-19 % more steps for 0.03-0.11
        mm rms.
    min_steps: steps always simulated (the growth phase plus a settling margin).
    grow_steps: steps over which the body grows from ``grow_from`` of its radius to full size when the
        aligned garment starts tangled with it (0 disables growing; ``start.growing_parts``: which parts).
        These two count steps of ``REFERENCE_STEP`` (0.02 s): at another time step the drape takes as many
        of its own as make the same simulated time (``steps_of``).
    grow_from: initial radial scale of the growing body parts (0..1).
    strain_limit: maximum strain (l / l0 - 1) per spring type (structural, shear, bending), after Provot:
        where the fabric locks (a knit is stretched this far by a body, never by its own weight: below the
        limit each spring pulls back with its fabric's stiffness, ``garment/fabric.py``), more on the bias
        (shear); bending springs span two edges and only keep a fold from collapsing.
    band_limit: maximum strain of a bottom's waistband (``pieces.waistband_mask``): a sewn band is
        interfaced and stretches ~2 %. With the structural 10 % a band 4 cm over its waist stretched
        freely over hips 10 % wider and the skirt slid down to the thighs.
    compression: fraction of a spring's compression (l < l0) corrected per pass, per type. Structural and
        shear springs go back to their natural length (paper eq. 2-3); bending springs only a little, so
        the cloth can still buckle and fold (a hard compression limit on them makes cloth a plate).
    projection_steps: Newton steps of the fast projection of the strain limits at the end of every step
        (``projection.py``: the springs over their limit solved together, so a correction crosses many springs
        at once); 0 = none. Off by default. With 4, the 4k cloth on the ball stretches 0.16 instead of 0.47 over
        all frames, and with 64 substeps meets Taichi's 0.118 (``tryon bench --only peers``); but on the
        catalogue (``tryon bench --only fit --projection 4``), with every other figure kept, more skin shows
        through the shown mesh (body-through vertices 122 -> 169, the small body's long-sleeves most) and a
        drape takes a third longer (median 0.18 -> 0.23 s).
    max_speed: m/s, per-particle speed clamp; a guard that keeps any scene bounded (gravity alone gives
        ~4 m/s after a 0.8 m fall, so it never acts on a normal drape).
    seed: random seed for anything random (stress scenes).
    """

    time_step: float = 0.02
    passes: int = 16
    substeps: int = 16
    simplification: float = 0.3
    max_steps: int = 400
    gravity: float = 9.81
    air_drag: float = 1.0
    collision_margin: float = 0.004
    contact_offset: float = 0.0005
    friction_static: float = 0.6
    friction_kinetic: float = 0.4
    rest_energy: float = 1e-3
    rest_speed: float = 0.01
    rest_force: float = 1.0
    min_steps: int = 30
    grow_steps: int = 20
    grow_from: float = 0.5
    strain_limit: tuple[float, float, float] = (0.10, 0.15, 0.30)
    band_limit: float = 0.02
    compression: tuple[float, float, float] = (1.0, 1.0, 0.1)
    projection_steps: int = 0
    max_speed: float = 10.0
    seed: int = 0

    def steps_of(self, n: int) -> int:
        """A count of ``REFERENCE_STEP`` steps (``min_steps``, ``grow_steps``) in steps of this
        ``time_step``: the same simulated time whatever the step, so a finer step changes how accurately the
        drape is computed, not what happens in it (a body grown over 0.4 s, not over 20 steps). 0 stays 0."""
        if n <= 0:
            return 0
        return max(1, int(math.ceil(n * REFERENCE_STEP / float(self.time_step) - 1e-9)))

    def limits_array(self) -> np.ndarray:
        """(3,) float64 strain limits by spring kind."""
        return np.asarray(self.strain_limit, dtype=np.float64)

    def compression_array(self) -> np.ndarray:
        """(3,) float64 compression correction fractions by spring kind."""
        return np.asarray(self.compression, dtype=np.float64)
