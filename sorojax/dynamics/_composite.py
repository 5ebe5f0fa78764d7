"""The mass matrix from composite inertias, without the points' Jacobians.

``M = sum_p w_p J_p^T M_p J_p`` costs O(points x 6 x n_dof^2) from the Jacobians.
The coordinates come in groups, a joint's or a division's, each acting through its
own steps only. In the frame of a link's chain start (pose ``G_a`` of point a
relative to it) a point's Jacobian is ``Ad(G_a) J_a = J0 + sum_{b<a} S_b``, with
``S_b = Ad(G_b) T_b dOmega_b`` nonzero on the columns of step b's group only, and
``J0`` the chain start's Jacobian (its parent's tip's; zero at the ground). With the
points' inertias in that frame, ``Mh_p = Ad(G_p)^-T w_p M_p Ad(G_p)^-1``:

* a point inside group g (after some of its steps) sees the partial sum
  ``C_p = sum_{b<a, b in g} S_b`` of g's steps; a point past g sees all of them,
  ``D_g``, whatever it is (a point, a later group's, a descendant link's);
* the diagonal block of g is ``sum_{p in g} C_p^T Mh_p C_p + D_g^T I_g D_g`` with
  ``I_g`` the composite inertia past g (the sum of every later point's ``Mh``,
  descendant links' carried from their start);
* the columns of g against every earlier column are ``Jstart_g^T P_g`` with
  ``P_g = sum_{p in g} Mh_p C_p + I_g D_g`` and ``Jstart_g = J0 + sum_{g' < g}
  D_{g'}`` the chain-frame Jacobian where g starts (later columns: zero).

Every block is ``(k, k)`` (groups padded to the widest): the start Jacobians are kept
by blocks, ``(groups, groups, 6, k)``. Cost: O(points x 6 x k^2) for groups of k
columns and O(groups^2 x 6 x k^2) for the blocks, gathered into M, where the
Jacobians' product is O(points x 6 x n_dof^2): for cosseratbench's pile (a 111-DoF
rope of ten divisions of 11 coordinates and a joint, 100 mass points) about 13x
fewer flops.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ..kinematics._recursion import ChainLayout, Steps, _Ad, dOmega
from ..model._precompute import LinkageData, lock_padding


class GroupLayout(NamedTuple):
    """Static layout of the coordinate groups (numpy, from shapes only).

    The groups are :class:`~sorojax.model._precompute.GroupBasis`'s (its segments of
    steps, in :class:`~sorojax.model._precompute.StepData` order). ``link``,
    ``slot0``, ``slot1`` ``(n_groups,)``: each group's link and its steps' slots
    ``[slot0, slot1)`` in the link's chain; ``step0`` its first step;
    ``mass_group`` ``(n_mass,)`` the group each mass point is inside (-1: none) and
    ``mass_step`` ``(n_mass,)`` the end of its partial sum (an index into the
    steps' prefix sums); ``after`` ``(n_groups, n_mass)`` 1 where a mass point lies
    past the group; ``before`` ``(n_groups, n_groups)`` 1 where a group precedes
    another in one chain.
    """

    link: np.ndarray
    slot0: np.ndarray
    slot1: np.ndarray
    step0: np.ndarray
    mass_group: np.ndarray
    mass_step: np.ndarray
    after: np.ndarray
    before: np.ndarray


def _group_layout(data: LinkageData, lay: ChainLayout) -> GroupLayout:
    """The :class:`GroupLayout` of ``data``: its groups placed on the chains."""
    step0, stop = (
        np.array(x, int) for x in zip(*data.steps.group.segments, strict=True)
    )
    link, slot0 = lay.step_link[step0], lay.step_slot[step0]
    slot1 = slot0 + stop - step0
    idx = np.asarray(data.mass_points, int)
    rows = lay.row[idx]
    assert (rows >= 0).all(), "a leaf carries mass"
    pl, ps = lay.point_link[rows], lay.point_slot[rows]
    # a point at prefix a is inside the group of the step before it (slot a - 1)
    inside = (pl[:, None] == link) & (ps[:, None] > slot0) & (ps[:, None] <= slot1)
    mass_group = np.where(inside.any(1), inside.argmax(1), -1)
    g = np.maximum(mass_group, 0)
    mass_step = np.where(mass_group >= 0, step0[g] + ps - slot0[g], 0)
    after = ((pl[:, None] == link) & (ps[:, None] > slot1)).T.astype(float)
    n_g = len(link)
    before = (link[:, None] == link) & (np.arange(n_g)[:, None] < np.arange(n_g))
    return GroupLayout(
        link, slot0, slot1, step0, mass_group, mass_step, after, before.astype(float)
    )


def uses_composite(data: LinkageData) -> bool:
    """Whether the dynamics forms M from composite inertias (static).

    Where the chain's steps have :class:`~sorojax.model._precompute.GroupBasis`
    (:data:`~sorojax.model._precompute.MIN_GROUPS` coordinate groups and
    :data:`~sorojax.model._precompute.MIN_GROUP_DOF` coordinates or more).
    """
    return data.steps.group is not None


def composite_mass(
    data: LinkageData, k: Steps, ct, lay: ChainLayout, added=None
) -> Array:
    """``M`` from composite inertias (module docstring).

    ``k``, ``ct``: the chain's steps and :class:`~sorojax.kinematics._recursion.
    ChainTerms` (poses relative to each chain's start) at the configuration;
    ``added``: ``(n_mass, 6, 6)`` added inertia of the mass points (weighted), or
    None.
    """
    gl = _group_layout(data, lay)
    gb = data.steps.group
    n_g, K = len(gl.link), gb.values.shape[3]
    dtype = k.R.dtype
    # every step's S_b on its group's columns, in its chain's frame
    dO = dOmega(data.steps, k, gb.values)  # (n_steps, 6, K)
    sl, ss = lay.step_link, lay.step_slot
    S = _Ad(ct.RG[sl, ss], ct.pG[sl, ss]) @ (k.T @ dO)
    cum = jnp.concatenate([jnp.zeros_like(S[:1]), jnp.cumsum(S, axis=0)])
    D = cum[gl.step0 + gl.slot1 - gl.slot0] - cum[gl.step0]  # (n_g, 6, K)
    # the mass points' inertias in their chain's frame, and their partial sums
    idx = np.asarray(data.mass_points, int)
    rows = lay.row[idx]
    pl, ps = lay.point_link[rows], lay.point_slot[rows]
    Gi = ct.Ginv[pl, ps]
    Mw = data.point_weight[idx, None, None] * data.point_M[idx]
    if added is not None:
        Mw = Mw + added
    Mh = jnp.swapaxes(Gi, 1, 2) @ Mw @ Gi
    g = np.maximum(gl.mass_group, 0)
    C = cum[gl.mass_step] - cum[gl.step0[g]]
    C = C * jnp.asarray(gl.mass_group >= 0, dtype)[:, None, None]
    MC = Mh @ C
    # each group's points side by side (padded by a zero row): one product a group
    members = [np.flatnonzero(gl.mass_group == i) for i in range(n_g)]
    width = max(1, max(len(m) for m in members))
    at = np.full((n_g, width), len(idx))
    for i, m in enumerate(members):
        at[i, : len(m)] = m
    Cg, MCg = (
        jnp.concatenate([x, jnp.zeros_like(x[:1])])[at].reshape(n_g, width * 6, K)
        for x in (C, MC)
    )
    P_in = jnp.sum(MCg.reshape(n_g, width, 6, K), axis=1)
    # composite inertia past each group: its link's later points, its descendants
    I_past = jnp.einsum("gp,pab->gab", jnp.asarray(gl.after, dtype), Mh)
    n_links = len(data.links)
    tree = any(ld.parent for ld in data.links)
    if tree:
        own = jnp.einsum(
            "lp,pab->lab", jnp.asarray(np.arange(n_links)[:, None] == pl, dtype), Mh
        )
        Gt = ct.Ginv[np.arange(n_links), lay.tip_slot]
        desc = [jnp.zeros((6, 6), dtype) for _ in range(n_links)]
        for i in range(n_links - 1, -1, -1):
            parent = data.links[i].parent
            if parent:
                Gp = Gt[parent - 1]
                desc[parent - 1] = desc[parent - 1] + Gp.T @ (own[i] + desc[i]) @ Gp
        I_past = I_past + jnp.stack(desc)[gl.link]
    ID = I_past @ D
    P = P_in + ID
    # the diagonal blocks F_g^T H_g: the group's own points and the inertia past it
    F = jnp.concatenate([Cg, D], axis=1)
    H = jnp.concatenate([MCg, ID], axis=1)
    # block (h, g): group h's columns of the chain-frame Jacobian where g starts
    # (D_h for an earlier group of g's chain, carried from an ancestor link's tip);
    # the blocks above the diagonal and half of the diagonal ones; M = U + U^T
    # rows (h, k), columns (g, l); a zero row and column for columns outside groups
    # (formed transposed, V = U^T: rows (g, l), columns (h, k), as the product
    # lays them out; B is symmetric)
    before = jnp.asarray(gl.before, dtype)
    if tree:
        Jst = before[:, :, None, None] * D[:, None]  # (h, g)
        in_link = np.arange(n_links)[:, None] == gl.link
        X = [jnp.zeros((n_g, 6, K), dtype) for _ in range(n_links)]
        for i, ld in enumerate(data.links):
            if ld.parent:
                p = ld.parent - 1
                own_D = jnp.asarray(in_link[p], dtype)[:, None, None] * D
                X[i] = jnp.einsum("ab,hbk->hak", Gt[p], X[p] + own_D)
        Jst = Jst + jnp.swapaxes(jnp.stack(X)[gl.link], 0, 1)
        V = jnp.einsum("hgak,gal->glhk", Jst, P)
    else:  # links on the ground: in coordinate order, from the start
        M = _chain_blocks(P, D, F, H, gl, np.array(gb.src))
        return lock_padding(M, data.locked)
    B = jnp.einsum("gxk,gxl->gkl", F, H)
    eye = jnp.eye(n_g, dtype=dtype)[:, None, :, None]
    V = (V + eye * (0.5 * B)[:, :, None, :]).reshape(n_g * K, n_g * K)
    src = np.array(gb.src)
    if src.max() == n_g * K:
        V = jnp.pad(V, ((0, 1), (0, 1)))
    V = _take_runs(_take_runs(V, src, 0), src, 1)
    return lock_padding(V + V.T, data.locked)


def _chain_blocks(P, D, F, H, gl: GroupLayout, src: np.ndarray) -> Array:
    """``M`` (before locking) of links on the ground, formed in coordinate order.

    ``P``, ``D`` ``(n_g, 6, K)`` and the diagonal blocks' factors ``F``, ``H``
    ``(n_g, x, K)`` of :func:`composite_mass`; ``src``: each coordinate's group
    column (``n_g K``: none).
    Every group's P against every D in one product of the coordinates' rows and
    columns (taken before it: the product is then M's size, with nothing to gather
    after it), masked where the row's group precedes the column's; each group's
    diagonal block ``F_g^T H_g`` (a 2-D product a group: the batched product
    measured 6-9 us slower on the pile) written over its zero block; ``M = V +
    V^T``.
    """
    n_g, _, K = P.shape
    P2 = jnp.swapaxes(P, 1, 2).reshape(n_g * K, 6)
    D2 = jnp.swapaxes(D, 0, 1).reshape(6, n_g * K)
    if src.max() == n_g * K:  # a zero row for the coordinates outside the groups
        P2 = jnp.concatenate([P2, jnp.zeros_like(P2[:1])])
        D2 = jnp.concatenate([D2, jnp.zeros_like(D2[:, :1])], axis=1)
    grp = np.where(src < n_g * K, src // K, -1)
    g = np.maximum(grp, 0)
    inside = (grp[:, None] >= 0) & (grp[None, :] >= 0)
    mask = np.where(inside, gl.before.T[g[:, None], g[None, :]], 0.0)
    V = (_take_runs(P2, src, 0) @ _take_runs(D2, src, 1)) * jnp.asarray(mask, P.dtype)
    # each group's coordinates are consecutive, its columns 0..k-1 in order
    # (GroupBasis); its own block of V is zero (a group does not precede itself)
    for h in range(n_g):
        pos = np.flatnonzero(grp == h)
        if len(pos):
            o, k = int(pos[0]), len(pos)
            half = 0.5 * (F[h, :, :k].T @ H[h, :, :k])
            V = jax.lax.dynamic_update_slice(V, half, (o, o))
    return V + V.T


def _take_runs(x, idx: np.ndarray, axis: int):
    """``x`` at static indices ``idx`` along ``axis``: slices of their runs.

    The coordinates' rows and columns are a few runs of consecutive group columns
    (a joint's column, then every division's), so copies of slices replace a gather
    (which XLA's CPU backend runs element by element); past eight runs, the gather.
    """
    runs = np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1)
    if len(runs) > 8:
        return jnp.take(x, idx, axis=axis)
    parts = [
        jax.lax.slice_in_dim(x, int(r[0]), int(r[-1]) + 1, axis=axis) for r in runs
    ]
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts, axis=axis)
