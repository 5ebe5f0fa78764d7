"""sorojax as a solver of the rod benchmark cosseratbench (its plugin contract 0.3).

:class:`SorojaxSolver` turns a ``cosseratbench.Scenario`` into one GVS model per rod,
solves it and samples the solution at the benchmark's material nodes. The benchmark
finds it through the entry point ``cosseratbench.solvers: sorojax`` (pyproject.toml);
this module is loaded only then, or by its test, so it imports cosseratbench at the
top. What is not modelled (a displaced driven end, a turning driven start, a
Poisson ratio above 0.5) raises ``NotImplementedError`` (reported
"unsupported"). Every capability is declared; ``SorojaxSolver(contact=False)``
declares none of contact's (the crossing's run takes about 5 minutes on a 2-core
CPU, the capstan's one, the pile's 6).

Model per rod (from the scenario's physics; :meth:`SorojaxSolver.settings` reports it):

- **Frame.** Each rod is modelled in its own frame: origin at its start, local x
  along the centre line's tangent there, local y the scenario's ``normal`` projected
  off it, so that ``d1 = R(X) e_y`` starts as ``Rod.directors``.
- **Strain modes** (DESIGN.md section 2: model no more than the scene needs). Bending
  about the normal of the plane that holds the centre line, the loads and gravity
  when there is one (planar motion), else about both section axes plus torsion (also
  when an end is turned). Stretch where the rod starts stretched or its axial strain
  ``(|loads| + weight) / EA`` reaches :data:`EFFECT_TOL`; shear where a cantilever's
  shear-to-bending compliance ``3 E I / (k G A L^2)`` reaches it (Cowper's ``k``,
  sorojax's default circle). A mode left out changes the results by less.
- **Orders** (Legendre): bending ``clip(round(n_elements / divisor), lo, hi)``
  (:data:`ORDER_RULES`: ``-v resolution`` shows the convergence); torsion a single
  uniform coordinate in quasi-static scenes (the twist of a round Kirchhoff rod under
  end loads is uniform along it); stretch and shear the bending order in statics,
  :data:`LOW_ORDER` in dynamics.
- **Ends.** A clamped start is the fixed base; a pinned start a revolute joint about
  the plane normal (planar) or a spherical joint; a free start a planar or free
  joint. A pinned end is a spherical closed-loop joint to the ground, a clamped end a
  fixed one. An end turned about a fixed axis (``end_motion``) carries a massless
  rigid link on a revolute joint about that axis whose angle is prescribed (minus the
  motion's), closed to the ground by a prismatic closed-loop joint along the axis when
  the end ``slides_along`` it (a fixed one otherwise): the rod's end turns with the
  motion and slides freely under its load. Point loads are world-frame dead forces.
- **Initial shape.** The strain coordinates are fitted (least squares,
  :func:`sorojax.strain_coordinates`) to the curvature and stretch of the centre line
  (with its ``rest_arc_length``); closed-loop targets are the fitted end poses.

Solvers:

- quasi-static scenes with constant loads: :func:`sorojax.solve_statics`; frame 0 is
  the initial shape, every later frame the equilibrium (the loads do not change).
  Were that equilibrium unstable, the damped dynamics below runs instead;
- quasi-static scenes with a driven end: dynamics with mass-proportional damping
  ``-c M_s eta`` per unit length at every rod point, ``c = 2
  scenario.slowest_frequency()`` (the benchmark's built-in adapters' choice, which
  its twist measurement assumes);
- dynamic scenes: :func:`sorojax.simulate` with no added damping.

Contact scenes (obstacles, rods that start near each other, a driven start) put
all rods in one linkage, each rod a link on the ground placed at its start frame,
with one :class:`sorojax.Contact`: cosseratbench's cylinders become capsules of its
length, planes stay planes, rods closer than :data:`PAIR_REACH` are a rod pair; a
driven start is a prismatic joint whose coordinate is prescribed. Contact laws are
sized from the scene's loads (:func:`_laws`: stiffness for :data:`PENETRATION`
between rods and :data:`OBSTACLE_PENETRATION` against obstacles, critical damping,
the larger friction coefficient, static and kinetic alike).
Frictionless quasi-static scenes (crossing) solve the contact statics from the
initial shapes (:data:`CONTACT_STATICS`); were that equilibrium unstable, they
settle by the damped dynamics for :data:`SETTLE_FRACTION` of the duration, at
constant linearly implicit Euler steps (:data:`SETTLE_SOLVER`), and Newton's method
finds the equilibrium from there, which later frames show. A
heaping rope (self-contact: the pile) runs the damped dynamics with
:data:`HEAP_SOLVER` (explicit) and softer
laws (:data:`HEAP_PENETRATION`, :data:`HEAP_FLOOR_PENETRATION`,
:data:`HEAP_STICK_VELOCITY`, :data:`HEAP_STICK_LOAD`): every pair of its
segments is checked at every step. Other frictional ones (capstan) run the damped
dynamics with ROS34PW2 (its W carries the obstacle contact and sticking friction,
tolerance :data:`CONTACT_RTOL`) on :data:`DIVISION_RULE` divisions of order
:data:`DIVISION_ORDER`, their ends moved onto the initial shape's curvature jumps
(:func:`_kinks`). A rod in a
contact scene keeps a planar model only where every contact force stays in its
plane.

Dynamics run ``FRAME_CHUNK`` frames per call of one compiled program whose shapes
depend on neither ``duration`` nor ``n_frames`` (times are traced, a last chunk
repeats its final time), so the benchmark's untimed warm-up call compiles all its
timed call runs. Rods whose local models coincide (the twist scene's six, which
differ only in the angle they are turned to) share one model and run as one
``jax.vmap`` batch. Everything runs in float64 (``jax.enable_x64`` for the call).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from cosseratbench import (
    Capability,
    Diverged,
    End,
    EndCondition,
    Scenario,
    Trajectory,
)
from cosseratbench.scenario import Motion, Rod

import sorojax as sj
from sorojax._jit import _runtime_threads
from sorojax._results import message
from sorojax.model._layout import ROD

MODE_NAMES = ("torsion", "bend_y", "bend_z", "stretch", "shear_y", "shear_z")

XLA_THREADS = 1
"""Threads of XLA's CPU runtime in a benchmark's process (``NPROC``, which XLA reads
when JAX starts its CPU client; :meth:`SorojaxSolver.__init__` sets it where unset
and JAX's backend has not started). The adapter's programs run one at a time and
their operations are microseconds each: handing independent ones to a second
thread cost more than it saved (2-core CPU, this code, one run each: the pile 25.0
against 30.5 s, the capstan 13.4 against 14.6 s; the pile's evaluation in a compiled
loop 398-404 against 427-473 us). The benchmark runs its own solvers' numerical work
on one thread in its worker processes, too (``OMP_NUM_THREADS`` and the like)."""

EFFECT_TOL = 5e-4
"""A strain mode is modelled when its estimated relative effect reaches this."""

ORDER_RULES: dict[str, tuple[float, int, int]] = {
    # method: (n_elements per polynomial order, lowest order, highest order)
    "statics": (5.0, 2, 16),
    "dynamics": (6.0, 4, 12),
}
"""Bending order ``clip(round(n_elements / divisor), lowest, highest)`` per method.

Measured at the benchmark's default resolutions: the catenary's sag converges to
4e-4 of the elastic catenary (its bending boundary layers at the pins) by order 10;
the pendulum's period to 2.1e-5 (the benchmark's own nonlinear floor, 2e-5) by order
6 and its amplitude drift to 4e-6 at order 8; the twisted rods' critical twist is
off by 3.6% / 0.56% / 0.095% / 0.002% at orders 6 / 7 / 8 / 10 (statics stability of
the straight rod: the buckling mode turns about 2.5 times along the rod).
"""

LOW_ORDER = 1
"""Order of stretch and shear in dynamics: they follow the tension, which is smooth,
and their high-order modes are the fastest vibrations (they set an explicit step)."""

DYNAMIC_SOLVER = "tsit5"
"""Integrator of the dynamics, damped or not: explicit and adaptive. The implicit
Rosenbrock ``"ros34pw2"`` takes 17x more steps on the twisted rods (their closed
loop's Baumgarte rows are not in its W matrix), Kvaerno3 100x the time."""

SOLVER_RTOL = 1e-4
"""Relative tolerance at ``time_step_scale = 1`` (atol: :data:`ATOL_FACTOR` of it).
The fast modes bound the explicit steps there already: 1e-6 changes the pendulum's
metrics by < 3e-9 and the twist's critical-twist error by 3e-9."""

ATOL_FACTOR = 1e-4

SOLVER_ORDER = 5
"""Order of the local error of Tsit5's step: rtol scales by time_step_scale**5."""

HEAP_SOLVER = "bosh3"
"""Integrator of a heaping rope (the pile): Bogacki-Shampine 3(2), three evaluations
a step against Tsit5's six. At the heap's loose tolerance (:data:`CONTACT_RTOL`)
its steps are not much shorter than Tsit5's: on the pile 14,400-14,600 steps
against Tsit5's 9,500 (with :data:`HEAP_CONTROLLER_GAINS` and
:data:`HEAP_STICK_LOAD`; 18,224 against 11,394 without them, 34-36 s against 47 s,
with the same heap). Heun's and Ralston's second-order pairs took 48,000-50,000
steps."""

HEAP_SOLVER_ORDER = 3
"""Order of the local error of :data:`HEAP_SOLVER`'s step."""

HEAP_CONTROLLER_GAINS = (0.3, 0.3)
"""PI step-size control of :data:`HEAP_SOLVER` (``simulate``'s
``controller_gains``): a heap's explicit steps sit at their stability limit, where
integral control rejected a quarter of them (the pile: 4,400 of 18,500 steps);
PI control took 16,900-17,300 (same laws, three runs)."""

FRAME_CHUNK = 32
"""Frames integrated per compiled call (one call and one step-size start per chunk)."""

PAIR_REACH = 0.2
"""Rods whose centre lines start closer than this fraction of the shorter one's
length are a contact pair."""

PENETRATION = 2e-3
"""Rod-pair contact stiffness: the scene's load scale sinks this fraction of the
radius."""

OBSTACLE_PENETRATION = 5e-2
"""Obstacle contact stiffness: the scene's load scale sinks this fraction of the
radius. Stiffer costs steps without changing the capstan's slide: at 0.1 of the
radius ROS34PW2 takes 1145 steps for its first 0.1 s, at 5e-2 1249 and at 2e-3
(the rod pairs' value) 1533 for 5 ms alone."""

SMOOTHING = 0.5
"""The law's smoothing depth, a fraction of the target penetration."""

STICK_VELOCITY = 1e-4
"""Regularised friction's stick velocity [m/s]: a rope held at r of its friction
limit creeps at about ``v r / sqrt(1 - r^2)``. The capstan rope at 0.8 of its
holding overhang creeps 0.32 mm in its 2 s at 1e-4, 2.9 mm at 1e-3 (which takes
0.6 of the time)."""

SPACING_RADII = 5.0
"""Largest distance between contact samples against obstacles, in rod radii (a rope
wrapped on the capstan's cylinder, 50 radii, bends with it between samples)."""

PAIR_SPACING_RADII = 8.0
"""Largest distance between contact samples of rod pairs, in rod radii."""

PILE_LAYERS = 4.0
"""A floor carries up to this many layers of rope: its stiffness's load scale."""

HEAP_PENETRATION = 5e-2
"""Self-contact stiffness of a heaping rope (dense self-contact, the pile): the
rope's weight sinks this fraction of the radius at one sample. Soft enough that
the explicit solver's steps are not bound by it (the pile's Tsit5 steps stayed
within 2 % with its damping at 0.35 to 1 of critical), stiff enough
that coils pressed by the heap above stay well apart (the pile's rope overlaps
itself by at most the figure in its result's ``max_rod_overlap``)."""

HEAP_FLOOR_PENETRATION = 5e-3
"""Floor stiffness under a heaping rope: :data:`PILE_LAYERS` layers of its weight
sink this fraction of the radius. The rope's end arrives at the clamp's speed, and
a coarse model's end carries the inertia of much of its last division: at
:data:`OBSTACLE_PENETRATION` (5e-2) the pile's end went 6 mm (2.4 radii) into the
floor, at 5e-3 it stays above it."""

HEAP_FEED_SPEED = 0.4
"""Feed speed [m/s] up to which :data:`HEAP_FLOOR_PENETRATION` holds (the pile's
default). A rope fed faster lands its end faster: an impact goes ``v sqrt(m / k)``
deep, so the floor's stiffness grows as ``(v / HEAP_FEED_SPEED)^2`` above it and the
end goes no deeper than at this speed (at 0.8 m/s with the benchmark's E of 1e7 the
floor sized for 0.4 m/s let the end go deeper than a radius,
``RESULTS.contact_too_deep``; with E 1e5 the rope's self-contact still does, see
docs/limitations.md)."""

HEAP_STICK_VELOCITY = 1e-2
"""Regularised friction's stick velocity [m/s] in a heap: ``mu N / v_s`` per
sample is a damping rate that would bound the explicit step at
:data:`STICK_VELOCITY` (0.3 g / 1e-4 m/s = 29,000/s on the floor)."""

HEAP_STICK_LOAD = 16.0
"""The floor's stick load under a heaping rope (:attr:`sorojax.ContactLaw.
stick_load`), in loads of the floor's stiffness (:data:`PILE_LAYERS` layers of the
rope's weight): past it the stick velocity grows with the load, so that an impact
(the rope's end landing with its last division's inertia, stopped within a fraction
of a radius) does not make sticking friction a damping that bounds the explicit
step. A rope resting under fewer layers holds as with :data:`HEAP_STICK_VELOCITY`
alone. On the pile (PI control) 14,400-14,600 steps against 16,900-17,300 without
it (two and three runs), its first 0.2 s 2,000 steps against 4,450; at 4 loads
15,500 and 17,100 steps in two runs (the heap settled more slowly)."""

DIVISION_RULE = (10.0, 4, 16)
"""Divisions of a rod in contact dynamics: ``clip(round(n_elements / a), lo, hi)``."""

DIVISION_ORDER = 3
"""Bending order per division in contact dynamics."""

MAX_KINKS = 4
"""Most curvature jumps of an initial shape that divisions are moved onto."""

CONTACT_SOLVER = "ros34pw2"
"""Integrator of contact dynamics: its W carries the obstacles' contact stiffness,
damping and sticking friction, which would bound an explicit step."""

CONTACT_SOLVER_ORDER = 3

PAIR_IMPLICIT_ORDER = 8
"""Rod-pair scenes whose bending order reaches this run ROS34PW2 (with the pairs'
stiffness in W), lower ones Tsit5: on the crossing (2-core CPU), at 31 elements
(order 6) Tsit5 took 333 s and ROS34PW2 778 s; at 51 (order 10) ROS34PW2 712 s,
Tsit5 more than 25 minutes."""

CONTACT_RTOL = 1e-2
"""Relative tolerance of contact dynamics at ``time_step_scale = 1`` (atol:
:data:`ATOL_FACTOR` of it). The quasi-static scenes' metrics are slow motions: the
capstan's light end moves the same to 2e-7 m over the first 0.1 s at 1e-2 and 1e-3,
in 353 and 1249 steps."""

CONTACT_STATICS = True
"""Whether frictionless quasi-static contact scenes (crossing) solve the contact
statics from the initial shapes (:func:`sorojax.solve_statics`: its stiffness
continuation from a softer law, and no point moving more than half a radius per
Newton step while the rod pairs' broad phase has not yet seen them near). On the
crossing at 51 elements: 26 Newton steps, 1.5 s warm. Off: they settle by the
damped dynamics of the same model (orders and divisions of the statics) instead."""

STATICS_MAX_STEPS = 64
"""Newton steps per increment of a contact statics."""

SETTLE_FRACTION = 0.5
"""Frictionless quasi-static rod-pair scenes (crossing) whose contact statics finds
an unstable equilibrium settle by the damped dynamics for this fraction of the
duration; Newton's method then finds the
equilibrium from there, which every later frame shows (as in the statics path).
The damped ropes approach it along a very soft mode (smallest eigenvalue of the
crossing's tangent 3.5e-4 at 50 elements) and still creep at 0.7 mm/s at the end
of the duration, while the shape and lift change by under 1e-5 of the length."""

SETTLE_SOLVER = "rosenbrock_euler"
"""Integrator of that settling: constant linearly implicit Euler steps (the rod
pairs' stiffness in W). Only the end state matters there (Newton's method takes it
to the equilibrium), and the L-stable Euler steps over the contact's and the ropes'
fast modes and damps what it does not resolve, where an adaptive explicit solver
resolves them all."""

SETTLE_STEPS_PER_FRAME = 160
"""Constant steps per frame interval of that settling (the crossing: 0.5 ms; at 1 and
2 ms the ropes' first touch, within a step and outside its W, went through each other:
non-finite states and a broad-phase overflow)."""

SETTLE_NEWTON_STEPS = 32
"""Newton steps from the settled state. On the crossing (51 elements) the scaled
residual is 2.5e-9 after 16 steps, 2.0e-9 after 32 and 2.2e-10 after 256 (which
took 35 s more): it stalls near 1e-9, far below :data:`SETTLE_RESIDUAL`."""

SETTLE_RESIDUAL = 1e-6
"""Largest scaled residual accepted from that Newton solve, with no negative
eigenvalue of its tangent: Newton stalls above 1e-10 there (1.6e-8 after 256 steps
at 50 elements). Otherwise the dynamics goes on to the end."""


# --------------------------------------------------------------------------- plan
@dataclasses.dataclass(frozen=True)
class _Plan:
    """The static modelling choices for one rod."""

    modes: tuple[int, ...]
    orders: tuple[int, ...]
    normal_local: tuple[float, float, float] | None  # plane normal, local frame
    start_joint: str  # N R S A F
    end_loop: str | None  # None S N P
    driven: bool  # end turned by a prescribed coordinate
    method: str  # "statics", "dynamics" or "damped"
    cuts: tuple[float, ...] = ()  # inner division ends, fractions of the length

    @property
    def n_divisions(self) -> int:
        """Divisions of the rod (one strain basis each)."""
        return len(self.cuts) + 1

    @property
    def n_strain_dof(self) -> int:
        """Strain coordinates of the rod."""
        per = sum(o + 1 for m, o in zip(self.modes, self.orders, strict=True) if m)
        return per * self.n_divisions

    @property
    def n_dof(self) -> int:
        """All coordinates (joint, strains, the driven end's prescribed angle)."""
        joint = {"N": 0, "R": 1, "S": 3, "A": 3, "F": 6, "P": 1}[self.start_joint]
        return joint + self.n_strain_dof + int(self.driven)

    @property
    def edges(self) -> np.ndarray:
        """Division ends as fractions of the length, 0 to 1."""
        return np.asarray([0.0, *self.cuts, 1.0])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    if not n > 0:
        raise ValueError(f"cannot normalise the zero vector {v!r}")
    return v / n


def _rest_arc(rod: Rod) -> np.ndarray:
    if rod.rest_arc_length is not None:
        return np.asarray(rod.rest_arc_length, dtype=float)
    pts = np.asarray(rod.centerline, dtype=float)
    return np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    )


def _rotation(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    a = float(np.linalg.norm(w))
    if a < 1e-300:
        return np.eye(3)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / a
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vector of the smallest rotation taking unit ``a`` to unit ``b``."""
    axis = np.cross(a, b)
    sin, cos = np.linalg.norm(axis), float(a @ b)
    if sin < 1e-300:
        return np.zeros(3)
    return axis / sin * math.atan2(sin, cos)


def _frame(rod: Rod) -> tuple[np.ndarray, np.ndarray]:
    """``(p0, R0)``: the rod's start and its frame (x tangent, y the projected normal).

    The tangent at the start is the first chord turned back by half its turn to the
    next chord (a chord is the tangent at its middle): second-order accurate, so
    that the fitted rod ends where the centre line does.
    """
    pts = np.asarray(rod.centerline, dtype=float)
    t0 = _unit(pts[1] - pts[0])
    if len(pts) > 2:
        arc = _rest_arc(rod)
        t1 = _unit(pts[2] - pts[1])
        rate = _turn(t0, t1) / ((arc[2] - arc[0]) / 2)
        t0 = _rotation(-rate * (arc[1] - arc[0]) / 2) @ t0
    normal = np.asarray(rod.normal, dtype=float)
    d1 = normal - (normal @ t0) * t0
    if np.linalg.norm(d1) < 1e-12:
        raise ValueError("Rod.normal is parallel to the rod's first segment")
    d1 = _unit(d1)
    return pts[0], np.stack([t0, d1, np.cross(t0, d1)], axis=1)


def _poisson(rod: Rod) -> float:
    m = rod.material
    nu = m.youngs_modulus / (2.0 * m.shear_modulus) - 1.0
    if not -1.0 < nu <= 0.5 + 1e-12:
        raise NotImplementedError(
            f"Rod.material: shear_modulus = {m.shear_modulus} Pa with youngs_modulus "
            f"= {m.youngs_modulus} Pa means a Poisson ratio {nu:.4g} outside sorojax's "
            "isotropic range (-1, 0.5]; give shear_modulus >= youngs_modulus / 3."
        )
    return min(nu, 0.5)


def _motion_axis(motion: Motion) -> np.ndarray:
    """The fixed world axis a motion turns about, or a clear NotImplementedError."""
    d = np.asarray(motion.displacement, dtype=float)
    if np.abs(d).max() > 0.0:
        raise NotImplementedError(
            "a driven end that is displaced (Motion.displacement != 0) is outside "
            "this adapter's models: only rotation about a fixed axis is prescribed."
        )
    r = np.asarray(motion.rotation, dtype=float)
    if motion.slides_along is not None:
        return motion.axis
    k = int(np.argmax(np.linalg.norm(r, axis=1)))
    if np.linalg.norm(r[k]) == 0.0:
        return np.array([1.0, 0.0, 0.0])
    axis = _unit(r[k])
    across = r - np.outer(r @ axis, axis)
    if np.abs(across).max() > 1e-12:
        raise NotImplementedError(
            "a driven end whose rotation axis changes over time is outside this "
            "adapter's models: give rotations about one fixed axis."
        )
    return axis


def _order(method: str, n_elements: int) -> int:
    divisor, lo, hi = ORDER_RULES["statics" if method == "statics" else "dynamics"]
    return int(min(max(round(n_elements / divisor), lo), hi))


def _start_direction(motion: Motion) -> np.ndarray:
    """The fixed world direction a driven start moves along (no rotation)."""
    r = np.asarray(motion.rotation, dtype=float)
    d = np.asarray(motion.displacement, dtype=float)
    if np.abs(r).max() > 0.0 or motion.slides_along is not None:
        raise NotImplementedError(
            "a driven start that turns or slides is outside this adapter's models: "
            "only a start moved along one fixed direction (a prismatic joint whose "
            "coordinate is prescribed) is modelled."
        )
    k = int(np.argmax(np.linalg.norm(d, axis=1)))
    if np.linalg.norm(d[k]) == 0.0:
        return np.array([0.0, 0.0, 1.0])
    axis = _unit(d[k])
    if np.abs(d - np.outer(d @ axis, axis)).max() > 1e-12:
        raise NotImplementedError(
            "a driven start whose direction of motion changes over time is outside "
            "this adapter's models: give displacements along one fixed direction."
        )
    return axis


def _plan(
    scenario: Scenario,
    rod: Rod,
    n_elements: int,
    *,
    method: str | None = None,
    planar_ok: bool = True,
    cuts: tuple[float, ...] = (),
    order: int | None = None,
) -> _Plan:
    """Choose the modes, orders, joints and solver for ``rod`` (see the module text).

    ``method``, ``planar_ok`` (False: a 3D model even where the rod, its loads and
    gravity lie in one plane), ``cuts`` (inner division ends) and ``order`` (the
    bending order) are the contact scenes' choices (:func:`_scene_plans`).
    """
    drive_start = rod.start_motion is not None
    if drive_start:
        if rod.start is not EndCondition.CLAMPED:  # the scenario checks it too
            raise NotImplementedError("Rod.start_motion needs a clamped start.")
        if rod.end_motion is not None:
            raise NotImplementedError(
                "a rod driven at both ends is outside this adapter's models."
            )
        _start_direction(rod.start_motion)  # raises for what is not modelled
    p0, R0 = _frame(rod)
    pts = (np.asarray(rod.centerline, dtype=float) - p0) @ R0
    forces = [np.asarray(ld.force, dtype=float) @ R0 for ld in rod.loads]
    gravity = np.asarray(scenario.gravity, dtype=float) @ R0
    driven = rod.end_motion is not None
    if driven and rod.end is not EndCondition.CLAMPED:  # the scenario checks it too
        raise NotImplementedError("Rod.end_motion needs a clamped end.")
    if driven:
        _motion_axis(rod.end_motion)  # raises for what is not modelled

    # ------------------------------------------------ planar? (plane holds local x)
    across = [v[1:] for v in (*pts[1:], *forces, gravity) if np.linalg.norm(v) > 0]
    normal_local = None
    if drive_start:
        across.append((_start_direction(rod.start_motion) @ R0)[1:])
    if not driven and planar_ok:
        W = np.asarray(across).reshape(-1, 2)
        W = W[np.linalg.norm(W, axis=1) > 1e-12 * max(1.0, np.abs(W).max(initial=0))]
        if len(W) == 0:
            normal_local = (0.0, 0.0, 1.0)
        else:
            _, s, Vt = np.linalg.svd(W / np.linalg.norm(W, axis=1, keepdims=True))
            if len(s) == 1 or s[1] <= 1e-9 * s[0]:
                n2 = Vt[-1] if len(s) > 1 else np.array([-Vt[0, 1], Vt[0, 0]])
                normal_local = (0.0, float(n2[0]), float(n2[1]))
    planar = normal_local is not None

    # ------------------------------------------------------------------ modes
    m = rod.material
    E, G, rho = m.youngs_modulus, m.shear_modulus, m.density
    A, I = rod.area, rod.second_moment_of_area
    L = rod.length
    nu = _poisson(rod)
    arc = _rest_arc(rod)
    seg = np.linalg.norm(np.diff(np.asarray(rod.centerline, float), axis=0), axis=1)
    prestretch = float(np.abs(seg / np.diff(arc) - 1.0).max())
    axial = (
        sum(np.linalg.norm(f) for f in forces) + rho * A * L * np.linalg.norm(gravity)
    ) / (E * A)
    stretch = prestretch >= EFFECT_TOL or axial >= EFFECT_TOL
    # Cowper's shear coefficient of the circle sorojax's model will use
    k = float(sj.CircularSection(rod.radius).shear_coefficients(0.0, nu)[0])
    shear = 3.0 * E * I / (k * G * A * L**2) >= EFFECT_TOL
    if planar:
        n = np.asarray(normal_local)
        bend_y = abs(n[1]) > 1e-12
        bend_z = abs(n[2]) > 1e-12
        modes = (0, int(bend_y), int(bend_z), int(stretch), int(shear and bend_z))
        modes = (*modes, int(shear and bend_y))
    else:
        modes = (1, 1, 1, int(stretch), int(shear), int(shear))

    # ------------------------------------------------------------------ method
    if method is None and (driven or drive_start):
        method = "damped" if scenario.quasi_static else "dynamics"
    elif method is None:
        method = "statics" if scenario.quasi_static else "dynamics"
    if order is None:
        order = _order(method, n_elements)
    # Torsion of a round rod without distributed moments is uniform at equilibrium
    # (Kirchhoff: the moment about the tangent is constant), so quasi-static scenes
    # give it one coordinate; stretch and shear get LOW_ORDER in dynamics.
    per_mode = (
        0 if scenario.quasi_static else order,
        order,
        order,
        *(3 * (order if method == "statics" else min(order, LOW_ORDER),)),
    )
    orders = tuple(o if f else 0 for f, o in zip(modes, per_mode, strict=True))

    # ------------------------------------------------------------------- ends
    start = {
        EndCondition.CLAMPED: "P" if drive_start else "N",
        EndCondition.PINNED: "R" if planar else "S",
        EndCondition.FREE: "A" if planar else "F",
    }[rod.start]
    if rod.end is EndCondition.FREE:
        end_loop = None
    elif rod.end is EndCondition.PINNED:
        end_loop = "S"
    elif driven and rod.end_motion.slides_along is not None:
        end_loop = "P"
    else:
        end_loop = "N"
    return _Plan(
        modes, orders, normal_local, start, end_loop, driven, method, tuple(cuts)
    )


# ------------------------------------------------------------------ initial shape
def _strain_tables(rod: Rod, R0: np.ndarray):
    """Tabulated curvature (local frame, at the vertices) and stretch (at segments).

    The centre line's frame is carried by the smallest rotation from one segment to
    the next (no torsion), starting at ``R0``; the curvature at a vertex is that
    rotation (in the local frame of the segment before) over the rest arc length
    between the segments' middles.
    """
    P = np.asarray(rod.centerline, dtype=float)
    S = _rest_arc(rod)
    D = np.diff(P, axis=0)
    ds = np.diff(S)
    length = np.linalg.norm(D, axis=1)
    t = D / length[:, None]
    s_mid = (S[:-1] + S[1:]) / 2
    stretch = length / ds
    kappa = np.zeros((max(len(t) - 1, 0), 3))
    # The frame on the first chord: R0 turned onto it (R0's x is the start tangent).
    R = _rotation(_turn(R0[:, 0], t[0])) @ R0
    for j in range(len(t) - 1):
        w = _turn(t[j], t[j + 1])
        kappa[j] = R.T @ w / (s_mid[j + 1] - s_mid[j])
        R = _rotation(w) @ R
    if len(kappa) == 0:  # a straight two-point centre line
        return np.array([0.0, S[-1]]), np.zeros((2, 3)), s_mid, stretch
    return S[1:-1], kappa, s_mid, stretch


def _tabulated_strain(s_k, kappa, s_n, stretch, s):
    """Strain ``(kx, ky, kz, gx, 0, 0)`` at arc length ``s`` from the tables."""
    k = [jnp.interp(s, s_k, kappa[:, i]) for i in range(3)]
    g = jnp.interp(s, s_n, stretch)
    z = jnp.zeros_like(g)
    return jnp.stack([*k, g, z, z])


@eqx.filter_jit
def _fit(sampler: sj.Linkage, strain) -> jax.Array:
    return sj.strain_coordinates(sampler, strain, link=1, total=True)


@eqx.filter_jit
def _sample(sampler: sj.Linkage, q, nodes, mids):
    g = sj.forward_kinematics(sampler, q)
    return g[nodes, :3, 3], g[mids, :3, 1], g[nodes[-1]]


# ---------------------------------------------------------------------- hooks
def _prescribed(times, values, t):
    """A prescribed joint coordinate, piecewise linear in time, held after."""
    return jnp.interp(t, times, values)[None]


@functools.lru_cache(maxsize=32)
def _mass_damping(rate: float, inertia: tuple[float, ...], rod_points: tuple[int, ...]):
    """Hook ``-rate M_s eta`` at rod points (body frame, per unit length), 0 elsewhere.

    Cached per value so that equal scenes give the same (static) function and reuse
    the compiled programs.
    """
    M_s = np.diag(np.asarray(inertia, dtype=float))
    mask = np.asarray(rod_points, dtype=float)

    def hook(t, q, qd, kin):
        W = -rate * kin.eta @ jnp.asarray(M_s, dtype=kin.eta.dtype)
        return W * jnp.asarray(mask, dtype=W.dtype)[:, None]

    return hook


# --------------------------------------------------------------------- the model
@dataclasses.dataclass
class _Model:
    """A built rod model in its local frame, and how to sample it."""

    plan: _Plan
    linkage: sj.Linkage
    sampler: sj.Linkage
    nodes: np.ndarray
    mids: np.ndarray
    q0: jax.Array
    key: tuple
    angles: np.ndarray | None  # (n_times,) the prescribed coordinate's samples
    times: np.ndarray | None
    laws: object = None  # a contact scene's _Laws


def _rod_link(rod: Rod, plan: _Plan, joint: sj.Joint | None = None) -> sj.SoftLink:
    """The rod as a soft link: its divisions (``plan.cuts``), basis and start joint."""
    m = rod.material
    material = sj.Material(
        E=m.youngs_modulus, poisson=_poisson(rod), rho=m.density, eta=0.0
    )
    basis = sj.LegendreBasis(plan.modes, plan.orders)
    section = sj.CircularSection(rod.radius)
    divisions = [
        sj.Division(rod.length * float(b - a), section, basis)
        for a, b in zip(plan.edges[:-1], plan.edges[1:], strict=True)
    ]
    if joint is None:
        joint = _joint(plan.start_joint, plan.normal_local)
    return sj.SoftLink(divisions, material, joint=joint)


def _probes(link: int, plan: _Plan, n_elements: int) -> list[sj.PointWrench]:
    """Zero point wrenches at the material nodes, then at the element middles."""
    x_nodes = np.linspace(0.0, 1.0, n_elements + 1)
    x_mids = (x_nodes[:-1] + x_nodes[1:]) / 2
    edges = plan.edges
    out = []
    for x in np.concatenate([x_nodes, x_mids]):
        k = int(np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2))
        X1 = float(np.clip((x - edges[k]) / (edges[k + 1] - edges[k]), 0.0, 1.0))
        out.append(sj.PointWrench(link, np.zeros(6), division=k + 1, X1=X1))
    return out


def _fitted(rod: Rod, rod_link: sj.SoftLink, plan: _Plan, n_elements: int):
    """``(q_rod, g_end, sampler, nodes, mids)`` of the rod alone in its local frame.

    ``q_rod`` fits the centre line's curvature and stretch, ``g_end`` is the end's
    pose it gives; the sampler carries the probes of :func:`_probes`.
    """
    _, R0 = _frame(rod)
    probes = _probes(1, plan, n_elements)
    sampler = sj.Linkage([rod_link], point_wrenches=probes)
    nodes = np.asarray([sampler.point_index(p) for p in probes[: n_elements + 1]])
    mids = np.asarray([sampler.point_index(p) for p in probes[n_elements + 1 :]])
    tables = _strain_tables(rod, R0)
    strain = eqx.Partial(_tabulated_strain, *map(jnp.asarray, tables))
    q_rod = _fit(sampler, strain)
    _, _, g_end = _sample(sampler, q_rod, nodes, mids)
    return q_rod, np.asarray(g_end), sampler, nodes, mids


def _build(scenario: Scenario, rod: Rod, n_elements: int, plan: _Plan) -> _Model:
    """The linkage of ``rod`` in its local frame, its sampler and initial state.

    The sampler is the same chain with zero point wrenches at the material nodes and
    element middles: they add significant points there, where its forward
    kinematics then gives the poses (the probes are not in the simulated model).
    """
    p0, R0 = _frame(rod)
    m = rod.material
    L = rod.length
    rod_link = _rod_link(rod, plan)
    links = [rod_link]
    axis_local = None
    angles = times = None
    if plan.driven:
        motion = rod.end_motion
        axis = _motion_axis(motion)
        times = np.asarray(motion.times, dtype=float)
        angles = -np.asarray(motion.rotation, dtype=float) @ axis
    probes = _probes(1, plan, n_elements)
    q_rod, g_end, sampler0, nodes0, mids0 = _fitted(rod, rod_link, plan, n_elements)
    if plan.driven:
        axis_local = R0.T @ axis
        a_end = g_end[:3, :3].T @ axis_local  # the axis in the end's frame
        inertia = 1e-3 * m.density * 2 * rod.second_moment_of_area * L
        links.append(
            sj.RigidLink(
                sj.Joint("R", axis=tuple(a_end)),
                length=rod.radius,
                section=sj.CircularSection(rod.radius),
                mass=0.0,
                inertia=inertia * np.eye(3),
                g_i=np.eye(4),
                g_f=np.eye(4),
            )
        )
    q0 = jnp.concatenate([q_rod, jnp.zeros(len(links) - 1)])
    sampler = sj.Linkage(links, point_wrenches=probes)
    loads = []
    for ld in rod.loads:
        f = np.asarray(ld.force, dtype=float) @ R0
        if ld.at is End.END:
            loads.append(sj.PointWrench(1, np.concatenate([np.zeros(3), f])))
        elif rod.start is EndCondition.FREE:
            loads.append(
                sj.PointWrench(1, np.concatenate([np.zeros(3), f]), division=1, X1=0.0)
            )
        # a load on a held start does nothing
    loops = []
    if plan.end_loop is not None:
        if plan.end_loop == "P":
            joint = sj.Joint("P", axis=tuple(g_end[:3, :3].T @ axis_local))
        else:
            joint = plan.end_loop
        loops.append(sj.ClosedLoopJoint(joint, link_A=len(links), link_B=0, g_B=g_end))
    gravity = np.asarray(scenario.gravity, dtype=float) @ R0
    hook = None
    rate = 0.0
    if plan.method == "damped":
        rate = 2.0 * scenario.slowest_frequency()
        A, Iy, Iz, Ip = map(float, sj.CircularSection(rod.radius).properties(0.0))
        inertia = tuple(m.density * v for v in (Ip, Iy, Iz, A, A, A))
        layout = sj.Linkage(links, point_wrenches=loads).layout
        rod_points = tuple(
            int(kind == ROD and link == 1)
            for kind, link in zip(layout.point_kind, layout.point_link, strict=True)
        )
        hook = _mass_damping(rate, inertia, rod_points)
    actuators = [sj.JointActuator(2, prescribed=True)] if plan.driven else []
    linkage = sj.Linkage(
        links,
        gravity=gravity,
        point_wrenches=loads,
        closed_loops=loops,
        actuators=actuators,
        custom_wrench=hook,
    )
    key = (
        plan,
        rod.radius,
        dataclasses.astuple(m),
        L,
        np.asarray(q0).tobytes(),
        np.asarray(
            [np.asarray(ld.force, dtype=float) @ R0 for ld in rod.loads]
        ).tobytes(),
        tuple(ld.at for ld in rod.loads),
        gravity.tobytes(),
        g_end.tobytes(),
        rate,
        None if times is None else times.tobytes(),
    )
    return _Model(plan, linkage, sampler, nodes0, mids0, q0, key, angles, times)


# ------------------------------------------------------------ contact scenes
def _pairs(scenario: Scenario) -> list[tuple[int, int]]:
    """Pairs of rods (0-based) modelled in rod-rod contact.

    Rods whose centre lines start closer than :data:`PAIR_REACH` of the shorter
    one's length; rods further apart (the twist scene's, 0.25 lengths) are left
    independent.
    """
    out = []
    rods = scenario.rods
    for a in range(len(rods)):
        for b in range(a + 1, len(rods)):
            pa = np.asarray(rods[a].centerline, dtype=float)
            pb = np.asarray(rods[b].centerline, dtype=float)
            gap = _polyline_gap(pa, pb)
            if gap < PAIR_REACH * min(rods[a].length, rods[b].length):
                out.append((a, b))
    return out


def _to_polyline(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance of each point ``x`` (n, 3) to the polyline ``p`` (m, 3)."""
    a, b = p[:-1], p[1:]
    ab = b - a
    t = np.einsum("nij,ij->ni", x[:, None] - a[None], ab)
    t = np.clip(t / np.maximum(np.sum(ab * ab, axis=1), 1e-300), 0.0, 1.0)
    c = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(x[:, None] - c, axis=2).min(axis=1)


def _polyline_gap(pa: np.ndarray, pb: np.ndarray) -> float:
    """Smallest distance between two polylines (their vertices against segments)."""
    return float(min(_to_polyline(pa, pb).min(), _to_polyline(pb, pa).min()))


def _nearest_fraction(pa: np.ndarray, arc: np.ndarray, pb: np.ndarray) -> float:
    """Fraction of rod a's rest length at its vertex nearest rod b's centre line."""
    return float(arc[int(np.argmin(_to_polyline(pa, pb)))] / arc[-1])


def _is_contact_scene(scenario: Scenario) -> bool:
    """Whether the scene takes the contact path (:func:`_build_scene`)."""
    return bool(
        scenario.obstacles
        or any(rod.start_motion is not None for rod in scenario.rods)
        or _pairs(scenario)
    )


def _settles(scenario: Scenario) -> bool:
    """Whether a contact scene settles, then solves its statics.

    Quasi-static, frictionless, constant loads, rod pairs and no obstacles: see
    :data:`SETTLE_FRACTION`.
    """
    return bool(
        scenario.quasi_static
        and _pairs(scenario)
        and not scenario.obstacles
        and not scenario.self_contact
        and not _driven(scenario)
        and not _frictional(scenario)
    )


def _driven(scenario: Scenario) -> bool:
    """Whether a rod's start or end follows a prescribed motion."""
    return any(
        r.start_motion is not None or r.end_motion is not None for r in scenario.rods
    )


def _frictional(scenario: Scenario) -> bool:
    rod_mu = max((rod.friction for rod in scenario.rods), default=0.0)
    touching_rods = bool(_pairs(scenario)) or scenario.self_contact
    return any(ob.friction > 0 for ob in scenario.obstacles) or (
        touching_rods and rod_mu > 0
    )


def _planar_with(scenario: Scenario, n: np.ndarray, others: list) -> bool:
    """Whether a rod's plane (world normal ``n``) keeps every contact force in it.

    A cylinder whose axis is the plane's normal, a plane whose normal lies in it;
    rod pairs (``others``: the other rods' plane normals, None when 3D) of
    perpendicular planes that both hold gravity (two ropes crossing at a right
    angle press along gravity, by symmetry).
    """
    for ob in scenario.obstacles:
        if ob.kind == "cylinder" and abs(abs(float(n @ ob.unit_axis)) - 1.0) > 1e-9:
            return False
        if ob.kind == "plane" and abs(float(n @ ob.unit_normal)) > 1e-9:
            return False
    g = np.asarray(scenario.gravity, dtype=float)
    for m in others:
        if m is None or not np.linalg.norm(g) > 0:
            return False
        if abs(float(n @ g)) > 1e-9 * np.linalg.norm(g) or abs(float(n @ m)) > 1e-9:
            return False
    return True


def _kinks(rod: Rod) -> tuple[float, ...]:
    """Where the initial centre line's curvature jumps, as fractions of the length.

    A rope draped over a cylinder is straight, then bent at the cylinder's radius,
    then straight again: a polynomial strain across such a jump fits it badly (the
    fitted rope starts cut into the cylinder and jolts off it). The jumps are where
    the turning rate per rest length crosses half its largest value within two
    vertices (a smooth sag's gentle rise is no jump); a rod turned by
    less than a tenth of a radian in all, or with more than :data:`MAX_KINKS` such
    crossings (a wavy line, not a wrap), has none.
    """
    pts = np.asarray(rod.centerline, dtype=float)
    arc = _rest_arc(rod)
    t = np.diff(pts, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    turn = np.arccos(np.clip(np.sum(t[1:] * t[:-1], axis=1), -1.0, 1.0))
    if turn.sum() < 0.1:
        return ()
    rate = turn / (0.5 * (arc[2:] - arc[:-2]))  # at the inner vertices
    high = rate > 0.5 * rate.max()
    flips = np.flatnonzero(high[1:] != high[:-1])
    # a jump, not a smooth rise: within two vertices, by a quarter of the most
    step = np.abs(np.diff(rate))
    near = [step[max(i - 2, 0) : i + 3].sum() for i in flips]
    flips = flips[np.asarray(near) > 0.25 * rate.max()] if len(flips) else flips
    if len(flips) > MAX_KINKS:
        return ()
    where = 0.5 * (arc[1:-1][flips] + arc[1:-1][flips + 1]) / arc[-1]
    return tuple(float(f) for f in where if 0.0 < f < 1.0)


def _divided(n_div: int, kinks: tuple[float, ...]) -> tuple[float, ...]:
    """``n_div`` even divisions, with division ends moved onto ``kinks``.

    Even ends closer than half a division to a kink give way to it.
    """
    even = np.arange(1, n_div) / n_div
    keep = [e for e in even if all(abs(e - k) >= 0.5 / n_div for k in kinks)]
    return tuple(sorted({*(round(float(e), 12) for e in keep), *kinks}))


def _scene_plans(scenario: Scenario, n_elements: int) -> list[_Plan]:
    """The rods' plans in a contact scene (see the module text)."""
    rods = scenario.rods
    drive = _driven(scenario)
    if not scenario.quasi_static:
        method = "dynamics"
    elif drive or _frictional(scenario):
        method = "damped"
    else:  # frictionless, constant loads: what statics models
        method = "statics"
    pairs = _pairs(scenario)
    cuts: list[tuple[float, ...]] = [() for _ in rods]
    order = None
    if method == "statics":
        # a rod pressed by another at a point: the shear force jumps there, so a
        # division ends there
        for a, b in pairs:
            pa, pb = (np.asarray(rods[i].centerline, dtype=float) for i in (a, b))
            for i, x, y in ((a, pa, pb), (b, pb, pa)):
                f = _nearest_fraction(x, _rest_arc(rods[i]), y)
                if 0.05 < f < 0.95:
                    cuts[i] = tuple(sorted({*cuts[i], round(f, 12)}))
    else:
        # several divisions of a low order: a rope wrapped on an obstacle bends
        # sharply where it leaves it, and that place moves along the rope as it
        # slides; a division ends where the initial shape's curvature jumps
        per, lo, hi = DIVISION_RULE
        n_div = int(min(max(round(n_elements / per), lo), hi))
        cuts = [_divided(n_div, _kinks(rod)) for rod in rods]
        order = DIVISION_ORDER
    if method == "statics" and not CONTACT_STATICS:
        # the frictionless scene's model, settled by the damped dynamics
        order = _order("statics", n_elements)
        method = "damped"
    plans = [
        _plan(scenario, rod, n_elements, method=method, cuts=c, order=order)
        for rod, c in zip(rods, cuts, strict=True)
    ]
    normals = [
        None
        if plan.normal_local is None
        else _frame(rod)[1] @ np.asarray(plan.normal_local)
        for rod, plan in zip(rods, plans, strict=True)
    ]
    out = []
    for i, (rod, plan) in enumerate(zip(rods, plans, strict=True)):
        others = [normals[b if a == i else a] for a, b in pairs if i in (a, b)]
        if normals[i] is not None and not _planar_with(scenario, normals[i], others):
            plan = _plan(
                scenario,
                rod,
                n_elements,
                method=method,
                planar_ok=False,
                cuts=plan.cuts,
                order=order,
            )
        out.append(plan)
    return out


@dataclasses.dataclass(frozen=True)
class _Laws:
    """The contact laws of a scene and the numbers behind them (for ``settings``)."""

    pair: sj.ContactLaw | None
    obstacles: tuple[sj.ContactLaw, ...]
    info: dict


def _laws(scenario: Scenario, method: str, spacing: float) -> _Laws:
    """Contact laws sized from the scene's loads.

    Obstacles (per unit length): the stiffness that holds the rope's weight per
    length, times ``1 + L / R`` on a cylinder of radius R (the tension of a rope
    hanging over it presses ``T / R``), at :data:`OBSTACLE_PENETRATION` of the
    rope's radius.
    Rod pairs and self-contact (per point): the lighter rod's weight at
    :data:`PENETRATION` of the radius. Damping is critical for a sample's mass;
    friction is the larger of the two coefficients, static and kinetic alike (the
    benchmark's Coulomb law). A heap (:func:`_heap`) uses
    :data:`HEAP_PENETRATION`, :data:`HEAP_FLOOR_PENETRATION` (on a floor of
    :data:`PILE_LAYERS` layers; stiffer for a feed faster than
    :data:`HEAP_FEED_SPEED`) and :data:`HEAP_STICK_VELOCITY` instead.
    """
    rods = scenario.rods
    g = float(np.linalg.norm(scenario.gravity)) or 1.0
    pen = PENETRATION
    r_min = min(rod.radius for rod in rods)
    mass_len = min(rod.material.density * rod.area for rod in rods)
    weight = min(rod.material.density * rod.area * rod.length * g for rod in rods)
    loads = max(
        (float(np.linalg.norm(ld.force)) for rod in rods for ld in rod.loads),
        default=0.0,
    )
    rod_mu = max((rod.friction for rod in rods), default=0.0)
    heap = _heap(scenario)
    v_s = HEAP_STICK_VELOCITY if heap else STICK_VELOCITY
    pen = HEAP_PENETRATION if heap else pen
    ob_pen = OBSTACLE_PENETRATION
    if heap:
        ob_pen = HEAP_FLOOR_PENETRATION
        feed = _feed_speed(scenario)
        if feed > HEAP_FEED_SPEED * (1 + 1e-9):  # the default feed: as it is
            ob_pen *= (HEAP_FEED_SPEED / feed) ** 2
    info: dict = {
        "target_penetration": f"{pen:g} of the rod radius",
        "obstacle_target_penetration": f"{ob_pen:g} of the rod radius",
    }
    pair = None
    if _pairs(scenario) or scenario.self_contact:
        k = (weight + loads) / (pen * r_min)
        m_pt = mass_len * spacing
        pair = sj.ContactLaw(
            stiffness=k,
            smoothing=SMOOTHING * pen * r_min,
            damping=2.0 * math.sqrt(k * m_pt),
            static_friction=rod_mu,
            stick_velocity=v_s,
        )
        info["rod_rod_stiffness_N_per_m"] = k
        info["rod_rod_friction"] = rod_mu
    obstacle_laws = []
    for ob in scenario.obstacles:
        L = max(rod.length for rod in rods)
        w_len = mass_len * g
        if ob.kind == "cylinder":
            f = w_len * (1.0 + L / ob.radius)
        else:
            f = w_len * PILE_LAYERS
        k = f / (ob_pen * r_min)
        mu = max(ob.friction, rod_mu)
        stick_load = HEAP_STICK_LOAD * f if heap else None
        obstacle_laws.append(
            sj.ContactLaw(
                stiffness=k,
                smoothing=SMOOTHING * ob_pen * r_min,
                damping=2.0 * math.sqrt(k * mass_len),
                static_friction=mu,
                stick_velocity=v_s,
                stick_load=stick_load,
            )
        )
        info[f"{ob.kind}_stiffness_N_per_m2"] = k
        info[f"{ob.kind}_friction"] = mu
        if stick_load is not None:
            info[f"{ob.kind}_stick_load_N_per_m"] = stick_load
    if method != "statics" and _frictional(scenario):
        info["stick_velocity_m_per_s"] = v_s
    info["smoothing_m"] = SMOOTHING * pen * r_min
    info["obstacle_smoothing_m"] = SMOOTHING * ob_pen * r_min
    info["sample_spacing_m"] = spacing
    return _Laws(pair, tuple(obstacle_laws), info)


def _spacing(scenario: Scenario) -> float:
    """Largest distance between contact samples.

    :data:`SPACING_RADII` rod radii against obstacles, :data:`PAIR_SPACING_RADII`
    with rod pairs (their cost grows as the square of the samples; ropes crossing
    at an angle touch at a point).
    """
    radii = PAIR_SPACING_RADII if _pairs(scenario) else SPACING_RADII
    return radii * min(rod.radius for rod in scenario.rods)


def _obstacle(ob) -> sj.AbstractObstacle:
    if ob.kind == "plane":
        return sj.Plane(point=tuple(ob.point), normal=tuple(ob.unit_normal))
    half = ob.unit_axis * ob.length / 2
    c = np.asarray(ob.center, dtype=float)
    return sj.Capsule(ob.radius, start=tuple(c - half), end=tuple(c + half))


def _build_scene(scenario: Scenario, n_elements: int, plans: list[_Plan]) -> _Model:
    """All rods of a contact scene in one linkage (world frame) and its sampler.

    Each rod is a link on the ground (``parents`` 0) placed at its start frame, so
    that rod pairs, self-contact and obstacles are one contact set. Nodes and
    middles of rod ``i`` are the ``i``-th blocks of ``nodes`` and ``mids``.
    """
    rods = scenario.rods
    links, placements, probes, loads, loops, q0s = [], [], [], [], [], []
    actuators, values, vtimes = [], None, None
    spacing = _spacing(scenario)
    for i, (rod, plan) in enumerate(zip(rods, plans, strict=True), start=1):
        if plan.driven:
            raise NotImplementedError(
                "a driven end in a scene with contact is outside this adapter's models."
            )
        p0, R0 = _frame(rod)
        G0 = np.eye(4)
        G0[:3, :3], G0[:3, 3] = R0, p0
        joint = None
        if plan.start_joint == "P":
            motion = rod.start_motion
            axis = _start_direction(motion)
            joint = sj.Joint("P", axis=tuple(R0.T @ axis))
            if values is not None:
                raise NotImplementedError("more than one driven start")
            vtimes = np.asarray(motion.times, dtype=float)
            values = np.asarray(motion.displacement, dtype=float) @ axis
            actuators.append(sj.JointActuator(i, prescribed=True))
        link = _rod_link(rod, plan, joint)
        q_rod, g_end, *_ = _fitted(rod, link, plan, n_elements)
        links.append(link)
        placements.append(G0)
        q0s.append(np.asarray(q_rod))
        probes += _probes(i, plan, n_elements)
        for ld in rod.loads:
            w = np.concatenate([np.zeros(3), np.asarray(ld.force, dtype=float)])
            if ld.at is End.END:
                loads.append(sj.PointWrench(i, w))
            elif rod.start is EndCondition.FREE:
                loads.append(sj.PointWrench(i, w, division=1, X1=0.0))
        if plan.end_loop is not None:
            loops.append(
                sj.ClosedLoopJoint(plan.end_loop, link_A=i, link_B=0, g_B=G0 @ g_end)
            )
    laws = _laws(scenario, plans[0].method, spacing)
    n_rods = len(rods)
    pairs = [(a + 1, b + 1) for a, b in _pairs(scenario)]
    selfc = tuple(range(1, n_rods + 1)) if scenario.self_contact else ()
    law = laws.pair if laws.pair is not None else laws.obstacles[0]
    contact = sj.Contact(
        tuple(_obstacle(ob) for ob in scenario.obstacles),
        law,
        links=tuple(range(1, n_rods + 1)) if scenario.obstacles else (),
        spacing=spacing,
        rod_pairs=pairs,
        self_contact=selfc,
        friction_in_rod_pairs=bool(laws.pair is not None)
        and float(laws.pair.static_friction) > 0,
        obstacle_laws=dict(enumerate(laws.obstacles)),
    )
    placements = np.stack(placements)
    parents = (0,) * n_rods
    gravity = np.asarray(scenario.gravity, dtype=float)
    hook = None
    rate = 0.0
    if plans[0].method == "damped":
        rate = 2.0 * scenario.slowest_frequency()
        layout = sj.Linkage(
            links,
            parents=parents,
            placements=placements,
            point_wrenches=loads,
            contact=contact,
        ).layout  # the contact samples are points too
        per_point = []
        for kind, lk in zip(layout.point_kind, layout.point_link, strict=True):
            if kind == ROD:
                rod = rods[lk - 1]
                A, Iy, Iz, Ip = map(
                    float, sj.CircularSection(rod.radius).properties(0.0)
                )
                rho = rod.material.density
                per_point.append(tuple(rho * v for v in (Ip, Iy, Iz, A, A, A)))
            else:
                per_point.append((0.0,) * 6)
        hook = _mass_damping_points(rate, tuple(per_point))
    linkage = sj.Linkage(
        links,
        parents=parents,
        placements=placements,
        gravity=gravity,
        point_wrenches=loads,
        closed_loops=loops,
        actuators=actuators,
        custom_wrench=hook,
        contact=contact,
    )
    sampler = sj.Linkage(
        links, parents=parents, placements=placements, point_wrenches=probes
    )
    n1 = n_elements + 1
    idx = [sampler.point_index(p) for p in probes]
    nodes, mids = [], []
    per_rod = n1 + n_elements
    for k in range(n_rods):
        block = idx[k * per_rod : (k + 1) * per_rod]
        nodes += block[:n1]
        mids += block[n1:]
    q0 = jnp.asarray(np.concatenate(q0s))
    key = ("scene", id(linkage))
    return _Model(
        plans[0],
        linkage,
        sampler,
        np.asarray(nodes),
        np.asarray(mids),
        q0,
        key,
        values,
        vtimes,
        laws,
    )


@functools.lru_cache(maxsize=32)
def _mass_damping_points(rate: float, per_point: tuple[tuple[float, ...], ...]):
    """Hook ``-rate M_s eta`` with a section inertia per point (0 off the rods)."""
    M = np.asarray(per_point, dtype=float)

    def hook(t, q, qd, kin):
        return -rate * kin.eta * jnp.asarray(M, dtype=kin.eta.dtype)

    return hook


def _feed_speed(scenario) -> float:
    """The fastest driven start's largest speed [m/s] (0 without one)."""
    speeds = [0.0]
    for rod in scenario.rods:
        m = rod.start_motion
        if m is None or len(m.times) < 2:
            continue
        t = np.asarray(m.times, dtype=float)
        x = np.asarray(m.displacement, dtype=float)
        dt = np.diff(t)
        v = np.linalg.norm(np.diff(x, axis=0), axis=1)
        speeds.extend((v[dt > 0] / dt[dt > 0]).tolist())
    return max(speeds)


def _heap(scenario: Scenario) -> bool:
    """Whether a scene is a heaping rope (dense self-contact: :data:`HEAP_SOLVER`)."""
    return bool(scenario.self_contact and _is_contact_scene(scenario))


def _implicit(plan: _Plan, obstacles: bool) -> bool:
    """Whether a contact scene runs ROS34PW2 (a heap never does: ``_tolerances``).

    Obstacles (their stiffness and sticking friction would bound an explicit step)
    or a rod pair whose bending order reaches :data:`PAIR_IMPLICIT_ORDER` do.
    """
    return obstacles or max(plan.orders) >= PAIR_IMPLICIT_ORDER


def _joint(kind: str, normal_local) -> sj.Joint:
    if kind in ("R", "A"):
        return sj.Joint(kind, axis=normal_local)
    return sj.Joint(kind)


# ------------------------------------------------------------------- the solvers
def _advance_chunk(
    linkage: sj.Linkage,
    sampler: sj.Linkage,
    nodes,
    mids,
    y,
    t0,
    ts,
    times,
    angles,
    solver: str,
    rtol: float,
    atol: float,
    dt: float | None = None,
    gains: tuple[float, float] | None = None,
):
    """A chunk of frames for a batch of rods (local frame).

    Integrates from ``t0`` to ``ts[-1]`` saving at ``ts`` (``FRAME_CHUNK`` times,
    non-decreasing; a last chunk repeats its final time). ``y`` is
    ``(batch, 2 n_dof)``, ``angles`` ``(batch, n_times)`` or None. Returns ``(ys,
    positions, d1, ok, steps, result)`` with a leading batch axis and then one entry
    per save time (``result``: ``simulate``'s result code). Shapes depend on
    neither the frame times nor their number: one compilation serves every chunk of
    every run of the same scene. ``dt``: constant steps of it (a constant-step
    solver) instead of adaptive ones at ``rtol``, ``atol``; ``gains``: the adaptive
    steps' controller gains (``simulate``'s ``controller_gains``).
    """
    n = linkage.n_dof
    steps = (
        dict(rtol=rtol, atol=atol, controller_gains=gains)
        if dt is None
        else dict(dt0=dt)
    )

    def one(y_, angles_):
        u = None if angles_ is None else eqx.Partial(_prescribed, times, angles_)
        tr = sj.simulate(
            linkage,
            ts[-1],
            y_[:n],
            y_[n:],
            t0=t0,
            ts=ts,
            solver=solver,
            u=u,
            throw=False,
            max_steps=1 << 20,
            **steps,
        )
        ys = jnp.concatenate([tr.q, tr.qd], axis=1)
        g = jax.vmap(lambda q: sj.forward_kinematics(sampler, q))(tr.q)
        ok = (tr.result == sj.RESULTS.successful) & jnp.all(jnp.isfinite(ys))
        return (
            ys, g[:, nodes][..., :3, 3], g[:, mids][..., :3, 1], ok, tr.num_steps,
            tr.result,
        )  # fmt: skip

    if y.shape[0] == 1:  # no batch: a vmap of one costs ~50% more per step
        out = one(y[0], None if angles is None else angles[0])
        return jax.tree.map(lambda a: a[None], out)
    in_angles = None if angles is None else 0
    return jax.vmap(one, in_axes=(0, in_angles))(y, angles)


# sorojax's compiler options at XLA's default level: the capstan runs 7 % faster
# than under equinox's plain jit; sorojax's long-run options and its runtime flags
# (XLA_FLAGS) measured slower on that 63-DoF model. A heap (the pile: 111 DoF,
# thousands of self-contact pairs) runs its steps ~5 % faster with the
# long-run options (XLA's YNNPACK fusions off).
_advance = sj.jit(_advance_chunk, tiered=False)
_advance_long = sj.jit(_advance_chunk, tiered=False, long_run=True)


# ------------------------------------------------------------------- the adapter
class SorojaxSolver:
    """cosseratbench solver adapter for sorojax (GVS Cosserat rods in JAX).

    Attributes:
        name: ``"sorojax"`` (the benchmark's name for it).
        capabilities: all of the benchmark's: stretch, shear, rod contact and
            friction, cylinder and plane contact (``contact=False``: stretch and
            shear only). The twist's self-contact is not checked.
        backend_version: the installed sorojax version.
        time_step_scale: multiplies the integrator's steps: the relative tolerance of
            the adaptive step control is scaled by ``time_step_scale**p``, ``p`` the
            order of its local error, and constant steps by ``time_step_scale``;
            statics has no step and ignores it.

    Constructing one before JAX's backend starts sets XLA's CPU runtime to
    :data:`XLA_THREADS` thread (``NPROC``) for the process, unless ``NPROC`` is set.
    """

    name = "sorojax"
    capabilities = frozenset(Capability)
    backend_version = sj.__version__

    def __init__(self, time_step_scale: float = 1.0, contact: bool = True):
        if not float(time_step_scale) > 0:
            raise ValueError(
                f"time_step_scale = {time_step_scale!r}: give a positive number "
                "(1 = the adapter's own choice)."
            )
        self.time_step_scale = float(time_step_scale)
        _runtime_threads(XLA_THREADS)
        if not contact:
            self.capabilities = frozenset({Capability.STRETCH, Capability.SHEAR})

    # ------------------------------------------------------------------ settings
    def _tolerances(
        self, contact: bool = False, heap: bool = False
    ) -> tuple[str, float, float]:
        # a heap runs an explicit solver at the contact tolerance: an implicit
        # one's W would carry thousands of segment pairs (some 7,000 in the pile,
        # whose first 0.3 s took more than 12 minutes on ROS34PW2), so its laws
        # are softened instead (HEAP_PENETRATION, HEAP_STICK_VELOCITY)
        if heap:
            rtol = CONTACT_RTOL * self.time_step_scale**HEAP_SOLVER_ORDER
            return HEAP_SOLVER, rtol, ATOL_FACTOR * rtol
        if contact:
            rtol = CONTACT_RTOL * self.time_step_scale**CONTACT_SOLVER_ORDER
            return CONTACT_SOLVER, rtol, ATOL_FACTOR * rtol
        rtol = SOLVER_RTOL * self.time_step_scale**SOLVER_ORDER
        return DYNAMIC_SOLVER, rtol, ATOL_FACTOR * rtol

    def settings(
        self, scenario: Scenario, *, n_elements: int, n_frames: int
    ) -> dict[str, object]:
        """The numerical choices for ``scenario`` (JSON values), per rod model.

        Args:
            scenario: the benchmark scene.
            n_elements: elements per rod (sets the polynomial order).
            n_frames: frames asked for.

        Returns:
            A dict: model (modes, orders, DoF, joints), solver and its tolerances,
            damping.
        """
        contact = _is_contact_scene(scenario)
        if contact:
            plans = _scene_plans(scenario, n_elements)
        else:
            plans = [_plan(scenario, rod, n_elements) for rod in scenario.rods]
        out: dict[str, object] = {}
        distinct = list(dict.fromkeys(plans))
        for k, plan in enumerate(distinct):
            rods = [i for i, p in enumerate(plans) if p == plan]
            entry: dict[str, object] = {
                "rods": rods,
                "orders": {
                    name: o
                    for name, f, o in zip(
                        MODE_NAMES, plan.modes, plan.orders, strict=True
                    )
                    if f
                },
                "basis": "Legendre",
                "divisions": plan.n_divisions,
                "n_dof": plan.n_dof,
                "start_joint": plan.start_joint,
                "end_closure": plan.end_loop,
                "driven_end": plan.driven,
                "method": plan.method,
            }
            if plan.method == "statics":
                entry["solver"] = "solve_statics (Newton, rtol=atol=1e-10)"
                entry["if_unstable"] = "damped dynamics (mass-proportional)"
            else:
                heap = contact and _heap(scenario)
                solver, rtol, atol = self._tolerances(
                    contact and _implicit(plan, bool(scenario.obstacles)), heap
                )
                entry.update(solver=solver, rtol=rtol, atol=atol, adaptive=True)
                if heap:
                    entry["controller_gains"] = list(HEAP_CONTROLLER_GAINS)
            if contact and _settles(scenario):
                entry["if_unstable"] = "the settling below, then Newton"
                entry["settle"] = (
                    f"{SETTLE_SOLVER}, constant steps of 1/{SETTLE_STEPS_PER_FRAME} "
                    f"of a frame interval (x time_step_scale) to {SETTLE_FRACTION:g} "
                    "of the duration; the damped dynamics to the end if Newton finds "
                    "no equilibrium from there"
                )
                entry["then"] = (
                    f"solve_statics from the state at {SETTLE_FRACTION:g} of the "
                    f"duration (scaled residual <= {SETTLE_RESIDUAL:g}, stable); "
                    "later frames show it"
                )
            if plan.method == "damped":
                entry["damping"] = "mass-proportional"
                entry["damping_rate"] = 2.0 * scenario.slowest_frequency()
            else:
                entry["damping"] = "none"
            out[f"model{k}" if len(distinct) > 1 else "model"] = entry
        if contact:
            out["model_layout"] = "all rods in one linkage, each on the ground"
            out["contact"] = _laws(scenario, plans[0].method, _spacing(scenario)).info
        out["time_step_scale"] = self.time_step_scale
        return out

    # ----------------------------------------------------------------------- run
    def run(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> Trajectory:
        """Simulate ``scenario`` and sample it at the material nodes.

        Args:
            scenario: the benchmark scene.
            n_elements: elements per rod: ``n_elements + 1`` nodes are returned.
            n_frames: frames, evenly spaced from 0 to ``scenario.duration``.

        Returns:
            The :class:`cosseratbench.Trajectory`.

        Raises:
            NotImplementedError: a scene feature outside these models (driven start,
                displaced end, obstacles, Poisson ratio above 0.5).
            cosseratbench.Diverged: a solve failed or gave non-finite values.
        """
        times = np.linspace(0.0, scenario.duration, n_frames)
        rods = scenario.rods
        if _is_contact_scene(scenario):
            return self._run_scene(scenario, n_elements, times)
        with jax.enable_x64(True):
            models = [
                _build(scenario, rod, n_elements, _plan(scenario, rod, n_elements))
                for rod in rods
            ]
            positions: list = [None] * len(models)
            directors: list = [None] * len(models)
            groups: dict = {}
            for i, mdl in enumerate(models):
                groups.setdefault(mdl.key, []).append(i)
            for members in groups.values():
                results = None
                if models[members[0]].plan.method == "statics":
                    out = self._statics(models[members[0]], scenario, n_frames)
                    if out is not None:
                        results = [out] * len(members)
                    else:  # unstable: the damped dynamics finds a stable one
                        for i in members:
                            plan = dataclasses.replace(models[i].plan, method="damped")
                            models[i] = _build(scenario, rods[i], n_elements, plan)
                if results is None:
                    results = self._dynamics(models, members, times)
                for i, (pos, d1) in zip(members, results, strict=True):
                    p0, R0 = _frame(rods[i])
                    positions[i] = p0 + pos @ R0.T
                    directors[i] = d1 @ R0.T
        return Trajectory(times, tuple(positions), tuple(directors))

    def _run_scene(self, scenario: Scenario, n_elements: int, times) -> Trajectory:
        """A contact scene: all rods in one linkage (:func:`_build_scene`)."""
        rods = scenario.rods
        n1 = n_elements + 1
        with jax.enable_x64(True):
            plans = _scene_plans(scenario, n_elements)
            mdl = _build_scene(scenario, n_elements, plans)
            out = None
            if plans[0].method == "statics":
                out = self._statics(mdl, scenario, len(times), STATICS_MAX_STEPS)
                if out is None:  # unstable: the damped dynamics finds a stable one
                    plans = [dataclasses.replace(p, method="damped") for p in plans]
                    mdl = _build_scene(scenario, n_elements, plans)
            if out is None and _settles(scenario):
                out = self._settle(mdl, times)
            if out is None:
                out = self._dynamics([mdl], [0], times, contact=True)[0]
        pos, d1 = out
        return Trajectory(
            times,
            tuple(pos[:, k * n1 : (k + 1) * n1] for k in range(len(rods))),
            tuple(
                d1[:, k * n_elements : (k + 1) * n_elements] for k in range(len(rods))
            ),
        )

    def _settle(self, mdl: _Model, times):
        """``(positions, d1)``: the damped dynamics, then the equilibrium from there.

        The dynamics runs to :data:`SETTLE_FRACTION` of the duration; Newton's
        method starts from its last state, and every later frame shows the
        equilibrium it finds (:data:`SETTLE_RESIDUAL`). Without one the dynamics
        goes on to the end.
        """
        k = int(np.searchsorted(times, SETTLE_FRACTION * times[-1]))
        k = min(max(k, 1), len(times) - 1)
        (pos, d1), y = self._dynamics(
            [mdl], [0], times[: k + 1], True, state=True, settle=True
        )
        sol = sj.solve_statics(
            mdl.linkage,
            jnp.asarray(y[0, : mdl.linkage.n_dof]),
            throw=False,
            warn_unstable=False,
            max_steps=SETTLE_NEWTON_STEPS,
            load_steps=1,
        )
        found = (
            float(sol.residual_norm) <= SETTLE_RESIDUAL
            and int(sol.n_negative) == 0
            and bool(np.all(np.isfinite(sol.q)))
        )
        if not found:
            return None
        pe, de, _ = _sample(mdl.sampler, sol.q, mdl.nodes, mdl.mids)
        later = len(times) - 1 - k
        return (
            np.concatenate([pos, np.repeat(np.asarray(pe)[None], later, 0)]),
            np.concatenate([d1, np.repeat(np.asarray(de)[None], later, 0)]),
        )

    def _statics(
        self,
        mdl: _Model,
        scenario: Scenario,
        n_frames: int,
        max_steps: int = 64,
        q0=None,
    ):
        """``(positions, d1)`` of the initial shape then the equilibrium, or None.

        None when the equilibrium Newton's method found is unstable.
        """
        sol = sj.solve_statics(
            mdl.linkage,
            mdl.q0 if q0 is None else q0,
            throw=False,
            warn_unstable=False,
            max_steps=max_steps,
            load_steps=None if mdl.laws is None else 1,
        )
        if not (sol.result == sj.RESULTS.successful) or not np.all(np.isfinite(sol.q)):
            raise Diverged(
                "sorojax.solve_statics did not converge (scaled residual "
                f"{float(sol.residual_norm):.3g})",
                time=scenario.duration,
            )
        if not bool(sol.stable):
            return None
        p0, d0, _ = _sample(mdl.sampler, mdl.q0, mdl.nodes, mdl.mids)
        p1, d1, _ = _sample(mdl.sampler, sol.q, mdl.nodes, mdl.mids)
        later = n_frames - 1
        pos = np.concatenate(
            [np.asarray(p0)[None], np.repeat(np.asarray(p1)[None], later, 0)]
        )
        d = np.concatenate(
            [np.asarray(d0)[None], np.repeat(np.asarray(d1)[None], later, 0)]
        )
        return pos, d

    def _dynamics(
        self,
        models,
        members,
        times,
        contact: bool = False,
        state: bool = False,
        settle: bool = False,
    ):
        mdl = models[members[0]]
        c = mdl.linkage.contact
        obstacles = bool(c is not None and c.obstacles)
        heap = bool(contact and c is not None and c.self_contact)
        solver, rtol, atol = self._tolerances(
            contact and _implicit(mdl.plan, obstacles), heap
        )
        dt = None
        if settle:  # only the end state matters: constant implicit Euler steps
            solver = SETTLE_SOLVER
            frame = float(times[1] - times[0])
            dt = frame / SETTLE_STEPS_PER_FRAME * self.time_step_scale
        n = mdl.linkage.n_dof
        B = len(members)
        y = jnp.tile(jnp.concatenate([mdl.q0, jnp.zeros(n)])[None], (B, 1))
        if mdl.angles is not None:
            angles = jnp.asarray(np.stack([models[i].angles for i in members]))
            mtimes = jnp.asarray(mdl.times)
        else:
            angles = mtimes = None
        p0, d0, _ = _sample(mdl.sampler, mdl.q0, mdl.nodes, mdl.mids)
        T = len(times)
        pos = np.empty((B, T, len(mdl.nodes), 3))
        dirs = np.empty((B, T, len(mdl.mids), 3))
        pos[:, 0], dirs[:, 0] = np.asarray(p0), np.asarray(d0)
        C = FRAME_CHUNK
        advance = _advance_long if heap else _advance
        for k in range(1, T, C):
            chunk = np.minimum(np.arange(k, k + C), T - 1)  # pad with the last frame
            ys, p, d, ok, _, result = advance(
                mdl.linkage,
                mdl.sampler,
                mdl.nodes,
                mdl.mids,
                y,
                jnp.asarray(times[k - 1]),
                jnp.asarray(times[chunk]),
                mtimes,
                angles,
                solver,
                rtol,
                atol,
                dt,
                HEAP_CONTROLLER_GAINS if heap else None,
            )
            if not bool(jnp.all(ok)):
                codes = set(np.unique(np.asarray(result._value)).tolist())
                codes.discard(int(sj.RESULTS.successful._value))
                why = [message(c) for c in sorted(codes)]
                why = why or ["a non-finite state"]
                raise Diverged(
                    f"sorojax.simulate ({solver}) failed between t = "
                    f"{times[k - 1]:.4g} and {times[chunk[-1]]:.4g} s: "
                    + "; ".join(why),
                    time=float(times[k - 1]),
                )
            m = min(C, T - k)
            y = ys[:, m - 1]
            pos[:, k : k + m], dirs[:, k : k + m] = (
                np.asarray(p[:, :m]),
                np.asarray(d[:, :m]),
            )
        out = [(pos[b], dirs[b]) for b in range(B)]
        return (out[0], y) if state else out
