"""A Rosenbrock-W solver for diffrax, with a cheap W for mechanical systems.

Soft robots are stiff through their *linear* elastic and damping forces: the fastest
modes of ``M qdd = -K q - D qd + f(q, qd, t)`` have eigenvalues of
``[[0, I], [-M^-1 K, -M^-1 D]]`` far beyond the motion one wants to resolve, and an
explicit solver's step is bounded by them, not by accuracy. A Rosenbrock-W method
treats a chosen matrix W linearly implicitly: each stage solves one linear system with
``I - h gamma W`` and evaluates the vector field once -- no Newton iteration, no
autodiff Jacobian -- and its order conditions hold for *any* W (Steihaug & Wolfbrandt
1979; Hairer & Wanner, Solving ODEs II, section IV.7), so W only decides stability.

* :class:`MechanicalTerm` (the simulator's term) gives W from ``(M(q), K, D)`` at the
  start of each step. Then ``(I/(h gamma) - W) x = r`` reduces to one symmetric
  positive definite system ``(M + c D + c^2 K) x_v = c (M r_v - c K r_q)``,
  ``x_q = c (r_q + x_v)`` with ``c = h gamma`` (n x n, Cholesky once per step).
* Any other diffrax term gets the exact Jacobian by forward-mode autodiff and an LU
  solve (a classical Rosenbrock method).

The method is ROS34PW2 (Rang & Angermann, BIT 45, 2005): 4 stages, order 3, embedded
order 2, stiffly accurate, L-stable, a W-method. It is run in the transformed variables
``u_i = sum_j gamma_ij k_j`` (Hairer & Wanner, eq. IV.7.4'), so no matrix-vector
product with W is needed. Non-autonomous vector fields are handled as a W-method
whose W has no time column (the order is kept).

Dense output is a cubic Hermite polynomial on ``(y0, h f(y0), y1, k_s)``.

* With a :class:`MechanicalTerm` the step is self-contained: its s stages are its
  only evaluations, run as one loop (one copy of the dynamics in the compiled
  program), and no first-same-as-last state is carried. The end slope is the last
  stage's ``k_s``: the method is stiffly accurate (``y1 = Y_s + sum_j gamma_sj k_j``
  with ``Y_s`` the last stage point, at ``t1``), so the stage equation gives
  ``k_s = h f(Y_s) + h W (y1 - Y_s) = h f(y1) + h (W - J)(y1 - Y_s) + ...``: exact
  for the stiff linear part (W), with an error O(h^3) from the rest of the Jacobian
  (``y1 - Y_s = O(h^2)``), the order of the step's error estimate. Step ends are
  exact; between them the interpolant is second order (third with the exact slope).
* Any other term evaluates the vector field at the step's end for the next step's
  first stage (first same as last) and uses it as the end slope.
"""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import cho_solve, lu_factor, lu_solve

# ROS34PW2 (Rang & Angermann, BIT 45, 2005): alpha_ij, gamma_ij (j < i), gamma_ii,
# b, and the embedded b_hat, in the standard Rosenbrock form
#   (I - h gamma W) k_i = h f(y + sum_j alpha_ij k_j) + h W sum_j gamma_ij k_j.
_GAMMA = 4.3586652150845900e-01
_ALPHA = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [8.7173304301691801e-01, 0.0, 0.0, 0.0],
        [8.4457060015369423e-01, -1.1299064236484185e-01, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]
)
_GAMMA_MAT = np.array(
    [
        [_GAMMA, 0.0, 0.0, 0.0],
        [-8.7173304301691801e-01, _GAMMA, 0.0, 0.0],
        [-9.0338057013044082e-01, 5.4180672388095326e-02, _GAMMA, 0.0],
        [2.4212380706095346e-01, -1.2232505839045147, 5.4526025533510214e-01, _GAMMA],
    ]
)
_B = np.array(
    [2.4212380706095346e-01, -1.2232505839045147e00, 1.5452602553351020e00, _GAMMA]
)
_B_HAT = np.array(
    [3.7810903145819369e-01, -9.6042292212423178e-02, 5.0e-01, 2.1793326075422950e-01]
)


class RosenbrockTableau(eqx.Module):
    """A Rosenbrock-W method in transformed variables (Hairer & Wanner IV.7.4').

    With ``Gamma = (gamma_ij)`` lower triangular (diagonal ``gamma``) and
    ``u_i = sum_j gamma_ij k_j``: ``(I/(h gamma) - W) u_i = f(t + c_i h, y + sum_j
    a_ij u_j) + sum_j C_ij u_j / h`` and ``y_1 = y + sum_i m_i u_i``, with
    ``a = alpha Gamma^-1``, ``C = diag(1/gamma) - Gamma^-1``, ``m = b Gamma^-1``;
    the error estimate is ``sum_i e_i u_i`` with ``e = (b - b_hat) Gamma^-1``.

    Attributes:
        gamma: diagonal coefficient.
        a: (s, s) stage coefficients (strictly lower).
        C: (s, s) coupling coefficients (strictly lower).
        c: (s,) stage times (row sums of alpha).
        m: (s,) solution weights.
        e: (s,) error weights.
        d: (s,) weights of the last stage's ``k_s = sum_j d_j u_j`` (the last row
            of ``Gamma^-1``): the end slope ``~ h f(y1)`` of a stiffly accurate method.
        stiffly_accurate: ``b`` is the last row of ``alpha + Gamma`` and ``c_s = 1``.
        order: classical order of the solution.
    """

    gamma: float = eqx.field(static=True)
    a: tuple[tuple[float, ...], ...] = eqx.field(static=True)
    C: tuple[tuple[float, ...], ...] = eqx.field(static=True)
    c: tuple[float, ...] = eqx.field(static=True)
    m: tuple[float, ...] = eqx.field(static=True)
    e: tuple[float, ...] = eqx.field(static=True)
    d: tuple[float, ...] = eqx.field(static=True)
    stiffly_accurate: bool = eqx.field(static=True)
    order: int = eqx.field(static=True)

    @classmethod
    def from_standard(cls, alpha, gamma_mat, b, b_hat, order):
        """Build from the standard-form coefficients ``alpha, Gamma, b, b_hat``."""
        gi = np.linalg.inv(gamma_mat)

        def vec(x):
            return tuple(float(v) for v in x)

        return cls(
            gamma=float(gamma_mat[0, 0]),
            a=tuple(vec(r) for r in alpha @ gi),
            C=tuple(vec(r) for r in np.diag(np.diag(gi)) - gi),
            c=vec(alpha.sum(axis=1)),
            m=vec(b @ gi),
            e=vec((b - b_hat) @ gi),
            d=vec(gi[-1]),
            stiffly_accurate=bool(
                np.allclose(alpha[-1] + gamma_mat[-1], b, rtol=0, atol=1e-14)
                and np.isclose(alpha[-1].sum(), 1.0, rtol=0, atol=1e-14)
            ),
            order=order,
        )


ROS34PW2 = RosenbrockTableau.from_standard(_ALPHA, _GAMMA_MAT, _B, _B_HAT, order=3)


class MechanicalTerm(diffrax.AbstractTerm):
    """ODE term of ``y = (q, qd)`` that also returns the matrices of its stiff part.

    ``field(t, y, args) -> (ydot, (M, K, D))`` with ``ydot = (qd, qdd)`` and
    ``W = [[0, I], [-M^-1 K, -M^-1 D]]`` the linear part used by :class:`RosenbrockW`
    (any other solver sees an ordinary ODE term).

    Attributes:
        field: the vector field and its linear part.
    """

    field: Callable

    def vf(self, t, y, args):
        """The vector field ``ydot``."""
        return self.field(t, y, args)[0]

    def vf_and_matrices(self, t, y, args):
        """``(ydot, (M, K, D))``."""
        return self.field(t, y, args)

    def contr(self, t0, t1, **kwargs):
        """The control of an ODE: the time increment."""
        return t1 - t0

    def prod(self, vf, control):
        """Vector field times control."""
        return vf * control


def _mechanical_term(terms) -> tuple[MechanicalTerm, object] | None:
    """``(term, direction)`` of a :class:`MechanicalTerm`, if ``terms`` is one.

    ``diffeqsolve`` hands solvers its terms inside a private wrapper (``WrapTerm``:
    attributes ``term`` and ``direction``, times multiplied by the direction).
    """
    if isinstance(terms, MechanicalTerm):
        return terms, 1
    inner = getattr(terms, "term", None)
    if isinstance(inner, MechanicalTerm):
        return inner, terms.direction
    return None


def _mechanical_factor(matrices, c):
    """``(L, M, K)``: ``(I/c - W)`` factored, ``W = [[0, I], [-M^-1 K, -M^-1 D]]``.

    ``L`` is the lower Cholesky factor of ``M + c D + c^2 K`` (n x n).
    """
    M, K, D = matrices
    K = jnp.broadcast_to(K, M.shape)
    D = jnp.broadcast_to(D, M.shape)
    return jnp.linalg.cholesky(M + c * D + (c * c) * K), M, K


def _mechanical_solve(factor, c, r):
    """``x = (I/c - W)^-1 r`` from :func:`_mechanical_factor`'s ``(L, M, K)``."""
    L, M, K = factor
    n = M.shape[0]
    rq, rv = r[:n], r[n:]
    xv = cho_solve((L, True), c * (M @ rv - c * (K @ rq)))
    return jnp.concatenate([c * (rq + xv), xv])


def _dense_solver(Jac, c):
    """``x = (I/c - J)^-1 r`` by LU, for a general Jacobian ``J``."""
    n = Jac.shape[0]
    fac = lu_factor(jnp.eye(n, dtype=Jac.dtype) / c - Jac)
    return lambda r: lu_solve(fac, r)


def _evaluate(terms, t, y, args):
    """``(f, lin)``: the vector field and W's data at ``(t, y)``.

    ``lin`` is ``(M, K, D)`` for a :class:`MechanicalTerm`, else the exact Jacobian
    (forward-mode autodiff, one pass for both).
    """
    mech = _mechanical_term(terms)
    if mech is not None:
        term, direction = mech
        return term.vf_and_matrices(t * direction, y, args)

    def vf_twice(y_):
        v = terms.vf(t, y_, args)
        return v, v

    Jac, f = jax.jacfwd(vf_twice, has_aux=True)(y)
    return f, Jac


def _check_state(solver: str, y0) -> None:
    """Refuse a state that is not a one-dimensional array."""
    if not eqx.is_array(y0) or y0.ndim != 1:
        got = (
            f"shape {y0.shape}"
            if eqx.is_array(y0)
            else f"a pytree {jax.tree_util.tree_structure(y0)}"
        )
        raise ValueError(
            f"{solver} needs a one-dimensional array state; got {got} "
            "(flatten the state, e.g. with jax.flatten_util.ravel_pytree)."
        )


class RosenbrockW(diffrax.AbstractAdaptiveSolver):
    """Rosenbrock-W solver (ROS34PW2 by default), adaptive, for stiff mechanics.

    With a :class:`MechanicalTerm` W is the linear elastic and damping part at the
    step's start (see the module docstring); with any other term W is the exact
    Jacobian (forward-mode autodiff, dense LU). One-dimensional array states only.

    Attributes:
        tableau: the method's coefficients.
    """

    tableau: RosenbrockTableau = ROS34PW2
    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation

    def order(self, terms):
        """Classical order (3 for ROS34PW2)."""
        return self.tableau.order

    def error_order(self, terms):
        """Order of the local error estimate's leading term minus one."""
        return self.tableau.order

    def init(self, terms, t0, t1, y0, args):
        """The solver's state (None for a :class:`MechanicalTerm`).

        A mechanical step evaluates its own start; any other term carries the
        first-same-as-last vector field and Jacobian.
        """
        _check_state(type(self).__name__, y0)
        if _mechanical_term(terms) is not None:
            return None  # the mechanical step evaluates its own start
        return _evaluate(terms, t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        """One step of the method (see the module docstring)."""
        tab = self.tableau
        if _mechanical_term(terms) is not None:
            return self._mechanical_step(terms, t0, t1, y0, args)
        # First same as last, unless the vector field jumped at t0 (diffrax's jump_ts).
        if made_jump is False:  # a caller's own loop: no cond,
            f0, lin0 = solver_state  # so no second copy of the vector field
        else:
            f0, lin0 = jax.lax.cond(
                made_jump,
                lambda: _evaluate(terms, t0, y0, args),
                lambda: solver_state,
            )
        h = t1 - t0
        c = h * tab.gamma
        solve = _dense_solver(lin0, c)
        s = len(tab.m)
        us = []
        for i in range(s):
            if i == 0:
                fi = f0
            else:
                yi = y0 + sum(tab.a[i][j] * us[j] for j in range(i) if tab.a[i][j])
                fi = terms.vf(t0 + tab.c[i] * h, yi, args)
            rhs = fi + sum(tab.C[i][j] / h * us[j] for j in range(i) if tab.C[i][j])
            us.append(solve(rhs))
        y1 = y0 + sum(tab.m[i] * us[i] for i in range(s))
        y_error = sum(tab.e[i] * us[i] for i in range(s) if tab.e[i])
        f1, lin1 = _evaluate(terms, t1, y1, args)
        dense_info = dict(y0=y0, y1=y1, k0=f0 * h, k1=f1 * h)
        return y1, y_error, dense_info, (f1, lin1), diffrax.RESULTS.successful

    def _mechanical_step(self, terms, t0, t1, y0, args):
        """:meth:`step` for a :class:`MechanicalTerm`: one vector field in the program.

        The s stages run as one ``lax.fori_loop`` whose body evaluates the vector
        field once, at the point picked by the iteration index from the tableau's
        rows, so the compiled step holds one copy of the dynamics, and the step
        carries no state: no evaluation in :meth:`init` and none re-done after a jump
        (``benchmarks/latency.py``: the gradient through 1 s of the free-fall rod
        held 7 copies of the dynamics with a first-same-as-last state evaluated in
        ``init``). The first row, at ``y0``, also gives W and its Cholesky factor,
        kept for the step's other rows. The end slope of the dense output is the
        last stage's ``k_s`` (module docstring). The stage values ``u`` are the rows
        of an ``(s, n)`` carry.
        """
        tab = self.tableau
        if not tab.stiffly_accurate:
            raise ValueError(
                "RosenbrockW with a MechanicalTerm takes its dense output's end slope "
                "from the last stage, which needs a stiffly accurate tableau (b = the "
                "last row of alpha + Gamma, c_s = 1); use ROS34PW2 or such a method."
            )
        s = len(tab.m)
        h = t1 - t0
        c = h * tab.gamma
        dt = y0.dtype
        n = y0.shape[0] // 2
        A = jnp.asarray(np.array(tab.a), dt)
        Cm = jnp.asarray(np.array(tab.C), dt)
        cs = jnp.asarray(np.array(tab.c), dt)

        # Checkpointed evaluation: reverse mode keeps only its inputs per row and
        # evaluates again, instead of stacking every intermediate of the dynamics
        # (gradient through 1 s of the free-fall rod: compiles ~17 % faster and runs
        # ~7 % faster than without it, 2-core CPU). Only the evaluation: with the
        # whole body checkpointed, the factorisation's cond made the reverse pass
        # 1.4x slower.
        evaluate = jax.checkpoint(lambda t, y: _evaluate(terms, t, y, args))

        def body(i, carry):
            us, factor, f0 = carry
            f, lin = evaluate(t0 + cs[i] * h, y0 + A[i] @ us)
            # W is that of the step's start: factored in the first row only
            factor = jax.lax.cond(
                i == 0, lambda: _mechanical_factor(lin, c), lambda: factor
            )
            u = _mechanical_solve(factor, c, f + (Cm[i] / h) @ us)
            return us.at[i].set(u), factor, jnp.where(i == 0, f, f0)

        mat = jnp.zeros((n, n), dt)
        init = (jnp.zeros((s,) + y0.shape, dt), (mat, mat, mat), jnp.zeros_like(y0))
        us, _, f0 = jax.lax.fori_loop(0, s, body, init)
        y1 = y0 + jnp.asarray(np.array(tab.m), dt) @ us
        y_error = jnp.asarray(np.array(tab.e), dt) @ us
        k1 = jnp.asarray(np.array(tab.d), dt) @ us
        dense_info = dict(y0=y0, y1=y1, k0=f0 * h, k1=k1)
        return y1, y_error, dense_info, None, diffrax.RESULTS.successful

    def func(self, terms, t0, y0, args):
        """The vector field at ``(t0, y0)``."""
        return terms.vf(t0, y0, args)


class RosenbrockEuler(diffrax.AbstractSolver):
    """One-stage linearly implicit (Rosenbrock) step at a constant step size.

    ``(I - gamma h W) k = h f(t0 + gamma h, y0)``, ``y1 = y0 + k``: one evaluation
    of the vector field and one linear solve per step, whatever the state (a batch
    runs in lockstep). The time ``t0 + gamma h`` keeps the order for time-dependent
    inputs (the one-stage method's W has no time column: ``f(t0 + gamma h) = f +
    gamma h f_t + ...`` supplies the ``gamma h^2 f_t`` term); with ``gamma = 1``
    inputs and prescribed motions are taken at the step's end, as backward Euler
    takes them. With a :class:`MechanicalTerm` W is the linear stiff part of the
    step's start, ``[[0, I], [-M^-1 K, -M^-1 D]]`` (K and D with the contacts'
    tangent when the linkage puts it in W), and the solve is the
    ``(M + c D + c^2 K)`` Cholesky system of :class:`RosenbrockW` (``c = gamma h``);
    any other term gets the exact Jacobian (forward-mode autodiff, dense LU).

    * ``gamma = 1`` (default, ``"rosenbrock_euler"``): the linearly implicit Euler
      method. In ``y = (q, v)`` it reads ``(M + h D + h^2 K) dv = h (F - h K v)``,
      ``v1 = v + dv``, ``q1 = q + h v1``: MuJoCo's ``implicitfast`` with the
      elastic stiffness (and the contacts') implicit too. Order 1, L-stable: stiff
      material, stiff contact and sticking friction do not bound the step, and
      oscillations faster than ``1/h`` are damped (numerical dissipation).
    * ``gamma = 1/2`` (``"rosenbrock_trapezoid"``): the linearised trapezoidal
      rule, order 2 where W is the exact Jacobian (the linear elastic and damping
      forces), A-stable and without numerical damping of the linear part: an
      undamped rod keeps its energy, but fast modes that a step cannot resolve
      ring instead of decaying.

    Not adaptive (no error estimate): ``simulate`` runs it at constant steps of its
    ``dt0``. Dense output between steps is linear. With W only the linear part of a
    nonlinear model (large rotations, contact's curvature) both variants are first
    order in practice.

    Attributes:
        gamma: the implicitness ``(0, 1]``.
    """

    gamma: float = eqx.field(static=True, default=1.0)
    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = diffrax.LocalLinearInterpolation

    def __check_init__(self):
        if not 0.0 < self.gamma <= 1.0:
            raise ValueError(
                f"RosenbrockEuler(gamma={self.gamma!r}): give 0 < gamma <= 1 (1: "
                "linearly implicit Euler, 1/2: linearised trapezoidal rule)."
            )

    def order(self, terms):
        """2 for ``gamma = 1/2`` (with W the exact Jacobian), else 1."""
        return 2 if self.gamma == 0.5 else 1

    def init(self, terms, t0, t1, y0, args):
        """No state: each step evaluates its own start."""
        _check_state(type(self).__name__, y0)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        """One step (see the class docstring)."""
        h = t1 - t0
        c = h * self.gamma
        f, lin = _evaluate(terms, t0 + c, y0, args)
        if _mechanical_term(terms) is not None:
            x = _mechanical_solve(_mechanical_factor(lin, c), c, f)
        else:
            x = _dense_solver(lin, c)(f)
        y1 = y0 + x / self.gamma  # k = h (I - c W)^-1 f = x / gamma
        dense_info = dict(y0=y0, y1=y1)
        return y1, None, dense_info, None, diffrax.RESULTS.successful

    def func(self, terms, t0, y0, args):
        """The vector field at ``(t0, y0)``."""
        return terms.vf(t0, y0, args)
