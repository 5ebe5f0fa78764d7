"""Time integration of M(q) qdd = f(q, qd, t) with diffrax (the manual's dynamics).

The state is SoRoSim's ``qqd = [q, qd]``; the vector field solves ``M qdd = f`` by one
Cholesky factorisation per evaluation (:mod:`sorojax.dynamics._eom`). The linkage's
constant arrays (K, D, bases, section matrices) are precomputed once per call, outside
the integrator's loop. Implicit solvers take the Jacobian of the vector field by
forward-mode autodiff. The compiled core never raises (no host callback unless a
progress bar is asked for), so JAX's persistent compilation cache can keep it
between runs; failures come back as a result code and are raised by the Python
wrapper when ``throw=True``. diffrax checks the save times inside the program
(``equinox.error_if``, a host callback that keeps the program out of the persistent
cache); sorojax checks them on the host instead (when they are concrete) and traces
``diffeqsolve`` with equinox's runtime errors turned into NaNs
(:func:`_errors_as_nans`), so bad save times under an outer jit give NaNs and a
failed result code rather than an error naming them.
"""

import concurrent.futures
import contextlib
import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike

from .._jit import _bound_arguments, _top_level, in_tiers, jit
from .._recompile import note_function, note_hooks
from .._results import RESULTS, throw_on_failure
from ..dynamics._contact import contact_report, contact_tangent
from ..dynamics._eom import (
    GeneralizedForce,
    InputFunction,
    as_inputs,
    consistent_velocities,
    constrained_dynamics,
    mass_and_force,
    prescribed_motion,
    spd_solve,
)
from ..kinematics._api import _as_q
from ..kinematics._recursion import point_jacobians, point_rates
from ..model._checks import check_finite, check_tolerances, is_concrete
from ..model._link import SoftLink
from ..model._linkage import Linkage
from ..model._precompute import precompute
from ._rosenbrock import MechanicalTerm, RosenbrockEuler, RosenbrockW
from ._trajectory import Trajectory

try:  # diffrax's marker for "take the tolerance from the step-size controller"
    from diffrax._root_finder import use_stepsize_tol as _UNSET
except ImportError:  # pragma: no cover - layout of a future diffrax
    _UNSET = None

SOLVERS: dict[str, Callable[[], diffrax.AbstractSolver]] = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "bosh3": diffrax.Bosh3,
    "dopri8": diffrax.Dopri8,
    "kvaerno3": diffrax.Kvaerno3,
    "kvaerno4": diffrax.Kvaerno4,
    "kvaerno5": diffrax.Kvaerno5,
    "implicit_euler": diffrax.ImplicitEuler,
    "ros34pw2": RosenbrockW,
    "rosenbrock_euler": RosenbrockEuler,
    "rosenbrock_trapezoid": functools.partial(RosenbrockEuler, gamma=0.5),
}
"""Solvers selectable by name; any ``diffrax.AbstractSolver`` instance is also taken."""

DEFAULT_SOLVER = "auto"
"""``"auto"``: ROS34PW2 on damped stiff models, else Tsit5 (Kvaerno5 if very stiff).

Chosen from ``benchmarks/dynamics.py`` (work-precision and stability parts). Soft rods
with material damping have strongly damped fast modes (eigenvalues of the
linearisation ``[[0, I], [-M^-1 K, -M^-1 D]]`` far out on the negative real axis):
they bound an explicit solver's step (``h < 2.8 / |lambda|`` for Tsit5) but not the
motion, and the Rosenbrock-W solver ``"ros34pw2"`` (:class:`RosenbrockW`, linearly
implicit in K and D) steps over them: 5 s of the damped free-fall rod take 0.12 s at
rtol 1e-3 (tip error 5e-5 L) against 0.46 s for Tsit5, 0.11 s vs 0.94 s for 1 s of a
3D motion. When the fastest modes are undamped oscillations (no damping, or a stiff
steel rod whose motion *is* its vibration), they must be resolved anyway and the
explicit Tsit5 is cheaper. ``"auto"`` computes the eigenvalues at ``q0`` (on the
host, once per call) and picks

* ``"ros34pw2"`` when an explicit solver would need more than ``AUTO_STIFF_STEPS``
  steps over ``[t0, t1]``, the fastest eigenvalue is mostly real (damped:
  ``-Re lambda > |Im lambda|``), ``rtol >= AUTO_MIN_RTOL`` (an order-3 method loses
  to high-order explicit ones at very tight tolerances) and the linkage has no
  closed loops (their Baumgarte rows are not in the W matrix, and the step size
  collapses: 5 s of the manual's hybrid took 10 021 ROS34PW2 steps at rtol 1e-3,
  where Tsit5 takes 535 for 2 s);
* else ``"kvaerno5"`` when an explicit solver would need more than
  ``AUTO_VERY_STIFF_STEPS`` steps;
* else ``"dopri8"`` when ``rtol <= AUTO_HIGH_ORDER_RTOL`` and the stability bound
  is far from the step count (at most ``AUTO_HIGH_ORDER_STEPS`` explicit steps
  over ``[t0, t1]``; rigid mechanisms without springs have none): the steps are
  then set by accuracy, where an 8th-order method takes far fewer (the driven
  four-bar over 3 s at rtol 1e-8: 500 steps, 0.33 s, against Tsit5's 1703 steps,
  0.64 s; the program compiles in the same time). Where fast modes must be
  resolved anyway Dopri8 gains nothing (the manual's hybrid over 2 s: at rtol 1e-6
  Tsit5 1.5-1.7 s against 1.9-2.2 s, at rtol 1e-8 about even, 2.9 / 3.5 s against
  3.2 / 3.4 s in two runs on a 2-core CPU);
* else ``"tsit5"``.

Under an outer jit/vmap/grad with traced parameters no host analysis is possible:
``"auto"`` then means ``"ros34pw2"`` for linkages with soft links and no closed
loops (never unstable, 4-10x faster on damped rods, ~3x slower than Tsit5 on
undamped ones) at ``rtol >= AUTO_MIN_RTOL`` and ``"tsit5"`` otherwise; name the
solver to choose.
"""

AUTO_STIFF_STEPS = 1_000
AUTO_VERY_STIFF_STEPS = 20_000
AUTO_MIN_RTOL = 1e-5
AUTO_HIGH_ORDER_RTOL = 1e-7
AUTO_HIGH_ORDER_STEPS = 100


@jit
def _linear_terms(linkage: Linkage, q0):
    from ..dynamics._mass import _mass_from_J
    from ..kinematics._recursion import poses_and_jacobians

    data = precompute(linkage)
    return _mass_from_J(data, poses_and_jacobians(data, q0)[1]), data.K, data.D


def _eigenvalues(linkage: Linkage, q0) -> np.ndarray:
    """Eigenvalues of the linearised state matrix at ``q0`` (at rest)."""
    if _without_springs(linkage):
        # K = D = 0: [[0, I], [0, 0]] is nilpotent, no program of M, K, D needed
        return np.zeros(2 * linkage.n_dof, complex)
    M, K, D = (np.asarray(a) for a in _linear_terms(linkage, q0))
    n = M.shape[0]
    if not n:
        return np.zeros(0, complex)
    MK, MD = np.linalg.solve(M, K), np.linalg.solve(M, D)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-MK, -MD]])
    return np.linalg.eigvals(A)


def stiffness_estimate(linkage: Linkage, q0) -> float:
    """Largest |eigenvalue| [1/s] of the linearised state matrix at ``q0`` (at rest).

    The explicit solvers' stable step is about ``2.8 / stiffness_estimate`` (Tsit5).
    """
    lam = _eigenvalues(linkage, q0)
    return float(np.abs(lam).max()) if lam.size else 0.0


def _without_springs(linkage: Linkage) -> bool:
    """Rigid links only and no joint stiffness or damping: ``K = D = 0``.

    The linearised state matrix is then nilpotent (every eigenvalue 0):
    :func:`_eigenvalues` says so without the program of M, K and D (a rigid
    four-bar's first ``simulate`` with ``solver="auto"``: ~0.3 s).
    """
    if any(isinstance(link, SoftLink) for link in linkage.links):
        return False
    return not any(
        np.any(np.asarray(link.joint.stiffness))
        or np.any(np.asarray(link.joint.damping))
        for link in linkage.links
    )


def auto_solver(linkage: Linkage, q0, t0, t1, rtol: float) -> str:
    """The solver name ``solver="auto"`` takes for this run (see ``DEFAULT_SOLVER``).

    A linkage of rigid links without joint stiffness or damping has no fast modes
    (K = D = 0), decided without computing M (see :func:`_without_springs`): Tsit5,
    or Dopri8 at ``rtol <= AUTO_HIGH_ORDER_RTOL``.

    Args:
        linkage: the model.
        q0: initial coordinates ``(n_dof,)`` (the linearisation point).
        t0: initial time [s].
        t1: final time [s].
        rtol: the relative tolerance of the run.

    Returns:
        ``"ros34pw2"``, ``"kvaerno5"``, ``"dopri8"`` or ``"tsit5"``.
    """
    leaves = jax.tree.leaves(eqx.filter((linkage, q0, t0, t1), eqx.is_array))
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        # Traced model: no host-side analysis; decide from the structure.
        soft = any(isinstance(link, SoftLink) for link in linkage.links)
        rosenbrock = soft and not linkage.closed_loops and rtol >= AUTO_MIN_RTOL
        return "ros34pw2" if rosenbrock else "tsit5"
    lam = _eigenvalues(linkage, q0)
    if not lam.size:
        return "tsit5"
    fastest = lam[np.argmax(np.abs(lam))]
    n_explicit = abs(float(t1) - float(t0)) * abs(fastest) / 2.8
    damped = -fastest.real > abs(fastest.imag)
    loops = bool(linkage.closed_loops)
    if n_explicit > AUTO_STIFF_STEPS and damped and rtol >= AUTO_MIN_RTOL and not loops:
        return "ros34pw2"
    if n_explicit > AUTO_VERY_STIFF_STEPS:
        return "kvaerno5"
    if rtol <= AUTO_HIGH_ORDER_RTOL and n_explicit <= AUTO_HIGH_ORDER_STEPS:
        return "dopri8"
    return "tsit5"


def _is_auto(solver) -> bool:
    return isinstance(solver, str) and solver.lower() == "auto"


def _make_solver(solver) -> diffrax.AbstractSolver:
    if isinstance(solver, diffrax.AbstractSolver):
        return solver
    if isinstance(solver, str) and solver.lower() in SOLVERS:
        return SOLVERS[solver.lower()]()
    raise ValueError(
        f"solver = {solver!r} is not known; give 'auto', one of {sorted(SOLVERS)} or a "
        "diffrax.AbstractSolver instance (e.g. diffrax.Kvaerno5())."
    )


def _root_finder_tolerances(solver, rtol, atol):
    """Give an implicit solver's root finder ``rtol``/``atol`` where they are unset.

    Under adaptive stepping diffrax takes them from the step-size controller; with
    constant steps there is no controller, so the same numbers are set here (with the
    controller's RMS norm) instead of leaving diffrax to refuse the run.
    """
    if _UNSET is None or not isinstance(solver, diffrax.AbstractImplicitSolver):
        return solver
    rf = solver.root_finder
    fields = ("rtol", "atol", "norm")
    values = {"rtol": rtol, "atol": atol, "norm": optx.rms_norm}
    unset = [f for f in fields if getattr(rf, f, None) is _UNSET]
    if not unset:
        return solver
    return eqx.tree_at(
        lambda s: [getattr(s.root_finder, f) for f in unset],
        solver,
        [values[f] for f in unset],
        is_leaf=lambda x: x is _UNSET,
    )


def _needs_inputs(linkage: Linkage) -> bool:
    return bool(
        linkage.actuators
        or linkage.closed_loops
        or linkage.custom_actuation is not None
    )


def _input_function(u_fn, u_const) -> InputFunction:
    if u_fn is None:
        return lambda t: u_const
    return lambda t: jnp.asarray(u_fn(t), dtype=u_const.dtype).reshape(u_const.shape)


@eqx.filter_jit
def _rates(linkage: Linkage, data, t, y, u_fn, u_const, generalized_force):
    """``(qd, qdd)``, the stiff part ``(M, K, D)`` and the constrained state.

    ``K`` and ``D`` are the model's constant ones, plus the contacts' tangent
    stiffness and damping when the linkage's contact puts them in W
    (``Contact.tangent_in_w``); the constrained state is None without inputs.

    Jitted so that the right-hand side is traced once for the compiled program:
    diffrax calls the vector field from several places (first stage, the stage loop)
    and the efforts at the save points call it again; each call with the same
    argument types reuses the first trace and its lowering (XLA inlines the calls).
    diffrax's term check (an ``eval_shape``) traces it once more: 2 traces, from 5.
    """
    n = y.shape[0] // 2
    q, qd = y[:n], y[n:]
    tangent = linkage.contact is not None and linkage.contact.tangent_in_w
    if not _needs_inputs(linkage):
        rates = point_rates(data, q, qd)
        M, f = mass_and_force(linkage, data, t, q, qd, generalized_force, rates=rates)
        ydot, st = jnp.concatenate([qd, spd_solve(M, f)]), None
    else:
        st, rates = constrained_dynamics(
            linkage, data, t, q, qd, _input_function(u_fn, u_const), generalized_force,
            return_rates=True,
        )  # fmt: skip
        ydot, M = jnp.concatenate([st.qd, st.qdd]), st.M
    if tangent:  # the contacts' stiffness and damping join W (ROS34PW2)
        J = point_jacobians(data, rates)  # the leaves' too: contacts sit on them
        Kc, Dc = contact_tangent(linkage, t, rates.g, J, rates.eta)
        return ydot, (M, data.K + Kc, data.D + Dc), st
    return ydot, (M, data.K, data.D), st


def consistent_start(linkage: Linkage, data, t0, y0, u_fn, u_const) -> Array:
    """``y0 = (q, qd)`` with qd projected onto the velocity constraints.

    Prescribed coordinates and closed loops; unchanged for a linkage without inputs.
    """
    if not _needs_inputs(linkage):
        return y0
    n = y0.shape[0] // 2
    qd0 = consistent_velocities(
        linkage, data, t0, y0[:n], y0[n:], _input_function(u_fn, u_const)
    )
    return jnp.concatenate([y0[:n], qd0])


class _Field(eqx.Module):
    """The dynamics' vector field: ``(qd, qdd)`` and the stiff part (M, K, D).

    It closes over no array: the arrays the dynamics read (the linkage's, its
    derived data, the constant inputs, and those of ``u`` and
    ``generalized_force`` functions) come in ``args`` as a flat list
    (:func:`_vector_field`), and the rest of their pytrees (structure, functions,
    Python values) is static here. diffrax's ``BacksolveAdjoint`` differentiates
    through ``args`` only: a traced array that the field closed over would leak out
    of its backward solve, and it cannot take empty tuples (a linkage without
    cables) inside ``args``.
    """

    treedef: Any = eqx.field(static=True)
    static: tuple = eqx.field(static=True)  # the non-array leaves, None at arrays

    def __call__(self, t, y, args):
        leaves = iter(args)
        parts = [next(leaves) if x is None else x for x in self.static]
        linkage, data, u_const, u_fn, generalized_force = jax.tree_util.tree_unflatten(
            self.treedef, parts
        )
        ydot, stiff, _ = _rates(linkage, data, t, y, u_fn, u_const, generalized_force)
        return ydot, stiff


def _vector_field(
    linkage: Linkage, data, u_const, u_fn, generalized_force
) -> tuple[MechanicalTerm, list]:
    """``(term, args)``: the dynamics as a diffrax term and its ``args``."""
    leaves, treedef = jax.tree_util.tree_flatten(
        (linkage, data, u_const, u_fn, generalized_force)
    )
    arrays = [x for x in leaves if eqx.is_array(x)]
    static = tuple(None if eqx.is_array(x) else x for x in leaves)
    return MechanicalTerm(_Field(treedef, static)), arrays


def _result_code(sol: diffrax.Solution, constant_step: bool) -> RESULTS:
    """The sorojax result code of a diffrax solution.

    A successful solve whose saved states are not all finite failed: at a constant
    step it is ``unstable_step`` (the step is too large for the scheme), with
    adaptive steps ``nonlinear_divergence``.
    """
    finite = jnp.all(jnp.isfinite(sol.ys))
    ok = sol.result == diffrax.RESULTS.successful
    steps = sol.result == diffrax.RESULTS.max_steps_reached
    code = RESULTS.where(steps, RESULTS.max_steps_reached, RESULTS.failed)
    code = RESULTS.where(ok, RESULTS.successful, code)
    bad = RESULTS.unstable_step if constant_step else RESULTS.nonlinear_divergence
    return RESULTS.where(ok & ~finite, bad, code)


@contextlib.contextmanager
def _errors_as_nans():
    """Trace with equinox's runtime errors as NaNs: no host callback in the program.

    ``equinox.error_if`` reads ``EQX_ON_ERROR`` (an environment variable, read once at
    import) from its module at trace time; the setting is changed for the duration
    of the trace only. Without that module attribute (another equinox) nothing changes.
    """
    from equinox import _errors

    old = getattr(_errors, "EQX_ON_ERROR", None)
    if old is None:
        yield
        return
    _errors.EQX_ON_ERROR = "nan"
    try:
        yield
    finally:
        _errors.EQX_ON_ERROR = old


def _own_rms_norm(norm, locked):
    """``norm`` (an RMS) rescaled to the mean over the model's own components.

    A size-class model's padded states have zero error (they stay at zero), so the
    plain RMS over the padded state would be smaller than the model's own by
    ``sqrt(n_own / n)``: larger steps than the unpadded model takes at the same
    tolerances. Rescaled, the steps and the trajectory are the unpadded model's.
    """
    n_own = jnp.maximum(2.0 * jnp.sum(1.0 - locked), 1.0)

    def own(x):
        n = sum(leaf.size for leaf in jax.tree_util.tree_leaves(x))
        return norm(x) * jnp.sqrt(n / n_own)

    return own


# At XLA's default level from the first call (an integration runs long by design) and
# with the long-run options: the grasp's constant steps run 10-15 % faster for a
# compile ~4 % longer (2-core CPU); at -O0 (the test suite) the compile is unchanged.
@functools.partial(jit, tiered=False, long_run=True)
def _simulate(
    linkage: Linkage,
    y0: Array,
    t0: Array,
    t1: Array,
    ts: Array,
    solver: diffrax.AbstractSolver,
    controller: diffrax.AbstractStepSizeController,
    dt0: Array | None,
    max_steps: int,
    generalized_force,
    progress_meter: diffrax.AbstractProgressMeter,
    adjoint: diffrax.AbstractAdjoint,
    u_fn,
    u_const: Array,
    extras_inline: bool,
) -> Trajectory:
    data = precompute(linkage)
    y0 = consistent_start(linkage, data, t0, y0, u_fn, u_const)
    if data.locked is not None and isinstance(controller, diffrax.PIDController):
        controller = eqx.tree_at(
            lambda c: c.norm, controller, _own_rms_norm(controller.norm, data.locked)
        )
    term, field_args = _vector_field(linkage, data, u_const, u_fn, generalized_force)
    sol = diffrax.diffeqsolve(
        term,
        solver,
        t0,
        t1,
        dt0,
        y0,
        args=field_args,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=controller,
        max_steps=max_steps,
        adjoint=adjoint,
        throw=False,
        progress_meter=progress_meter,
    )
    n = y0.shape[0] // 2
    assert sol.ys is not None and sol.ts is not None and sol.stats is not None
    result = _result_code(sol, isinstance(controller, diffrax.ConstantStepSize))
    extra = {}
    if extras_inline:  # else computed by _saved_extras
        extra, result = _extras_at(
            linkage, data, sol.ts, sol.ys, u_fn, u_const, generalized_force, result,
            False,
        )  # fmt: skip
    return Trajectory(
        solver=type(solver).__name__,
        t=sol.ts,
        q=sol.ys[:, :n],
        qd=sol.ys[:, n:],
        result=result,
        num_steps=sol.stats["num_steps"],
        num_accepted_steps=sol.stats["num_accepted_steps"],
        num_rejected_steps=sol.stats["num_rejected_steps"],
        **extra,
    )


def _inputs_at(linkage, data, ts, ys, u_fn, u_const, generalized_force, batched):
    """Inputs, prescribed efforts and loop multipliers at the save points.

    ``batched``: one vmapped evaluation of all save points, else a ``lax.map`` of
    one (one copy of the right-hand side in the program). At XLA's default level
    they run equally fast and the map compiles ~20 % faster, so it serves inside
    the integration's program; at -O0 the batch runs 1.7x faster (the grasp's 61
    save points: 28 against 48 ms) and compiles as fast.
    """

    def at(t, y):
        return _rates(linkage, data, t, y, u_fn, u_const, generalized_force)[2]

    st = jax.vmap(at)(ts, ys) if batched else jax.lax.map(lambda ty: at(*ty), (ts, ys))
    return st.u, st.efforts, st.lam


def _needs_extras(linkage: Linkage) -> bool:
    """Whether a trajectory carries more than its states at the save points."""
    return _needs_inputs(linkage) or linkage.contact is not None


def _extras_at(
    linkage, data, ts, ys, u_fn, u_const, generalized_force, result, batched
):  # fmt: skip
    """``(extras, result)``: :class:`Trajectory` fields at the save points.

    The inputs, prescribed efforts and loop multipliers (:func:`_inputs_at`) and
    the contact report (:func:`~sorojax.dynamics._contact.contact_report`, which
    may turn ``result`` into a contact code); ``batched``: the efforts' save points
    in one batch (:func:`_inputs_at`).
    """
    extra = {}
    if _needs_inputs(linkage):
        u, efforts, lam = _inputs_at(
            linkage, data, ts, ys, u_fn, u_const, generalized_force, batched
        )
        extra = {"u": u, "efforts": efforts, "lam": lam}
    if linkage.contact is not None:
        n = ys.shape[1] // 2
        extra["contact"], result = contact_report(
            linkage, data, ts, ys[:, :n], ys[:, n:], result
        )
    return extra, result


@jit
def _saved_extras(linkage, ts, q, qd, u_fn, u_const, generalized_force, result):
    """:func:`_extras_at` as a program of its own, for top-level ``simulate`` calls.

    The efforts hold a copy of the right-hand side and the contact report one of
    the contacts' kinematics and geometry: inside the integration's program,
    compiled at XLA's default level, they lengthen its compile (the efforts the
    manual hybrid's dynamics by ~1.5 s, 2.6 against 4.1 s; the report the grasp's
    by ~2 s, a first call of 10.2 against 7.6 s), where on their own they are
    compiled in sorojax's tiers (-O0 first; they run once per trajectory), in a
    thread while the integration compiles, the efforts' save points in one batch
    (at -O0 the grasp's 61 take 28 ms, against 7.7 ms once compiled at the
    default level; the tiers' second compile starts when their budget is spent,
    and one started at the first call shares the 2-core CPU with the calls that
    follow). With every program at the default level (``SOROJAX_COMPILE=full``)
    they stay inside. It takes ``q`` and ``qd`` as the trajectory holds them
    (joined here, not by an eager operation that would compile a program of its
    own).
    """
    ys = jnp.concatenate([q, qd], axis=1)
    return _extras_at(
        linkage, precompute(linkage), ts, ys, u_fn, u_const, generalized_force,
        result, True,
    )  # fmt: skip


def simulate(
    linkage: Linkage,
    t1: ArrayLike,
    q0: ArrayLike | None = None,
    qd0: ArrayLike | None = None,
    *,
    t0: ArrayLike = 0.0,
    ts: ArrayLike | None = None,
    n_save: int = 101,
    solver: str | diffrax.AbstractSolver = DEFAULT_SOLVER,
    rtol: float = 1e-3,
    atol: float = 1e-5,
    dt0: float | None = None,
    adaptive: bool | None = None,
    max_steps: int = 16384,
    generalized_force: GeneralizedForce | None = None,
    u: ArrayLike | InputFunction | None = None,
    progress: bool = False,
    adjoint: diffrax.AbstractAdjoint | None = None,
    throw: bool = True,
    controller_gains: tuple[float, float] | None = None,
) -> Trajectory:
    """Integrate the linkage's dynamics from ``t0`` to ``t1``.

    Args:
        linkage: the model (gravity, point wrenches and the custom hook included).
        t1: final time [s].
        q0: initial coordinates ``(n_dof,)`` (default zeros: the reference shape).
        qd0: initial velocities ``(n_dof,)`` (default zeros).
        t0: initial time [s].
        ts: save times (increasing, within ``[t0, t1]``); default ``n_save`` evenly
            spaced times from ``t0`` to ``t1``.
        n_save: number of save times when ``ts`` is not given.
        solver: ``"auto"`` (default: the Rosenbrock-W ``"ros34pw2"`` when the
            linearised model at ``q0`` has fast damped modes, else Tsit5, or Kvaerno5
            when very stiff; see ``DEFAULT_SOLVER``; under an outer jit/vmap/grad
            with traced parameters ``"auto"`` decides from the structure), a name in
            ``sorojax.integrate.SOLVERS`` or any ``diffrax.AbstractSolver``. The
            constant-step ``"rosenbrock_euler"`` (linearly implicit Euler,
            :class:`~sorojax.integrate.RosenbrockEuler`: one evaluation and one
            solve per step with ROS34PW2's W, the contacts' tangent included) is
            the fast choice for contact-rich scenes, batches and learning loops
            at first-order accuracy: give ``dt0``.
        rtol: relative tolerance of the adaptive step-size controller (default 1e-3,
            as MATLAB's ode15s in SoRoSim: on the free-fall rod the tip error is then
            ~5e-5 L, far below the error of a cubic strain basis; tighten it, and
            name an explicit solver such as ``"dopri8"``, for reference solutions).
        atol: absolute tolerance (states are ``q`` [-, or m / rad for joints] and
            ``qd`` [1/s]).
        dt0: initial step [s]; chosen automatically when adaptive and ``None``;
            the step of a constant-step run.
        adaptive: adaptive steps (PID controller) or, if ``False``, constant steps
            of ``dt0``. Default ``None``: constant steps for the constant-step
            solvers (``"rosenbrock_euler"``, ``"rosenbrock_trapezoid"``), adaptive
            ones for the others.
        max_steps: most steps before giving up (``RESULTS.max_steps_reached``).
        generalized_force: optional ``tau(t, q, qd) -> (n_dof,)`` generalised
            actuation force (pure JAX), added to the right-hand side.
        u: actuation inputs ``(n_inputs,)`` (constant), or a pure JAX function
            ``t -> (n_inputs,)`` (see ``Linkage.input_slices``): joint forces, cable
            tensions (> 0 pulls), and for prescribed joints the coordinates q(t),
            whose velocities and accelerations are taken by autodiff (give a smooth
            function). Default zeros. Prescribed coordinates start at u(t0), u'(t0)
            whatever q0, qd0 say; with closed loops qd0 is projected onto the
            velocity constraints (least kinetic-energy change), while q0 must be
            assembled (e.g. from ``solve_statics``). A function closing over
            traced values (under ``jax.grad``) must be an ``equinox.Partial``.
        progress: show a tqdm progress bar (its host callback makes the compiled
            program uncacheable; leave off in batch runs).
        adjoint: a diffrax adjoint for gradients (default
            ``diffrax.RecursiveCheckpointAdjoint()``: exact reverse-mode gradients;
            for forward mode, ``jax.jvp`` / ``jax.jacfwd`` through ``simulate``,
            pass ``diffrax.ForwardMode()``, as examples/system_identification.py
            does: the same exact derivative, and for a few parameters the faster
            one to compile and often to run: d(tip)/d(E, eta) over 1 s of the
            damped free-fall rod compiles in 5.2-6.1 s against 12.6-14.9 s, 81-105
            against 100-104 ms warm, ``benchmarks/gradients.py``).
            ``diffrax.BacksolveAdjoint`` (the continuous adjoint, memory
            independent of the number of steps) needs a backward solver that takes
            pytree states: for a non-stiff model
            ``BacksolveAdjoint(solver=diffrax.Tsit5())``; with ``"ros34pw2"`` as
            the backward solver (the default solver's usual pick) it is refused.
            For a stiff, damped rod it is no use: on the damped free-fall rod the
            backward Tsit5 solve gave a gradient of 1e19 (the exact one: -0.019)
            and a Kvaerno5 one did not finish its first call within 10 minutes on
            a 2-core CPU.
        throw: raise ``RuntimeError`` on failure (under an outer jit an equinox
            runtime error); use ``throw=False`` under ``vmap`` and read ``result``.
        controller_gains: ``(pcoeff, icoeff)``, the proportional and integral
            gains of the adaptive step-size controller (``diffrax.PIDController``'s,
            scaled by the method's order there). Default: ``(0.3, 0.3)``, PI
            control, for implicit and Rosenbrock solvers; ``(0, 1)``, integral
            control, for explicit ones. PI control damps the step size's swings
            where an explicit solver's steps sit at its stability limit: on
            cosseratbench's pile (Bogacki-Shampine, a heaping rope) ``(0.3, 0.3)``
            took 17,000 steps against 18,500, a quarter of them rejected under
            integral control.

    Returns:
        A :class:`Trajectory`.

    Raises:
        ValueError: bad shapes, unknown solver, ``ts`` outside ``[t0, t1]``.
        RuntimeError: the integration failed and ``throw`` is True.
    """
    plan = _plan(
        linkage, t1, q0, qd0, t0, ts, n_save, solver, rtol, atol, dt0, adaptive,
        max_steps, generalized_force, u, progress, adjoint, controller_gains,
    )  # fmt: skip
    with _errors_as_nans():
        # The extras' program (efforts, contact report) depends on the
        # trajectory's shapes only: it is traced and compiled in a thread while
        # the integration compiles and runs (their first call waits for it; manual
        # hybrid example 1.7 s of trace, lowering and -O0 compile taken off its
        # path). The integration's own trace comes first, alone: two traces at
        # once take turns on Python's lock, and the integration's is on the call's
        # path (the grasp's first call: its integration compiled 1.9 s sooner).
        ahead = []
        if plan.separate:
            _simulate.lower_first(*plan.args)
            ahead = [f for f in [_saved_extras.compile_ahead(*plan.extras_args)] if f]
        try:
            traj = _simulate(*plan.args)
        finally:  # the thread traces under _errors_as_nans too
            if ahead:
                concurrent.futures.wait(ahead)
        if plan.separate:
            _, _, _, _, u_fn, u_const, gf, _ = plan.extras_args
            extra, result = _saved_extras(
                linkage, traj.t, traj.q, traj.qd, u_fn, u_const, gf, traj.result
            )
            traj = eqx.tree_at(
                lambda tr: [getattr(tr, k) for k in extra] + [tr.result],
                traj,
                list(extra.values()) + [result],
                is_leaf=lambda x: x is None,
            )
    if not throw:
        return traj
    return throw_on_failure(
        traj,
        lambda message: (
            f"simulate failed: {message} After {int(traj.num_steps)} steps "
            f"({int(traj.num_rejected_steps)} rejected). For a stiff model use an "
            "implicit solver ('kvaerno5', 'kvaerno3', 'implicit_euler'); otherwise "
            "raise max_steps, loosen rtol/atol, or pass throw=False to inspect the "
            "trajectory up to the failure."
        ),
    )


def _check_adjoint(adjoint, solver) -> None:
    """Refuse a backward solve that the Rosenbrock-W solver cannot take."""
    if not isinstance(adjoint, diffrax.BacksolveAdjoint):
        return
    backward = adjoint.kwargs.get("solver", solver)
    if isinstance(backward, RosenbrockW):
        raise ValueError(
            "adjoint = diffrax.BacksolveAdjoint() integrates the state together with "
            "its adjoints backwards in time (a pytree state), and its backward solver "
            f"would be {type(backward).__name__} ('ros34pw2', which 'auto' picks for "
            "damped rods), which takes one-dimensional array states only. For a "
            "non-stiff model give the backward pass an explicit solver of its own, "
            "e.g. diffrax.BacksolveAdjoint(solver=diffrax.Tsit5()); otherwise keep "
            "the default adjoint (RecursiveCheckpointAdjoint: the exact gradient of "
            "the computed trajectory, the one for stiff, damped models; "
            "BacksolveAdjoint's is the continuous adjoint's, accurate to the "
            "backward solve's tolerance)."
        )


def _check_span(t0, t1, ts) -> None:
    """Refuse a concrete time span that is not finite and forward (or bad ts)."""
    for name, value in (("t0", t0), ("t1", t1)):
        check_finite(name, value, "give the time in seconds")
    if is_concrete(t0) and is_concrete(t1) and float(t1) < float(t0):
        raise ValueError(
            f"t1 = {float(t1)!r} is before t0 = {float(t0)!r}: simulate integrates "
            "forward in time; give t1 >= t0 (to run backwards, negate time in your "
            "model)."
        )
    if ts is not None and is_concrete(ts):
        ts_np = np.asarray(ts, dtype=float).reshape(-1)
        check_finite("ts", ts_np, "give finite save times in seconds")
        back = np.flatnonzero(np.diff(ts_np) < 0)
        if back.size:
            i = int(back[0])
            raise ValueError(
                f"ts[{i + 1}] = {ts_np[i + 1]!r} is before ts[{i}] = {ts_np[i]!r}: "
                "give save times in increasing order."
            )


def _adaptive(name, solver, adaptive: bool | None) -> bool:
    """Adaptive steps or not: ``adaptive``, or by default whether the solver can.

    ``solver`` is None for ``"auto"`` (an adaptive solver). A solver without an
    error estimate (not a ``diffrax.AbstractAdaptiveSolver``) asked for adaptive
    steps is refused.
    """
    can = solver is None or isinstance(solver, diffrax.AbstractAdaptiveSolver)
    if adaptive is None:
        return can
    if adaptive and not can:
        raise ValueError(
            f"solver = {name!r} takes constant steps (it has no error estimate for "
            "step control) but adaptive = True: leave adaptive at None (or give "
            "False) and give the step as dt0, or choose an adaptive solver such as "
            "'ros34pw2'."
        )
    return bool(adaptive)


def _check_constant_steps(t0, t1, dt0, max_steps) -> None:
    """Refuse a constant step that cannot reach ``t1`` within ``max_steps``."""
    if dt0 is None:
        raise ValueError(
            "adaptive=False (or a constant-step solver such as 'rosenbrock_euler') "
            "needs a step: dt0 = None; give dt0 (the constant step, in s)."
        )
    if all(is_concrete(x) for x in (t0, t1, dt0)):
        need = math.ceil((float(t1) - float(t0)) / float(dt0) - 1e-9)
        if need > max_steps:
            raise ValueError(
                f"dt0 = {float(dt0)!r} takes {need} constant steps from t0 = "
                f"{float(t0)!r} to t1 = {float(t1)!r}, more than max_steps = "
                f"{max_steps}: give max_steps >= {need} or a larger dt0."
            )


def _check_steps(rtol, atol, dt0, adaptive) -> None:
    """Refuse step-control settings that cannot work (concrete values only)."""
    if adaptive:
        check_tolerances(
            rtol,
            atol,
            "defaults rtol 1e-3, atol 1e-5",
            "no step would ever be accepted",
        )
    if dt0 is not None and is_concrete(dt0) and not 0 < float(dt0) < math.inf:
        raise ValueError(
            f"dt0 = {dt0!r}: give the (initial) step in seconds, finite and > 0, or "
            "None to let the adaptive controller choose it."
        )


def _check_gains(gains) -> tuple[float, float]:
    """``controller_gains`` as two finite floats, the integral gain positive."""
    try:
        p, i = (float(x) for x in gains)
        ok = np.isfinite(p) and np.isfinite(i) and i > 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(
            f"controller_gains = {gains!r}: give (pcoeff, icoeff), two finite "
            "numbers with icoeff > 0, e.g. (0.3, 0.3) for PI control."
        )
    return p, i


class _Plan(NamedTuple):
    """What :func:`simulate` decided on the host: the compiled core's arguments."""

    args: tuple  # of _simulate
    separate: bool  # the extras at the save points are a program of their own
    extras_args: tuple  # of _saved_extras, with the save points' shapes


def _plan(
    linkage, t1, q0, qd0, t0, ts, n_save, solver, rtol, atol, dt0, adaptive,
    max_steps, generalized_force, u, progress, adjoint, controller_gains=None,
) -> _Plan:  # fmt: skip
    """:func:`simulate`'s checks and host-side choices, up to its compiled core."""
    # default zeros made on the host (jnp.zeros compiles a program per size)
    zeros = np.zeros(linkage.n_dof)
    q0 = _as_q(linkage, zeros if q0 is None else q0, "q0")
    qd0 = _as_q(linkage, zeros.astype(q0.dtype) if qd0 is None else qd0, "qd0")
    dtype = q0.dtype
    check_finite("q0", q0, "give finite initial coordinates (default zeros)")
    check_finite("qd0", qd0, "give finite initial velocities (default zeros)")
    _check_span(t0, t1, ts)
    solver_ = _make_solver(solver) if not _is_auto(solver) else None
    adaptive = _adaptive(solver, solver_, adaptive)
    _check_steps(rtol, atol, dt0, adaptive)
    t0_, t1_ = jnp.asarray(t0, dtype=dtype), jnp.asarray(t1, dtype=dtype)
    u_fn, u_const = _split_inputs(linkage, u, dtype)
    if _top_level():  # a call of its own (not inside a user's trace)
        for fn, what in ((u_fn, "u"), (generalized_force, "generalized_force")):
            note_function(fn, what, "simulate")
        note_hooks(linkage, "simulate")
    if ts is None and n_save < 1:
        raise ValueError(f"n_save = {n_save}; give at least 1 save time.")
    q0, y0, ts_ = _initial_state(
        linkage, q0, qd0, t0_, t1_, u_fn, u_const, n_save if ts is None else None
    )
    if ts is not None:
        ts_ = jnp.asarray(ts, dtype=dtype).reshape(-1)
        if not isinstance(ts_, jax.core.Tracer) and not isinstance(
            t1_, jax.core.Tracer
        ):
            if ts_.size == 0 or bool(ts_[0] < t0_) or bool(ts_[-1] > t1_):
                raise ValueError(
                    f"ts spans [{float(ts_[0]) if ts_.size else 'empty'}, "
                    f"{float(ts_[-1]) if ts_.size else 'empty'}]; save times must lie "
                    f"within [t0, t1] = [{float(t0_)}, {float(t1_)}]."
                )
    if max_steps < 1:
        raise ValueError(f"max_steps = {max_steps}; give a positive integer.")
    if not adaptive:
        _check_constant_steps(t0, t1, dt0, max_steps)
    if solver_ is None:  # "auto": chosen from the linearisation at q0
        solver_ = _make_solver(auto_solver(linkage, q0, t0_, t1_, rtol))
    if adaptive:
        if controller_gains is not None:
            p, i = _check_gains(controller_gains)
            controller = diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=p, icoeff=i)
        elif isinstance(solver_, diffrax.AbstractImplicitSolver | RosenbrockW):
            # PI control: the plain I controller makes implicit solvers on damped
            # rods alternate accept/reject (measured: 320 steps, 149 rejected vs
            # 117 steps, 15 rejected for Kvaerno5 over 0.5 s of the free-fall rod).
            controller = diffrax.PIDController(
                rtol=rtol, atol=atol, pcoeff=0.3, icoeff=0.3
            )
        else:
            controller = diffrax.PIDController(rtol=rtol, atol=atol)
    else:
        controller = diffrax.ConstantStepSize()
        solver_ = _root_finder_tolerances(solver_, rtol, atol)
    dt0_ = None if dt0 is None else jnp.asarray(dt0, dtype=dtype)
    meter = diffrax.TqdmProgressMeter() if progress else diffrax.NoProgressMeter()
    adjoint = diffrax.RecursiveCheckpointAdjoint() if adjoint is None else adjoint
    _check_adjoint(adjoint, solver_)
    # In the compile tiers the efforts and the contact report at the save points
    # are a program of their own, compiled at -O0 (see _saved_extras); compiled
    # at the default level they cost about as much inside the integration's
    # program as apart, and inside a trace they are part of the caller's program.
    inline = not in_tiers()
    args = (
        linkage, y0, t0_, t1_, ts_, solver_, controller, dt0_, max_steps,
        generalized_force, meter, adjoint, u_fn, u_const, inline,
    )  # fmt: skip
    # q, qd of the saved states: shapes only
    shapes = np.zeros((ts_.shape[0], y0.shape[0] // 2), y0.dtype)
    return _Plan(
        args,
        not inline and _needs_extras(linkage),
        (linkage, ts_, shapes, shapes, u_fn, u_const, generalized_force,
         RESULTS.successful),
    )  # fmt: skip


def prepare_simulate(*args, **kwargs) -> concurrent.futures.Future | None:
    """Compile the programs of ``simulate(...)`` (same arguments) in a worker thread.

    :func:`sorojax.prepare` with :func:`simulate`. Traces and lowers the
    integration's program (and, in the compile tiers, the extras' program) here;
    their XLA compiles run in a worker thread while the caller goes on, and the
    later ``simulate`` call with arguments of the same shapes and the same settings
    waits for them instead of compiling. Nothing is integrated. Array values do not
    matter, except where ``simulate`` decides on the host from them: ``solver="auto"``
    picks the solver from ``q0``, ``t0`` and ``t1`` (name the solver, or give the
    values of the later call). Returns the future of the integration's compile
    (None inside a trace, or when that program is compiled or prepared already).
    """
    # throw: the same program either way
    plan = _plan(**_bound_arguments(simulate, args, kwargs, ("throw",)))
    with _errors_as_nans():
        future = _simulate.prepare(*plan.args)
    if plan.separate:
        _saved_extras.prepare(*plan.extras_args)
    return future


simulate.prepare = prepare_simulate


@jit
def _initial_state(linkage: Linkage, q0, qd0, t0, t1, u_fn, u_const, n_save):
    """``(q0, y0, ts)`` with the prescribed coordinates started on their motion.

    The prescribed coordinates take u(t0) and its derivative; ``ts`` is ``n_save``
    evenly spaced save times (None when ts is given).

    One compiled program instead of a dozen single operations run one by one (each
    compiled on first use).
    """
    qi, _ = linkage.prescribed
    if len(qi):
        qp, qdp, _ = prescribed_motion(linkage, _input_function(u_fn, u_const), t0)
        q0, qd0 = q0.at[qi].set(qp), qd0.at[qi].set(qdp)
    y0 = jnp.concatenate([q0, qd0.astype(q0.dtype)])
    return q0, y0, None if n_save is None else jnp.linspace(t0, t1, n_save)


def _split_inputs(linkage: Linkage, u, dtype):
    """``(function or None, constant array)`` from the ``u`` argument of simulate."""
    m = linkage.n_inputs
    if callable(u):
        if m == 0:
            raise ValueError(
                "u is a function but this linkage has no actuators (n_inputs = 0): "
                "add actuators to Linkage(actuators=...) or drop u."
            )
        return u, as_inputs(linkage, None, dtype)
    if u is None:
        return None, as_inputs(linkage, None, dtype)
    u = jnp.asarray(u, dtype=dtype).reshape(-1)
    if u.shape != (m,):
        raise ValueError(
            f"u has shape {u.shape}; this linkage has n_inputs = {m} (see "
            "Linkage.input_slices): give one entry per input, or a function of t."
        )
    check_finite("u", u, "give finite inputs (tensions [N], joint efforts, ...)")
    return None, u
