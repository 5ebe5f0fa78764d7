"""Generalised mass and Coriolis terms (DESIGN.md section 4).

At every significant point p with weight w_p (quadrature weight [m] at rod points, 1 at
rigid centres of mass, 0 elsewhere), inertia M_p (density or rigid spatial inertia),
body Jacobian J_p and body twist eta_p = J_p qd:

    M(q)         = sum_p w_p J_p^T M_p J_p
    C(q, qd) qd  = sum_p w_p J_p^T (M_p Jdot_p qd - ad(eta_p)^T M_p eta_p)
    C(q, qd)     = sum_p w_p J_p^T (M_p Jdot_p + (M_p ad(eta_p) - ad(eta_p)^T M_p) J_p)

The matrix form uses ad(eta) eta = 0 to add M ad(eta) J (which vanishes on qd): the
bracket is then skew-symmetric, so Mdot - 2C is skew-symmetric, not merely
qd^T (Mdot - 2C) qd = 0.

Two ways to evaluate the velocity-product force C qd:

* the dynamics (:func:`sorojax.dynamics._eom.mass_and_force`): one kinematic pass
  gives J, the twists and their rates Jdot qd
  (:func:`sorojax.kinematics._recursion.kinematics_and_rates`); M comes from the same J.
* :func:`coriolis_force`: no Jacobian at all. The body twists come from a forward-mode
  derivative of the poses, their velocity-product rates from a second one, and the
  generalised force from the backward wrench recursion. Cost O(n_points n_dof).
"""

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import _as_q
from ..kinematics._recursion import jacobians_dot, poses_and_jacobians
from ..lie import ad
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, lock_padding, precompute
from ._wrench_recursion import force_from_wrenches, poses_with_records


def _weighted_inertia(data: LinkageData) -> Float[Array, "n_points 6 6"]:
    return data.point_weight[:, None, None] * data.point_M


def _mass_from_J(data: LinkageData, J, rows=None) -> Array:
    """``sum w J^T M J`` over the points that carry mass.

    Contact samples and load points add zeros. ``rows``: each point's row in ``J``
    (default: J has a row per point).
    """
    idx = np.asarray(data.mass_points, dtype=int)
    Mw = data.point_weight[idx, None, None] * data.point_M[idx]
    J = J[idx if rows is None else rows[idx]]
    MJ = jnp.einsum("pab,pbj->paj", Mw, J)
    M = jnp.einsum("pai,paj->ij", J, MJ)
    return lock_padding(0.5 * (M + M.T), data.locked)


def _gyroscopic(Mw, eta, etadot_v):
    """Per-point ``w (M etadot - ad(eta)^T M eta)`` (body frames)."""
    Meta = jnp.einsum("pab,pb->pa", Mw, eta)
    adT = jnp.einsum("pba,pb->pa", jax.vmap(ad)(eta), Meta)
    return jnp.einsum("pab,pb->pa", Mw, etadot_v) - adT


def _twists_from_poses(data: LinkageData, q, qd):
    """Body twists ``(g^-1 gdot)^vee`` from a forward-mode derivative of the poses."""

    def poses(q_):
        return poses_with_records(data, q_)[0]

    g, gdot = jax.jvp(poses, (q,), (qd,))
    R, pdot, Rdot = g[:, :3, :3], gdot[:, :3, 3], gdot[:, :3, :3]
    Wb = jnp.einsum("pji,pjk->pik", R, Rdot)  # R^T Rdot = hat(omega)
    omega = jnp.stack([Wb[:, 2, 1], Wb[:, 0, 2], Wb[:, 1, 0]], axis=1)
    v = jnp.einsum("pji,pj->pi", R, pdot)
    return jnp.concatenate([omega, v], axis=1)


def coriolis_force_from_data(data: LinkageData, q, qd) -> Array:
    """``C(q, qd) qd`` by forward-mode twists and the backward wrench recursion."""
    eta, etadot_v = jax.jvp(lambda q_: _twists_from_poses(data, q_, qd), (q,), (qd,))
    W = _gyroscopic(_weighted_inertia(data), eta, etadot_v)
    _, records = poses_with_records(data, q)
    return force_from_wrenches(data, records, W)


def coriolis_matrix_from_data(data: LinkageData, q, qd) -> Array:
    """The matrix ``C(q, qd)`` of the module docstring (Mdot - 2C skew)."""
    _, J = poses_and_jacobians(data, q)
    Jdot = jacobians_dot(data, q, qd)
    eta = jnp.einsum("pai,i->pa", J, qd)
    Mw = _weighted_inertia(data)
    A = jax.vmap(ad)(eta)
    S = jnp.einsum("pab,pbc->pac", Mw, A)
    S = S - jnp.swapaxes(S, 1, 2)  # M ad(eta) - ad(eta)^T M
    inner = jnp.einsum("pab,pbj->paj", Mw, Jdot) + jnp.einsum("pab,pbj->paj", S, J)
    return jnp.einsum("pai,paj->ij", J, inner)


@jit
def mass_matrix(linkage: Linkage, q: ArrayLike) -> Float[Array, "n_dof n_dof"]:
    """Generalised mass matrix M(q) (the manual's GeneralizedMassMatrix).

    Symmetric positive definite whenever every coordinate moves some mass.
    """
    q = _as_q(linkage, q)
    data = precompute(linkage)
    return _mass_from_J(data, poses_and_jacobians(data, q)[1])


@jit
def coriolis_matrix(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike
) -> Float[Array, "n_dof n_dof"]:
    """Generalised Coriolis matrix C(q, qd) (the manual's GeneralizedCoriolisMatrix).

    Chosen so that ``dM/dt - 2 C`` is skew-symmetric; ``C @ qd`` equals
    :func:`coriolis_force`.
    """
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    return coriolis_matrix_from_data(precompute(linkage), q, qd)


@jit
def coriolis_force(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike
) -> Float[Array, " n_dof"]:
    """Velocity-product force ``C(q, qd) qd`` without forming C or any Jacobian."""
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    return coriolis_force_from_data(precompute(linkage), q, qd)
