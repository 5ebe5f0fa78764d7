"""Public generalised-force queries (the manual's GeneralizedExternalForce)."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import Kinematics, _as_q
from ..kinematics._recursion import jacobians_dot, poses_and_jacobians, strains
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._external import external_force


def kinematics_from_data(data: LinkageData, q, qd, *, need_jdot: bool) -> Kinematics:
    """Kinematics from precomputed data; Jdot only when asked (else zeros)."""
    g, J = poses_and_jacobians(data, q)
    Jdot = jacobians_dot(data, q, qd) if need_jdot else jnp.zeros_like(J)
    return Kinematics(g=g, J=J, xi=strains(data, q), eta=J @ qd, Jdot=Jdot)


@jit
def generalized_external_force(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike | None = None, t: ArrayLike = 0.0
) -> Float[Array, " n_dof"]:
    """Generalised external force F(q, qd, t): gravity, point wrenches, custom hook."""
    q = _as_q(linkage, q)
    qd = jnp.zeros_like(q) if qd is None else _as_q(linkage, qd, "qd")
    data = precompute(linkage)
    kin = kinematics_from_data(data, q, qd, need_jdot=linkage.custom_wrench is not None)
    return external_force(linkage, data, t, q, qd, kin)
