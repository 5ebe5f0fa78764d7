"""A pure, jit-able and vmap-able environment for control and learning.

In the style JAX users know from brax, MJX and gymnax: the model and its settings
are an immutable :class:`Environment`; the state is a small pytree
(:class:`EnvState`); ``reset(key) -> state`` and ``step(state, action) -> state``
are pure functions, so ``jax.jit``, ``jax.vmap`` (over states, actions, keys or
stacked environments), ``jax.grad`` (through whole rollouts: analytic policy
gradients) and ``jax.lax.scan`` compose with them. One ``step`` integrates the
dynamics over one control period with :func:`sorojax.simulate` (the same solver,
tolerances and adjoint), saving only the period's end, and never raises: a failed
integration leaves a :class:`sorojax.RESULTS` code in ``state.result`` and the
state where it was (masked, so that one failed member of a batch does not poison
the others with ``inf``).

What does not live here: observation normalisation, reward functions, episode
termination (write them as plain functions of the state; the helpers below give the
usual observations), and training loops (see ``examples/learn_reach.py``).
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int, PRNGKeyArray

from .._jit import jit
from .._results import RESULTS
from ..dynamics._actuation import cable_lengths
from ..dynamics._contact import contact_state, pair_link_b
from ..integrate._simulate import (
    _initial_state,
    _make_solver,
    _root_finder_tolerances,
    _vector_field,
    consistent_start,
    simulate,
)
from ..kinematics._api import screw_strains, tip_pose
from ..kinematics._recursion import poses_and_jacobians
from ..model._actuation import Cable
from ..model._checks import is_concrete
from ..model._linkage import Linkage
from ..model._precompute import precompute


class EnvState(eqx.Module):
    """The state of an :class:`Environment` (a pytree: batch it with ``vmap``).

    Attributes:
        q: (n_dof,) coordinates.
        qd: (n_dof,) velocities [1/s, or m/s, rad/s for joints].
        t: () time [s].
        u: (n_inputs,) the inputs applied over the last period (prescribed
            coordinates ramp from these to the next action's).
        result: () int, ``RESULTS`` code of the last step (0: successful). A failed
            step keeps ``q``, ``qd`` and ``t`` of the state before it.
        steps: () int, solver steps taken by the last period's integration.
    """

    q: Float[Array, " n_dof"]
    qd: Float[Array, " n_dof"]
    t: Float[Array, ""]
    u: Float[Array, " n_inputs"]
    result: Int[Array, ""]
    steps: Int[Array, ""]


def _cable_mask(linkage: Linkage) -> np.ndarray:
    mask = np.zeros(linkage.n_inputs, bool)
    for a, sl in zip(linkage.actuators, linkage.input_slices, strict=True):
        if isinstance(a, Cable):
            mask[sl] = True
    return mask


class Environment(eqx.Module):
    """A linkage under feedback control at a fixed control period.

    Actions map onto the linkage's inputs ``u`` (see ``Linkage.input_slices``):
    ``u = action_scale * action``, then cable tensions are clipped at zero (a
    cable cannot push). Joint forces and tensions are held over a period (zero-order
    hold); prescribed joint coordinates ramp linearly from the previous inputs to
    the new ones over the period (first-order hold: a prescribed coordinate must be
    continuous; its velocity jumps at the control instants).

    Attributes:
        linkage: the model.
        period: control period [s].
        solver: a solver name of ``sorojax.integrate.SOLVERS`` (default
            ``"ros34pw2"``, the Rosenbrock-W method: no Newton iterations, stable on
            damped rods) or a diffrax solver. ``"auto"`` is not accepted (it would
            decide per call from the state).
        rtol: relative tolerance of the adaptive steps.
        atol: absolute tolerance.
        dt: constant solver step [s] (``period`` a multiple of it), or None for
            adaptive steps. Constant steps make ``step`` a smooth function of its
            inputs (adaptive step choices are piecewise constant in them, so finite
            differences of an adaptive rollout carry the tolerance's noise).
        max_steps: most solver steps per period.
        action_scale: (n_inputs,) or () factor from actions to inputs.
        q0: (n_dof,) coordinates at reset (assembled, for closed loops).
        qd0: (n_dof,) velocities at reset.
        u0: (n_inputs,) inputs before the first action (prescribed coordinates'
            starting values; default zeros).
        noise: () or (n_dof,) standard deviation of the random perturbation of
            ``q0`` at reset [coordinate units] (0: a deterministic reset).
        adjoint: the diffrax adjoint for gradients through ``step`` (default
            ``diffrax.RecursiveCheckpointAdjoint()``).
    """

    linkage: Linkage
    period: float = eqx.field(static=True)
    solver: object = eqx.field(static=True, default="ros34pw2")
    rtol: float = eqx.field(static=True, default=1e-3)
    atol: float = eqx.field(static=True, default=1e-5)
    dt: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=4096)
    action_scale: Float[Array, "..."] = eqx.field(default=1.0, converter=jnp.asarray)
    q0: Float[Array, " n_dof"] | None = None
    qd0: Float[Array, " n_dof"] | None = None
    u0: Float[Array, " n_inputs"] | None = None
    noise: Float[Array, "..."] = eqx.field(default=0.0, converter=jnp.asarray)
    adjoint: object = eqx.field(static=True, default=None)

    def __check_init__(self):
        if not isinstance(self.linkage, Linkage):
            raise ValueError(
                f"Environment.linkage = {type(self.linkage).__name__}: give a Linkage."
            )
        if not self.period > 0:
            raise ValueError(
                f"Environment.period = {self.period!r}: give the control period in "
                "seconds (> 0)."
            )
        if self.solver == "auto":
            raise ValueError(
                "Environment.solver = 'auto': name the solver (e.g. 'ros34pw2' or "
                "'tsit5'); 'auto' would choose per call from the state."
            )
        if self.dt is None and not isinstance(
            _make_solver(self.solver), diffrax.AbstractAdaptiveSolver
        ):
            raise ValueError(
                f"Environment.solver = {self.solver!r} takes constant steps: give dt "
                f"(a step that divides the period, {self.period} s, e.g. dt = "
                "period), or an adaptive solver such as 'ros34pw2'."
            )
        if self.dt is not None:
            n = self.period / self.dt
            if not self.dt > 0 or abs(n - round(n)) > 1e-9 * n:
                raise ValueError(
                    f"Environment.dt = {self.dt!r}: give a positive step that divides "
                    f"the period ({self.period} s) a whole number of times, or None "
                    "for adaptive steps."
                )
        if is_concrete(self.noise) and not np.all(np.asarray(self.noise) >= 0):
            raise ValueError(
                f"Environment.noise = {np.asarray(self.noise).tolist()}: give standard "
                "deviations >= 0 of the initial coordinates' perturbation."
            )
        n_dof, n_in = self.linkage.n_dof, self.linkage.n_inputs
        for name, size in (("q0", n_dof), ("qd0", n_dof), ("u0", n_in)):
            v = getattr(self, name)
            if v is not None and jnp.shape(v) != (size,):
                raise ValueError(
                    f"Environment.{name} has shape {jnp.shape(v)}; give ({size},)."
                )
        if jnp.ndim(self.action_scale) > 1 or jnp.size(self.action_scale) not in (
            1,
            n_in,
        ):
            raise ValueError(
                f"Environment.action_scale has shape {jnp.shape(self.action_scale)}; "
                f"give a scalar or one factor per input ({n_in},)."
            )

    # Identity hash and equality (not field-wise: the fields hold arrays), so that
    # ``jax.jit(env.step)`` works as with brax / gymnax environments; as a pytree
    # (eqx.filter_jit, vmap over stacked environments) it is unaffected.
    def __hash__(self):
        return id(self)

    def __eq__(self, other):
        return self is other

    @property
    def action_size(self) -> int:
        """Number of action entries (the linkage's ``n_inputs``)."""
        return self.linkage.n_inputs

    def inputs(self, action: ArrayLike) -> Float[Array, " n_inputs"]:
        """The inputs ``u`` an action maps to (scaled; cable tensions >= 0)."""
        u = self.action_scale * jnp.asarray(action)
        mask = _cable_mask(self.linkage)
        if mask.any():
            u = jnp.where(mask, jnp.maximum(u, 0.0), u)
        return u

    def reset(self, key: PRNGKeyArray) -> EnvState:
        """The initial state: ``q0`` (+ ``noise`` times a standard normal draw)."""
        lk = self.linkage
        q0 = jnp.zeros(lk.n_dof) if self.q0 is None else jnp.asarray(self.q0, float)
        qd0 = jnp.zeros_like(q0) if self.qd0 is None else jnp.asarray(self.qd0, float)
        q0 = q0 + self.noise * jax.random.normal(key, q0.shape, q0.dtype)
        u0 = jnp.zeros(lk.n_inputs, q0.dtype) if self.u0 is None else self.u0
        qi, ui = lk.prescribed
        if len(qi):
            q0 = q0.at[qi].set(jnp.asarray(u0)[ui])
        zero = jnp.zeros((), jnp.int32)
        return EnvState(
            q=q0,
            qd=qd0,
            t=jnp.zeros((), q0.dtype),
            u=jnp.asarray(u0, q0.dtype),
            result=zero,
            steps=zero,
        )

    def input_function(self, state: EnvState, action: ArrayLike):
        """``t -> u`` over the period after ``state`` (zero- and first-order hold)."""
        u1 = self.inputs(action).astype(state.q.dtype)
        _, ui = self.linkage.prescribed
        if not len(ui):
            return None, u1
        ramp = np.zeros(self.linkage.n_inputs, bool)
        ramp[ui] = True
        return eqx.Partial(_held_inputs, state.u, u1, state.t, self.period, ramp), u1

    def step(self, state: EnvState, action: ArrayLike) -> EnvState:
        """Integrate one control period under ``action``; never raises.

        One compiled program per environment structure when called outside a
        trace; inside your ``jit``, ``vmap``, ``grad`` or ``scan`` it is traced
        into your program.

        Args:
            state: the current state.
            action: (n_inputs,) action (see :meth:`inputs`).

        Returns:
            The state one period later; on failure the same state with
            ``result`` set (and ``t`` not advanced).
        """
        # an array: a list or a Python float would be a static (retraced) argument
        return _compiled_step(self, state, jnp.asarray(action, dtype=state.q.dtype))

    def _step(self, state: EnvState, action: ArrayLike) -> EnvState:
        u_fn, u1 = self.input_function(state, action)
        t1 = state.t + self.period
        if self.dt is not None:
            return self._fixed_steps(state, u_fn, u1, t1)
        tr = simulate(
            self.linkage,
            t1,
            state.q,
            state.qd,
            t0=state.t,
            ts=t1[None],
            solver=self.solver,
            rtol=self.rtol,
            atol=self.atol,
            max_steps=self.max_steps,
            u=u1 if u_fn is None else u_fn,
            adjoint=self.adjoint,
            throw=False,
        )
        ok = tr.result == RESULTS.successful
        return _advanced(
            state, ok, tr.q[-1], tr.qd[-1], t1, u1, tr.result._value, tr.num_steps
        )

    def _fixed_steps(self, state, u_fn, u1, t1) -> EnvState:
        """Constant steps without diffrax's loop.

        ``simulate(adaptive=False)``'s steps (same solver, same stages) in a
        ``fori_loop`` of known length, so that autodiff goes through the steps
        directly instead of through the checkpointed while loop of
        ``diffeqsolve``.
        """
        lk = self.linkage
        dtype = state.q.dtype
        n_sub = round(self.period / self.dt)
        u_const = u1 if u_fn is None else jnp.zeros(lk.n_inputs, dtype)
        solver = _make_solver(self.solver)
        solver = _root_finder_tolerances(solver, self.rtol, self.atol)
        t0 = state.t
        _, y0, _ = _initial_state(lk, state.q, state.qd, t0, t1, u_fn, u_const, None)
        data = precompute(lk)
        y0 = consistent_start(lk, data, t0, y0, u_fn, u_const)
        term, args = _vector_field(lk, data, u_const, u_fn, None)
        dt = jnp.asarray(self.dt, dtype)
        solver_state = solver.init(term, t0, t0 + dt, y0, args)

        def body(i, carry):
            y, st, bad = carry
            ta = t0 + i * dt
            tb = jnp.where(i == n_sub - 1, t1, ta + dt)
            y1, _, _, st, res = solver.step(term, ta, tb, y, args, st, False)
            return y1, st, bad | (res != diffrax.RESULTS.successful)

        y, _, bad = jax.lax.fori_loop(
            0, n_sub, body, (y0, solver_state, jnp.asarray(False))
        )
        ok = ~bad & jnp.all(jnp.isfinite(y))
        code = jnp.where(
            bad,
            RESULTS.failed._value,
            jnp.where(ok, 0, RESULTS.nonlinear_divergence._value),
        )
        n = lk.n_dof
        return _advanced(state, ok, y[:n], y[n:], t1, u1, code, n_sub)

    # ------------------------------------------------------------ observations
    def tip_pose(self, state: EnvState, link: int = -1) -> Float[Array, "4 4"]:
        """World pose of link ``link``'s tip (1-based; -1: the last link)."""
        return tip_pose(self.linkage, state.q, link)

    def tip_position(self, state: EnvState, link: int = -1) -> Float[Array, " 3"]:
        """World position of link ``link``'s tip [m]."""
        return self.tip_pose(state, link)[:3, 3]

    def tip_velocity(self, state: EnvState, link: int = -1) -> Float[Array, " 3"]:
        """World linear velocity of link ``link``'s tip [m/s]."""
        point = self.linkage.tip_point(self.linkage.n_links if link == -1 else link)
        return _tip_motion(self.linkage, state.q, state.qd, point)[1]

    def strains(self, state: EnvState) -> Float[Array, "n_points 6"]:
        """Screw strains at every significant point (angular first)."""
        return screw_strains(self.linkage, state.q)

    def cable_lengths(self, state: EnvState) -> Float[Array, " n_cables"]:
        """Length of every cable [m]."""
        return cable_lengths(self.linkage, state.q)

    def contacts(self, state: EnvState):
        """The :class:`~sorojax.ContactState` at the state (friction included)."""
        return contact_state(self.linkage, state.q, state.qd, state.t)

    def contact_forces(self, state: EnvState) -> Float[Array, "n_links 3"]:
        """Resultant contact force on each link [N, world]: a touch sensor.

        Obstacles and the other rods' pushes on the link (rod-rod pairs count for
        both links, with opposite signs); zeros for links that touch nothing.
        """
        cs = self.contacts(state)
        # the rows' reaction on link B of a pair: minus the force on link A
        pair_b = pair_link_b(self.linkage)
        out = jnp.zeros((self.linkage.n_links, 3), state.q.dtype)
        out = out.at[cs.link - 1].add(cs.force)
        if pair_b.size:
            n_obs = cs.force.shape[0] - pair_b.size
            out = out.at[pair_b - 1].add(-cs.force[n_obs:])
        return out

    def observation(self, state: EnvState) -> Float[Array, " n_obs"]:
        """A flat observation: ``[q, qd, tip position, tip velocity]``.

        With contact, the resultant contact force on every link follows
        (:meth:`contact_forces`, flattened).
        """
        point = self.linkage.tip_point(self.linkage.n_links)
        x, v = _tip_motion(self.linkage, state.q, state.qd, point)
        parts = [state.q, state.qd, x, v]
        if self.linkage.contact is not None:
            parts.append(self.contact_forces(state).ravel())
        return jnp.concatenate(parts)


@jit
def _compiled_step(env: Environment, state: EnvState, action) -> EnvState:
    return env._step(state, action)


@jit
def _tip_motion(linkage: Linkage, q, qd, point: int):
    """World position and linear velocity of a significant point.

    One kinematics pass (poses and Jacobians) gives both.
    """
    g, J = poses_and_jacobians(precompute(linkage), q)
    return g[point, :3, 3], g[point, :3, :3] @ (J[point] @ qd)[3:]  # body -> world


def _advanced(state, ok, q, qd, t1, u1, code, steps) -> EnvState:
    """The state after a period: the integration's end where ``ok``, else ``state``.

    ``where``, not the raw values: a failed member's inf must not reach the
    others' gradients (nor its own: the untaken branch is finite).
    """
    return EnvState(
        q=jnp.where(ok, jnp.nan_to_num(q), state.q),
        qd=jnp.where(ok, jnp.nan_to_num(qd), state.qd),
        t=jnp.where(ok, t1, state.t),
        u=u1,
        result=jnp.asarray(code, jnp.int32),
        steps=jnp.asarray(steps, jnp.int32),
    )


def _held_inputs(u0, u1, t0, period, ramp, t):
    """Zero-order hold of ``u1``; linear ramp ``u0 -> u1`` where ``ramp``.

    Not clipped to the period: the integration only asks for t in [t0, t0 +
    period], and a clip's derivative at its ends (0.5 at a tie) would spoil the
    prescribed velocity at the stages on the period's ends (measured: 1.7e-3 rad).
    """
    s = (t - t0) / period
    return jnp.where(ramp, u0 + s * (u1 - u0), u1)


def rollout(
    env: Environment, state: EnvState, actions_or_policy, n_steps: int | None = None
):
    """Run ``env`` from ``state`` with ``jax.lax.scan``.

    Args:
        env: the environment.
        state: the initial state.
        actions_or_policy: an ``(n_steps, n_inputs)`` array of actions, or a
            policy ``(state) -> action`` (e.g. an equinox module closing over
            observations of ``env``).
        n_steps: number of periods (required with a policy).

    Returns:
        ``(final state, states)``: ``states`` stacks the state after every period
        (leading axis ``n_steps``).
    """
    if callable(actions_or_policy):
        if n_steps is None:
            raise ValueError("rollout with a policy needs n_steps.")
        policy, xs = actions_or_policy, None
    else:
        policy, xs = None, jnp.asarray(actions_or_policy)

    def body(s, a):
        s1 = env.step(s, a if policy is None else policy(s))
        return s1, s1

    return jax.lax.scan(body, state, xs, length=n_steps)
