"""Generalised force of body wrenches by a backward recursion: F = sum_p J_p^T W_p.

Forming every Jacobian costs O(n_points x 6 x n_dof) and its derivative (needed by
Newton) O(n_points x 6 x n_dof^2). The recursion never forms J: with
``J_{a+1} = Ad(E_a)^-1 (J_a + T_a dOmega_a)`` a wrench carried from the tips to the
base (like the RNEA's backward sweep) gives

    y_a = Ad(E_a)^-T Lambda_{a+1},  F += dOmega_a^T T_a^T y_a,  Lambda_a = W_a + y_a.

Along one link's chain (:mod:`sorojax.kinematics._recursion`) the sweep is a suffix
sum in the frame of the chain's start: with ``G_a`` the pose of point a relative to
it, ``y_b = Ad(G_b)^T sum_{a > b} Ad(G_a)^-T W_a``; every link is evaluated in one
batch and only the links' totals (each child's wrench at its start, which is its
parent's tip frame) are carried along the tree. A leaf's wrench (a contact sample
off the chain, :mod:`sorojax.model._layout`) first crosses its own step to its
chain point (:func:`leaf_wrenches`).
"""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..kinematics import _leaves
from ..kinematics._recursion import (
    chain_layout,
    chain_terms,
    from_step_end,
    leaf_poses,
    leaf_steps,
    leaf_sums,
    link_base_poses,
    point_poses,
    step_jacobians_transpose,
    steps,
    tangent_transpose_apply,
    to_step_end_wrench,
    with_leaves,
)
from ..model._precompute import LinkageData


def poses_with_records(data: LinkageData, q):
    """Poses at all significant points plus what the backward pass needs.

    All steps of the linkage in one vectorised call and the prefix products of all
    links' chains in one batch (:mod:`sorojax.kinematics._recursion`); the loop
    over the tree only carries the tip poses.
    """
    lay = chain_layout(data)
    k = steps(data, q)
    ct = chain_terms(data, k, lay)
    g = point_poses(ct, lay, link_base_poses(data, ct, lay))
    kl = leaf_steps(data, q)
    return with_leaves(lay, g, leaf_poses(lay, g, kl)), (k, ct, lay, kl)


def leaf_wrenches(data: LinkageData, lay, kl, W, rows=None, on_leaves: bool = True):
    """Leaves' wrenches carried to their chain points, and their own steps' force.

    With ``J_leaf = Ad(E)^-1 (J_a + T dOmega)`` (E the leaf's step from chain point
    a), ``J_leaf^T W = J_a^T y + dOmega^T T^T y``, ``y = Ad(E)^-T W``. Returns the
    chain points' wrenches ``(n_core, 6)`` (their own plus their leaves' ``y``) and
    the generalised force of the leaves' steps ``(n_dof,)``. ``rows``: more
    wrenches, already at the leaves' chain points (``y``), component by component
    ``(6, n_leaves)`` (only with the leaves' own kernels,
    :mod:`sorojax.kinematics._leaves`), or None; ``on_leaves``: False where ``W``
    holds nothing on the leaves (static: their rows are then not read).
    """
    Wc = W[lay.core]
    if kl is None:
        return Wc, jnp.zeros(data.n_dof, W.dtype)
    if isinstance(kl, _leaves.LeafRecord):  # many leaves: component by component
        W_l = W[np.asarray(data.leaf_points)] if on_leaves or rows is None else None
        y, F = _leaves.leaf_wrenches(data, kl, W_l, rows)
        return Wc + leaf_sums(lay, y), F
    y = from_step_end(kl.R, kl.p, W[np.asarray(data.leaf_points)])
    z = tangent_transpose_apply(kl.T, y)
    F = step_jacobians_transpose(data, kl, z, st=data.leaf_steps)
    return Wc + leaf_sums(lay, y), F


def force_from_wrenches(
    data: LinkageData,
    records,
    W: Float[Array, "n_points 6"],
    leaf_rows=None,
    on_leaves: bool = True,
) -> Float[Array, " n_dof"]:
    """``sum_p J_p^T W_p`` for body wrenches ``W`` at the significant points.

    Args:
        data: precomputed linkage.
        records: from :func:`poses_with_records` at the same ``q``.
        W: body-frame wrenches (moment, force) at every significant point, already
            multiplied by their quadrature weights where distributed.
        leaf_rows: more wrenches on the leaves, at their chain points, ``(6,
            n_leaves)`` (see :func:`leaf_wrenches`), or None.
        on_leaves: whether ``W`` holds any wrench on the leaves (static).
    """
    k, ct, lay, kl = records
    W, F_leaves = leaf_wrenches(data, lay, kl, W, leaf_rows, on_leaves)
    n_links = len(data.links)
    rows = np.arange(n_links)
    pl, ps = lay.point_link, lay.point_slot
    # Every point's wrench in its chain start's frame, Ad(G_a)^-T W_a, and suffix sums
    # over the point list: a link's points are contiguous and in slot order, so the
    # sum over its points from index i on is R[i] - R[end + 1] (gathers only, no
    # scatter: scatters are slow under vmap).
    Wt = from_step_end(ct.RG[pl, ps], ct.pG[pl, ps], W)
    R = jnp.flip(jnp.cumsum(jnp.flip(Wt, 0), 0), 0)
    R = jnp.concatenate([R, jnp.zeros_like(R[:1])])
    first = np.searchsorted(pl, rows)  # first point of each link
    stop = np.searchsorted(pl, rows, side="right")  # one past its last point
    own = R[first] - R[stop]
    # Children's totals enter at their parent's tip (carried tip to base).
    R_tip, p_tip = ct.RG[rows, lay.tip_slot], ct.pG[rows, lay.tip_slot]
    child = [jnp.zeros(6, W.dtype) for _ in range(n_links)]
    for i in range(n_links - 1, -1, -1):
        parent = data.links[i].parent
        if parent:
            total = own[i] + from_step_end(R_tip[i], p_tip[i], child[i])
            child[parent - 1] = child[parent - 1] + total
    at_tip = from_step_end(R_tip, p_tip, jnp.stack(child))
    # Step b of a link joins its slots b and b + 1: y_b = Ad(G_b)^T (sum of the
    # link's points at slots > b, and the children's wrench at its tip).
    sl, ss = lay.step_link, lay.step_slot
    after = np.array(
        [
            first[lk] + np.searchsorted(ps[first[lk] : stop[lk]], b + 1)
            for lk, b in zip(sl, ss, strict=True)
        ],
        dtype=int,
    ).reshape(-1)
    suffix = R[after] - R[stop[sl]] + at_tip[sl]
    y = to_step_end_wrench(ct.RG[sl, ss], ct.pG[sl, ss], suffix)
    z = jnp.einsum("sba,sb->sa", k.T, y)
    return step_jacobians_transpose(data, k, z) + F_leaves


def force_from_point_rates(
    data: LinkageData,
    pr,
    W: Float[Array, "n_points 6"],
    leaf_rows=None,
    on_leaves: bool = True,
):
    """``sum_p J_p^T W_p`` with :class:`~sorojax.kinematics._recursion.PointRates`.

    The chain points' Jacobians map their wrenches and their leaves' (carried
    across the leaves' steps by :func:`leaf_wrenches`); ``leaf_rows`` and
    ``on_leaves`` as there.
    """
    if pr.leaves is None:  # every point's Jacobian
        return jnp.einsum("pai,pa->i", pr.J, W)
    lay = chain_layout(data)
    Wc, F = leaf_wrenches(data, lay, pr.leaves, W, leaf_rows, on_leaves)
    return jnp.einsum("pai,pa->i", pr.J, Wc) + F
