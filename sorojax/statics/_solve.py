"""Static equilibrium: K q = F(q) (+ actuation, later), solved with optimistix.

The residual ``r(q) = K q - lambda F(q, 0, t)`` is Jacobi-scaled by diag(K), so the
solver's absolute tolerance reads as a coordinate tolerance whatever the stiffness
units. The Jacobian comes from autodiff. For very large loads the load factor lambda
goes 1/n, 2/n, ..., 1 (``load_steps = n``), each solve warm-started from the last.
Gradients flow through the final solve by the implicit function theorem
(``optx.ImplicitAdjoint``); the earlier load steps only provide its starting point.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jax import lax
from jaxtyping import Array, ArrayLike

from .._results import RESULTS, StaticsSolution
from ..dynamics._external import external_force
from ..dynamics._generalized import kinematics_from_data
from ..kinematics._api import _as_q
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute


def _row_scale(K) -> Array:
    d = jnp.abs(jnp.diag(K))
    fallback = jnp.where(jnp.any(d > 0), jnp.max(d), 1.0)
    return 1.0 / jnp.where(d > 0, d, fallback)


def equilibrium_residual(linkage: Linkage, data: LinkageData, q, t=0.0, lam=1.0) -> Array:
    """Unscaled residual ``K q - lam F(q, 0, t)`` (generalised forces)."""
    qd = jnp.zeros_like(q)
    kin = kinematics_from_data(data, q, qd, need_jdot=False)
    return data.K @ q - lam * external_force(linkage, data, t, q, qd, kin)


def _to_results(optx_result) -> RESULTS:
    return RESULTS.where(
        optx_result == optx.RESULTS.successful,
        RESULTS.successful,
        RESULTS.where(
            optx_result == optx.RESULTS.max_steps_reached,
            RESULTS.max_steps_reached,
            RESULTS.nonlinear_divergence,
        ),
    )


@eqx.filter_jit
def solve_statics(
    linkage: Linkage,
    q0: ArrayLike | None = None,
    *,
    t: ArrayLike = 0.0,
    solver: optx.AbstractRootFinder | optx.AbstractLeastSquaresSolver | None = None,
    load_steps: int = 1,
    max_steps: int = 64,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    throw: bool = True,
) -> StaticsSolution:
    """Solve the static equilibrium of ``linkage`` (the manual's ``statics``).

    Args:
        linkage: the model.
        q0: initial guess ``(n_dof,)``; default zeros (the reference configuration).
        t: time at which time-dependent loads are evaluated [s].
        solver: an optimistix root finder or least-squares solver; default
            ``optx.Newton(rtol, atol)`` on the Jacobi-scaled residual.
        load_steps: number of load increments (use 4-10 for very large loads).
        max_steps: maximum iterations per load step.
        rtol, atol: tolerances of the default solver.
        throw: raise if the solve fails; use ``throw=False`` under ``vmap`` and read
            ``result``.

    Returns:
        A :class:`~sorojax.StaticsSolution` with q, the residual max-norm, the total
        iteration count and a result code.

    Raises:
        ValueError: bad ``q0`` shape or ``load_steps`` < 1.
    """
    if not isinstance(load_steps, int) or load_steps < 1:
        raise ValueError(f"load_steps = {load_steps!r}: give an integer >= 1.")
    n = linkage.n_dof
    q0 = jnp.zeros(n) if q0 is None else _as_q(linkage, q0, "q0")
    if solver is None:
        solver = optx.Newton(rtol=rtol, atol=atol)
    data = precompute(linkage)
    scale = _row_scale(data.K)

    def fn(q, args):
        data_, lam = args
        return scale * equilibrium_residual(linkage, data_, q, t, lam)

    def solve(q_start, lam, data_):
        return optx.root_find(
            fn, solver, q_start, (data_, lam), max_steps=max_steps, throw=False
        )

    num_pre = jnp.array(0)
    result_pre = RESULTS.successful
    if load_steps > 1:
        lams = jnp.arange(1, load_steps) / load_steps
        data_ng = jax.lax.stop_gradient(data)

        def body(q, lam):
            sol = solve(q, lam, data_ng)
            return sol.value, (sol.stats["num_steps"], sol.result)

        q0, (steps, results) = lax.scan(body, jax.lax.stop_gradient(q0), lams)
        num_pre = jnp.sum(steps)
        ok_pre = jnp.all(results._value == optx.RESULTS.successful._value)
        result_pre = RESULTS.where(ok_pre, RESULTS.successful, RESULTS.nonlinear_divergence)
        q0 = jax.lax.stop_gradient(q0)
    sol = solve(q0, jnp.asarray(1.0), data)
    q = sol.value
    r = equilibrium_residual(linkage, data, q, t)
    finite = jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(r))
    result = RESULTS.where(finite, _to_results(sol.result), RESULTS.nonlinear_divergence)
    # A failed intermediate load step is reported only if the final solve failed too:
    # the final solve from any start that converges is a true equilibrium.
    result = RESULTS.where(result == RESULTS.successful, result, result)
    del result_pre
    res_norm = jnp.max(jnp.abs(r), initial=0.0)
    if throw:
        q = result.error_if(q, result != RESULTS.successful)
    return StaticsSolution(
        q=q,
        residual_norm=res_norm,
        num_steps=num_pre + sol.stats["num_steps"],
        result=result,
    )
