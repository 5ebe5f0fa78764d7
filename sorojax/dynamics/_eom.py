"""Equations of motion M(q) qdd = F(q, qd, t) + tau - C(q, qd) qd - D qd - K q.

One pass forms the body Jacobians J, the twists J qd and their velocity-product rates
Jdot qd (a forward-mode derivative of J qd along qd, no Jdot matrix), then M = sum w
J^T M J and every point force (inertial, gravity, point wrenches, custom hook) is
gathered as one body wrench per point and mapped by J^T. K and D are constant
(precomputed once per solve, outside the integrator's loop).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.scipy.linalg import cho_factor, cho_solve
from jaxtyping import Array, ArrayLike, Float

from ..kinematics._api import Kinematics, _as_q
from ..kinematics._recursion import jacobians_dot, strains
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._external import custom_wrenches, external_wrenches
from ._mass import _gyroscopic, _mass_from_J, _weighted_inertia, kinematics_with_rates

GeneralizedForce = Callable[[Array, Array, Array], ArrayLike]
"""``tau(t, q, qd) -> (n_dof,)`` generalised actuation force added to the right side."""


def mass_and_force(
    linkage: Linkage,
    data: LinkageData,
    t,
    q,
    qd,
    generalized_force: GeneralizedForce | None = None,
) -> tuple[Array, Array]:
    """``(M, f)`` with ``M qdd = f``: mass matrix and all other generalised forces."""
    g, J, eta, etadot_v = kinematics_with_rates(data, q, qd)
    W = external_wrenches(linkage, data, t, g) - _gyroscopic(
        _weighted_inertia(data), eta, etadot_v
    )
    if linkage.custom_wrench is not None:
        kin = Kinematics(
            g=g, J=J, xi=strains(data, q), eta=eta, Jdot=jacobians_dot(data, q, qd)
        )
        W = W + custom_wrenches(linkage, data, t, q, qd, kin)
    f = jnp.einsum("pai,pa->i", J, W) - data.K @ q - data.D @ qd
    if generalized_force is not None:
        tau = jnp.asarray(generalized_force(t, q, qd), dtype=f.dtype)
        if tau.shape != f.shape:
            raise ValueError(
                f"generalized_force returned shape {tau.shape}; expected "
                f"({f.shape[0]},) (one force per coordinate)."
            )
        f = f + tau
    return _mass_from_J(data, J), f


@jax.custom_jvp
def spd_solve(M: Array, f: Array) -> Array:
    """``M^-1 f`` for symmetric positive definite ``M`` (Cholesky).

    Its JVP ``dx = M^-1 (df - dM x)`` reuses the factorisation: the implicit solvers'
    forward-mode Jacobians then cost one multi-column triangular solve, where the
    default Cholesky derivative under ``vmap`` costs a batched factorisation per
    tangent direction (~1000x slower on CPU at 12 DoF).
    """
    return cho_solve(cho_factor(M), f)


@spd_solve.defjvp
def _spd_solve_jvp(primals, tangents):
    M, f = primals
    dM, df = tangents
    c = cho_factor(M)
    x = cho_solve(c, f)
    return x, cho_solve(c, df - dM @ x)


def accelerations(
    linkage: Linkage,
    data: LinkageData,
    t,
    q,
    qd,
    generalized_force: GeneralizedForce | None = None,
) -> Array:
    """``qdd`` from one Cholesky solve of ``M qdd = f``."""
    M, f = mass_and_force(linkage, data, t, q, qd, generalized_force)
    return spd_solve(M, f)


@eqx.filter_jit
def forward_dynamics(
    linkage: Linkage,
    q: ArrayLike,
    qd: ArrayLike,
    t: ArrayLike = 0.0,
    generalized_force: GeneralizedForce | None = None,
) -> Float[Array, " n_dof"]:
    """Generalised accelerations ``qdd`` at ``(q, qd, t)``.

    Args:
        linkage: the model.
        q: coordinates ``(n_dof,)``.
        qd: velocities ``(n_dof,)``.
        t: time [s] (for time-varying loads).
        generalized_force: optional ``tau(t, q, qd)`` added to the right-hand side.
    """
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    t = jnp.asarray(t, dtype=q.dtype)
    return accelerations(linkage, precompute(linkage), t, q, qd, generalized_force)


@eqx.filter_jit
def equations_of_motion(
    linkage: Linkage,
    q: ArrayLike,
    qd: ArrayLike,
    t: ArrayLike = 0.0,
    generalized_force: GeneralizedForce | None = None,
) -> tuple[Float[Array, "n_dof n_dof"], Float[Array, " n_dof"]]:
    """``(M, f)``: mass matrix and right side of ``M qdd = f`` at ``(q, qd, t)``."""
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    t = jnp.asarray(t, dtype=q.dtype)
    return mass_and_force(linkage, precompute(linkage), t, q, qd, generalized_force)
