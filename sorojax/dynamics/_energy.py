"""Kinetic, gravitational and elastic energy (for checking models and integrators).

All use the same quadrature as the equations of motion, so that for a conservative
model (no damping, no point wrenches, no custom forces) their sum is an exact
invariant of the semi-discrete equations and only the time integrator makes it drift:

    T = 1/2 qd^T M(q) qd,
    U_g = - sum_p w_p m_p a . r_p   (m_p: mass density or rigid mass; r_p: the point's
          origin, the section centroid or the centre of mass),
    U_e = 1/2 q^T K q   (strain deviation from the reference strain, joint springs).

Point wrenches and the custom hook are not included (they need not be conservative).
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import _as_q
from ..kinematics._recursion import poses, poses_and_jacobians
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._contact import contact_energy_from_poses
from ._mass import _mass_from_J
from ._wrench_recursion import poses_with_records


def _gravitational(data: LinkageData, q) -> Array:
    g = poses_with_records(data, q)[0]
    m = data.point_weight * data.point_M[:, 3, 3]
    return -jnp.sum(m * (g[:, :3, 3] @ data.gravity))


def _elastic(data: LinkageData, q) -> Array:
    return 0.5 * q @ (data.K @ q)


def _kinetic(data: LinkageData, q, qd) -> Array:
    M = _mass_from_J(data, poses_and_jacobians(data, q)[1])
    return 0.5 * qd @ (M @ qd)


@jit
def kinetic_energy(linkage: Linkage, q: ArrayLike, qd: ArrayLike) -> Float[Array, ""]:
    """Kinetic energy ``1/2 qd^T M(q) qd`` [J]."""
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    return _kinetic(precompute(linkage), q, qd)


@jit
def gravitational_energy(linkage: Linkage, q: ArrayLike) -> Float[Array, ""]:
    """Gravitational potential energy [J], zero with every mass at the world origin."""
    return _gravitational(precompute(linkage), _as_q(linkage, q))


@jit
def elastic_energy(linkage: Linkage, q: ArrayLike) -> Float[Array, ""]:
    """Elastic energy ``1/2 q^T K q`` of the rods and joint springs [J]."""
    return _elastic(precompute(linkage), _as_q(linkage, q))


@jit
def total_energy(linkage: Linkage, q: ArrayLike, qd: ArrayLike) -> Float[Array, ""]:
    """Kinetic + gravitational + elastic energy [J], with contact's elastic energy."""
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    data = precompute(linkage)
    E = _kinetic(data, q, qd) + _gravitational(data, q) + _elastic(data, q)
    if linkage.contact is not None:
        E = E + contact_energy_from_poses(linkage, poses(data, q))
    return E
