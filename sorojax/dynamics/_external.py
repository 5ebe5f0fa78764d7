"""Generalised external force F(q, qd, t): gravity, point wrenches and the custom hook.

DESIGN.md section 4: F = sum_p w_p J_p^T M_p Ad(g_p)^-1 G + sum_k J_k^T W_k + custom,
with G = (0, 0, 0, gravity), w_p the quadrature weight [m] at rod points (1 at rigid
centres of mass) and M_p the inertia density (or the rigid inertia). Global point
wrenches are rotated into the body frame of their point; follower wrenches are already
there.
"""

import jax.numpy as jnp
from jaxtyping import Array, Float

from ..model._linkage import Linkage
from ..model._precompute import LinkageData


def gravity_force(
    data: LinkageData, g: Float[Array, "n 4 4"], J: Float[Array, "n 6 d"]
) -> Float[Array, " d"]:
    """Generalised gravity force ``sum_p w_p J_p^T M_p (0, R_p^T a)``."""
    a_body = jnp.einsum("pji,j->pi", g[:, :3, :3], data.gravity)  # R^T a
    G_body = jnp.concatenate([jnp.zeros_like(a_body), a_body], axis=1)
    W = data.point_weight[:, None] * jnp.einsum("pab,pb->pa", data.point_M, G_body)
    return jnp.einsum("pai,pa->i", J, W)


def point_wrench_force(
    linkage: Linkage, t, g: Float[Array, "n 4 4"], J: Float[Array, "n 6 d"]
) -> Float[Array, " d"]:
    """Generalised force of the linkage's point wrenches at time ``t``."""
    F = jnp.zeros(J.shape[-1], dtype=J.dtype)
    for pw in linkage.point_wrenches:
        idx = linkage.point_index(pw)
        W = pw.value(t)
        if not pw.follower:
            Rt = g[idx, :3, :3].T
            W = jnp.concatenate([Rt @ W[:3], Rt @ W[3:]])
        F = F + J[idx].T @ W
    return F


def custom_force(data: LinkageData, W: Float[Array, "n 6"], J) -> Float[Array, " d"]:
    """Generalised force of the custom hook's wrenches (distributed on rods, point at CMs)."""
    return jnp.einsum("pai,pa->i", J, data.point_weight[:, None] * W)


def external_force(linkage: Linkage, data: LinkageData, t, q, qd, kin) -> Array:
    """Total generalised external force (gravity + point wrenches + custom hook).

    Args:
        linkage: the model (static loads and hook).
        data: its precomputed arrays.
        t: time [s].
        q, qd: coordinates and velocities.
        kin: a :class:`sorojax.kinematics.Kinematics` at (q, qd).

    Returns:
        ``(n_dof,)`` generalised force.
    """
    F = gravity_force(data, kin.g, kin.J)
    F = F + point_wrench_force(linkage, t, kin.g, kin.J)
    if linkage.custom_wrench is not None:
        W = jnp.asarray(linkage.custom_wrench(t, q, qd, kin))
        if W.shape != (kin.g.shape[0], 6):
            raise ValueError(
                f"Linkage.custom_wrench returned shape {W.shape}; expected "
                f"({kin.g.shape[0]}, 6) (one body-frame wrench per significant point)."
            )
        F = F + custom_force(data, W, kin.J)
    return F
