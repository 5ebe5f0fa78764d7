"""Generalised force of body wrenches by a backward recursion: F = sum_p J_p^T W_p.

Forming every Jacobian costs O(n_points x 6 x n_dof) and its derivative (needed by
Newton) O(n_points x 6 x n_dof^2). The recursion never forms J: a forward pass computes
the poses and keeps each step's exp(Omega) and T(Omega); a backward pass carries one
wrench Lambda from the tips to the base (like the RNEA's backward sweep),

    J_{a+1} = Ad(E_a)^-1 (J_a + T_a dOmega_a)
    =>  y_a = Ad(E_a)^-T Lambda_{a+1},  F_a += dOmega_a^T T_a^T y_a,
        Lambda_a = W_a + y_a,

and dOmega^T x is evaluated as h/2 (Phi_1 + Phi_2)^T x + c (Phi_2^T ad(xi_1)^T x -
Phi_1^T ad(xi_2)^T x) without forming dOmega. Children add their base wrench,
transported by Ad(placement)^-T, to their parent's tip.
"""

import math

import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, Float

from ..kinematics._recursion import chain_layout, chain_poses, chain_terms, steps
from ..kinematics._step import Ad_inv_Rp
from ..lie import ad
from ..model._precompute import LinkageData

_C = math.sqrt(3.0) / 12.0


def poses_with_records(data: LinkageData, q):
    """Poses at all significant points plus per-step records for the backward pass.

    All steps of the linkage in one vectorised call and the prefix products of all
    chains in one batch (:mod:`sorojax.kinematics._recursion`); the loop over the
    tree only composes each chain with its first point's pose.
    """
    dtype = q.dtype
    layout = chain_layout(data)
    k = steps(data, q)
    ct = chain_terms(data, k, layout)
    chain_of = {(ch[0], ch[1]): (c, ch[2]) for c, ch in enumerate(layout[0])}
    tips, gs, records = [], [], []
    for i, ld in enumerate(data.links):
        g = jnp.eye(4, dtype=dtype) if ld.parent == 0 else tips[ld.parent - 1]
        g = g @ ld.placement
        jrec = None
        if ld.joint_Phi.shape[1]:
            c, s = chain_of[(i, None)]
            g = chain_poses(ct, c, 1, g)[-1]
            jrec = (k.R[s], k.p[s], k.T[s])
        gs.append(g[None])
        g = g @ ld.g_i
        drecs = []
        if ld.soft:
            for j, dd in enumerate(ld.divisions):
                c, s = chain_of[(i, j)]
                m = dd.h.shape[0]
                gd = chain_poses(ct, c, m, g)
                gs.append(gd)
                sl = slice(s, s + m)
                drecs.append((k.R[sl], k.p[sl], k.T[sl], k.xi1[sl], k.xi2[sl]))
                g = gd[-1]
        else:
            gs.append(g[None])
        g = g @ ld.g_f
        gs.append(g[None])
        tips.append(g)
        records.append((jrec, drecs))
    return jnp.concatenate(gs), records


def _Ad_inv_T(g):
    return Ad_inv_Rp(g[:3, :3], g[:3, 3]).T


def force_from_wrenches(
    data: LinkageData, records, W: Float[Array, "n_points 6"], q
) -> Float[Array, " n_dof"]:
    """``sum_p J_p^T W_p`` for body wrenches ``W`` at the significant points.

    Args:
        data: precomputed linkage.
        records: from :func:`poses_with_records` at the same ``q``.
        W: body-frame wrenches (moment, force) at every significant point, already
            multiplied by their quadrature weights where distributed.
        q: coordinates (for the basis contractions).
    """
    F = jnp.zeros(data.n_dof, dtype=W.dtype)
    n_links = len(data.links)
    # Point indices per link, in the same order as the forward pass.
    starts, idx = [], 0
    for ld in data.links:
        starts.append(idx)
        idx += 2 + (sum(dd.h.shape[0] + 1 for dd in ld.divisions) if ld.soft else 1)
    child_wrench = [jnp.zeros(6, dtype=W.dtype) for _ in range(n_links)]
    for i in range(n_links - 1, -1, -1):
        ld = data.links[i]
        jrec, drecs = records[i]
        s = starts[i]
        tip_idx = (
            s + 1 + (sum(dd.h.shape[0] + 1 for dd in ld.divisions) if ld.soft else 1)
        )
        Lam = W[tip_idx] + child_wrench[i]
        Lam = _Ad_inv_T(ld.g_f) @ Lam  # to the body end (rod end / CM)
        if ld.soft:
            end = tip_idx
            for dd, rec in zip(ld.divisions[::-1], drecs[::-1], strict=True):
                m = dd.h.shape[0]
                first = end - (m + 1)
                Wd = W[first:end]
                Lam = Lam + Wd[-1]
                o, n = dd.offset, dd.n_dof

                def back(Lam_next, x, n=n):
                    (R, p, T, xi1, xi2), h, P, W_a = x
                    y = Ad_inv_Rp(R, p).T @ Lam_next
                    z = T.T @ y
                    if n:
                        c = _C * h * h
                        f = 0.5 * h * (P[0] + P[1]).T @ z + c * (
                            P[1].T @ (ad(xi1).T @ z) - P[0].T @ (ad(xi2).T @ z)
                        )
                    else:
                        f = jnp.zeros((0,), dtype=z.dtype)
                    return W_a + y, f

                Lam, fs = lax.scan(
                    back, Lam, (rec, dd.h, dd.Phi_z, Wd[:-1]), reverse=True
                )
                if n:
                    F = F.at[o : o + n].add(jnp.sum(fs, axis=0))
                end = first
        else:
            Lam = Lam + W[s + 1]
        Lam = _Ad_inv_T(ld.g_i) @ Lam + W[s]  # to the joint frame
        if jrec is not None:
            R, p, T = jrec
            y = Ad_inv_Rp(R, p).T @ Lam
            nj = ld.joint_Phi.shape[1]
            F = F.at[ld.joint_offset : ld.joint_offset + nj].add(
                ld.joint_Phi.T @ (T.T @ y)
            )
            Lam = y
        if ld.parent:
            child_wrench[ld.parent - 1] = (
                child_wrench[ld.parent - 1] + _Ad_inv_T(ld.placement) @ Lam
            )
    return F
