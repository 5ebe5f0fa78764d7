"""Generalised external force F(q, qd, t): gravity, point wrenches and the custom hook.

DESIGN.md section 4: F = sum_p w_p J_p^T M_p Ad(g_p)^-1 G + sum_k J_k^T W_k + custom,
with G = (0, 0, 0, gravity), w_p the quadrature weight [m] at rod points (1 at rigid
centres of mass) and M_p the inertia density (or the rigid inertia). All loads are
first gathered as one array of body-frame wrenches at the significant points
(:func:`external_wrenches`); the generalised force is then either ``J^T W`` (when the
Jacobians are at hand) or the backward recursion of
:mod:`sorojax.dynamics._wrench_recursion` (statics: no Jacobians formed).
"""

import jax.numpy as jnp
from jaxtyping import Array, Float

from ..model._linkage import Linkage
from ..model._precompute import LinkageData
from ._contact import contact_wrenches
from ._wrench_recursion import force_from_wrenches, poses_with_records


def gravity_wrenches(
    data: LinkageData, g: Float[Array, "n 4 4"], idx=None
) -> Float[Array, "n 6"]:
    """Weighted body-frame gravity wrenches ``w_p M_p (0, R_p^T a)``.

    ``idx``: only at these points (``g`` then has their rows only).
    """
    a_body = jnp.einsum("pji,j->pi", g[:, :3, :3], data.gravity)  # R^T a
    G_body = jnp.concatenate([jnp.zeros_like(a_body), a_body], axis=1)
    w, M = data.point_weight, data.point_M
    if idx is not None:
        w, M = w[idx], M[idx]
    return w[:, None] * jnp.einsum("pab,pb->pa", M, G_body)


def point_wrenches(
    linkage: Linkage, t, g: Float[Array, "n 4 4"]
) -> Float[Array, "n 6"]:
    """Body-frame point wrenches of the linkage at time ``t``, one row per point."""
    W = jnp.zeros((g.shape[0], 6), dtype=g.dtype)
    for pw in linkage.point_wrenches:
        idx = linkage.point_index(pw)
        w = pw.value(t)
        if not pw.follower:
            Rt = g[idx, :3, :3].T
            w = jnp.concatenate([Rt @ w[:3], Rt @ w[3:]])
        W = W.at[idx].add(w)
    return W


def custom_wrenches(linkage: Linkage, data: LinkageData, t, q, qd, kin) -> Array:
    """Weighted wrenches of the custom hook (distributed on rods, point at CMs)."""
    W = jnp.asarray(linkage.custom_wrench(t, q, qd, kin))  # type: ignore[misc]
    if W.shape != (kin.g.shape[0], 6):
        raise ValueError(
            f"Linkage.custom_wrench returned shape {W.shape}; expected "
            f"({kin.g.shape[0]}, 6) (one body-frame wrench per significant point)."
        )
    return data.point_weight[:, None] * W


def external_wrenches(linkage: Linkage, data: LinkageData, t, g) -> Array:
    """Gravity and point wrenches at every significant point (body frames, weighted)."""
    return gravity_wrenches(data, g) + point_wrenches(linkage, t, g)


def external_force(linkage: Linkage, data: LinkageData, t, q, qd, kin) -> Array:
    """Total generalised external force ``J^T W`` given the kinematics ``kin``.

    Args:
        linkage: the model (static loads and hook).
        data: its precomputed arrays.
        t: time [s].
        q: coordinates ``(n_dof,)``.
        qd: velocities ``(n_dof,)``.
        kin: a :class:`sorojax.kinematics.Kinematics` at (q, qd).

    Returns:
        ``(n_dof,)`` generalised force.
    """
    W = external_wrenches(linkage, data, t, kin.g)
    if linkage.contact is not None:
        W = W + contact_wrenches(linkage, t, kin.g, kin.eta)
    if linkage.custom_wrench is not None:
        W = W + custom_wrenches(linkage, data, t, q, qd, kin)
    return jnp.einsum("pai,pa->i", kin.J, W)


def external_force_recursive(linkage: Linkage, data: LinkageData, t, q) -> Array:
    """Generalised external force at rest (qd = 0) without forming Jacobians.

    Only for linkages without a custom hook (the hook may need the Jacobians).
    """
    g, records = poses_with_records(data, q)
    W = external_wrenches(linkage, data, t, g)
    if linkage.contact is not None:
        W = W + contact_wrenches(linkage, t, g)
    return force_from_wrenches(data, records, W)
