"""The leaves' steps in component-major form: the dynamics' contact samples.

A leaf (a contact sample off the kinematic chain, :mod:`sorojax.model._layout`) is
one 4th-order Magnus step from the chain point before it (DESIGN.md section 3). The
dynamics needs of each leaf its pose, its twist and the transpose of its Jacobian
applied to its wrench, never the Jacobian itself:

    eta_leaf = Ad(E)^-1 (eta_a + T(Omega) Omegadot),
    J_leaf^T W = J_a^T y + dOmega^T T(Omega)^T y,   y = Ad(E)^-T W,

with E = exp(Omega). Here every quantity is stored component-major, leaves last
(``(6, n_leaves)`` twists, ``(3, 3, n_leaves)`` rotations): each arithmetic operation
is then one loop over the leaves, where the point-major layout of
:mod:`sorojax.kinematics._recursion` (trailing dimensions of 3 and 6) costs XLA's CPU
backend several times more per leaf. A leaf's strain reads its own division's
coordinates only (``LeafData.basis`` holds those columns, padded to the widest
division). The exp/tangent coefficients are those of
:func:`sorojax.kinematics._step.coefficients`; the results equal
:func:`sorojax.kinematics._recursion.point_rates`'s to round-off (tested).

6th-order models (a division of basis order >= 4) take the point-major path.
"""

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ._step import _SERIES, _SMALL


def _coefficients(theta2):
    """:func:`sorojax.kinematics._step.coefficients` of ``(L,)`` angles squared.

    The same closed forms and Taylor series (double-where below ``_SMALL``), each
    coefficient's series its own loop over the leaves (the stacked ``(L, 5)`` form
    costs several times more in this layout).
    """
    small = theta2 < _SMALL
    t2 = jnp.where(small, 1.0, theta2)
    t = jnp.sqrt(t2)
    s, c = jnp.sin(t), jnp.cos(t)
    closed = (
        s / t,
        (1.0 - c) / t2,
        (t - s) / (t2 * t),
        (t2 / 2 + c - 1.0) / (t2 * t2),
        (2.0 * t - 3.0 * s + t * c) / (2.0 * t2 * t2 * t),
    )
    x = jnp.where(small, theta2, 0.0)
    out = []
    for j, cl in enumerate(closed):
        rows = _SERIES[:, j]
        y = jnp.full_like(x, rows[-1])
        for r in rows[-2::-1]:
            y = y * x + r
        out.append(jnp.where(small, y, cl))
    return out


def _cross(a, b):
    """Cross products of component-major 3-vectors ``(3, L)``."""
    return jnp.stack(
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    )


def _ad(x, y):
    """``ad(x) y`` for twists ``(6, L)``: ``(w x a, v x a + w x b)``."""
    w, v, a, b = x[:3], x[3:], y[:3], y[3:]
    return jnp.concatenate([_cross(w, a), _cross(v, a) + _cross(w, b)])


def _ad_transpose(x, z):
    """``ad(x)^T z`` for a twist ``x`` and a wrench ``z = (m, f)``, ``(6, L)``."""
    w, v, m, f = x[:3], x[3:], z[:3], z[3:]
    return jnp.concatenate([_cross(m, w) + _cross(f, v), _cross(f, w)])


def _matvec(M, x):
    """``M x`` for ``(3, 3, L)`` matrices and ``(3, L)`` vectors."""
    return M[:, 0] * x[0][None] + M[:, 1] * x[1][None] + M[:, 2] * x[2][None]


def _matvec_t(M, x):
    """``M^T x`` for ``(3, 3, L)`` matrices and ``(3, L)`` vectors."""
    return M[0] * x[0][None] + M[1] * x[1][None] + M[2] * x[2][None]


def _hat(w):
    """Skew matrices ``(3, 3, L)`` of ``(3, L)`` vectors."""
    z = jnp.zeros_like(w[0])
    return jnp.stack(
        [jnp.stack([z, -w[2], w[1]]), jnp.stack([w[2], z, -w[0]]),
         jnp.stack([-w[1], w[0], z])]
    )  # fmt: skip


class LeafLayout(NamedTuple):
    """Static tables of the leaves (numpy).

    ``cols`` ``(n_local, L)``: the coordinate of each local basis column of each
    leaf (0 where padded); ``div_first``, ``div_stop``: the leaves of each division
    that has leaves; ``dof_local``, ``dof_div`` ``(n_dof,)``: where each
    coordinate's force from the leaves lies in the ``(n_local, n_divisions + 1)``
    table of sums (the last column is zero: coordinates of no such division).
    """

    cols: np.ndarray
    div_first: np.ndarray
    div_stop: np.ndarray
    dof_local: np.ndarray
    dof_div: np.ndarray


def leaf_layout(data) -> LeafLayout:
    """The :class:`LeafLayout` of ``data`` (static: from shapes only)."""
    n_local = data.leaf_data.basis.shape[0]
    cols, first, stop = [], [], []
    dof_local = np.zeros(data.n_dof, int)
    dof_div = np.full(data.n_dof, -1)
    start = 0
    for ld in data.links:
        for dd in ld.divisions if ld.soft else ():
            m = 0 if dd.leaf_h is None else dd.leaf_h.shape[0]
            if not m:
                continue
            c = np.zeros((n_local, m), int)
            c[: dd.n_dof] = np.arange(dd.offset, dd.offset + dd.n_dof)[:, None]
            cols.append(c)
            dof_local[dd.offset : dd.offset + dd.n_dof] = np.arange(dd.n_dof)
            dof_div[dd.offset : dd.offset + dd.n_dof] = len(first)
            first.append(start)
            stop.append(start + m)
            start += m
    dof_div = np.where(dof_div < 0, len(first), dof_div)
    return LeafLayout(
        np.concatenate(cols, axis=1), np.array(first), np.array(stop), dof_local,
        dof_div,
    )  # fmt: skip


class LeafSteps(NamedTuple):
    """The leaves' steps, component-major (leaves last).

    ``x1, x2``: strains at the Zanna points ``(6, L)``; ``R`` ``(3, 3, L)`` and
    ``p`` ``(3, L)``: exp(Omega); ``Ts``, ``Q`` ``(3, 3, L)``: the blocks of the
    tangent operator ``T = [[Ts, 0], [Q, Ts]]``.
    """

    x1: Array
    x2: Array
    R: Array
    p: Array
    Ts: Array
    Q: Array


def _strains(data, lay: LeafLayout, q):
    """Strains (or their rates, ``xi_ref`` left out) at the Zanna points."""
    ld = data.leaf_data
    return jnp.einsum("nzal,nl->zal", ld.basis, q[lay.cols])


def leaf_steps(data, lay: LeafLayout, q) -> LeafSteps:
    """Every leaf's step at ``q`` (4th order), component-major."""
    ld = data.leaf_data
    xi = _strains(data, lay, q) + ld.xi_ref
    x1, x2 = xi[0], xi[1]
    Om = 0.5 * ld.h[None] * (x1 + x2) + ld.c[None] * _ad(x1, x2)
    w, v = Om[:3], Om[3:]
    t2 = jnp.sum(w * w, axis=0)
    wv = jnp.sum(w * v, axis=0)
    # coefficients broadcast over a vector's rows (1, L) and a matrix's (1, 1, L)
    A, B, C, D, F = (x[None, None] for x in _coefficients(t2))
    t2m, wvm = t2[None, None], wv[None, None]
    eye = jnp.eye(3, dtype=q.dtype)[:, :, None]
    W, V = _hat(w), _hat(v)
    W2 = w[:, None] * w[None, :] - t2m * eye
    R = eye + A * W + B * W2
    Ts = eye + B * W + C * W2
    wxv = _cross(w, v)
    p = v + B[0] * wxv + C[0] * (w * wv[None] - t2[None] * v)
    WV_VW = v[:, None] * w[None, :] + w[:, None] * v[None, :] - 2.0 * wvm * eye
    W2V_VW2 = w[:, None] * wxv[None, :] - wxv[:, None] * w[None, :] - 2.0 * t2m * V
    Q = (
        0.5 * V
        + C * (WV_VW - wvm * W)
        + D * (W2V_VW2 + 3.0 * wvm * W)
        - 2.0 * F * wvm * W2
    )
    return LeafSteps(x1, x2, R, p, Ts, Q)


def leaf_poses(g_parent, k: LeafSteps) -> Array:
    """World poses ``(L, 4, 4)`` of the leaves from their chain points' poses."""
    R = jnp.moveaxis(k.R, -1, 0)
    p = k.p.T
    Rg = g_parent[:, :3, :3]
    top = jnp.concatenate(
        [Rg @ R, (jnp.einsum("lab,lb->la", Rg, p) + g_parent[:, :3, 3])[..., None]],
        axis=-1,
    )
    return jnp.concatenate([top, g_parent[:, 3:]], axis=1)


def leaf_twists(data, lay: LeafLayout, k: LeafSteps, eta_parent, qd) -> Array:
    """Body twists ``(L, 6)`` of the leaves: ``Ad(E)^-1 (eta_a + T Omegadot)``."""
    ld = data.leaf_data
    xd = _strains(data, lay, qd)
    xd1, xd2 = xd[0], xd[1]
    h, c = ld.h[None], ld.c[None]
    Od = 0.5 * h * (xd1 + xd2) + c * (_ad(k.x1, xd2) - _ad(k.x2, xd1))
    a, b = Od[:3], Od[3:]
    e = eta_parent.T
    w = e[:3] + _matvec(k.Ts, a)
    v = e[3:] + _matvec(k.Q, a) + _matvec(k.Ts, b)
    # Ad(E)^-1 (w, v) = (R^T w, R^T (v + w x p))
    out = jnp.concatenate([_matvec_t(k.R, w), _matvec_t(k.R, v + _cross(w, k.p))])
    return out.T


def leaf_wrenches(data, lay: LeafLayout, k: LeafSteps, W_leaf):
    """The leaves' wrenches ``W_leaf`` ``(L, 6)`` carried to their chain points.

    Returns ``(y, F)``: ``y = Ad(E)^-T W`` ``(L, 6)`` and the generalised force of
    the leaves' own steps, ``sum dOmega^T T^T y`` ``(n_dof,)``.
    """
    ld = data.leaf_data
    m, f = W_leaf.T[:3], W_leaf.T[3:]
    Rf = _matvec(k.R, f)
    y = jnp.concatenate([_matvec(k.R, m) + _cross(k.p, Rf), Rf])
    ym, yf = y[:3], y[3:]
    z = jnp.concatenate([_matvec_t(k.Ts, ym) + _matvec_t(k.Q, yf), _matvec_t(k.Ts, yf)])
    h, c = ld.h[None], ld.c[None]
    Z1 = 0.5 * h * z - c * _ad_transpose(k.x2, z)
    Z2 = 0.5 * h * z + c * _ad_transpose(k.x1, z)
    per_leaf = jnp.einsum("nzal,zal->nl", ld.basis, jnp.stack([Z1, Z2]))
    # sum each division's leaves (consecutive): differences of prefix sums
    c = jnp.concatenate(
        [jnp.zeros_like(per_leaf[:, :1]), jnp.cumsum(per_leaf, axis=1)], axis=1
    )
    sums = c[:, lay.div_stop] - c[:, lay.div_first]  # (n_local, n_divisions)
    sums = jnp.concatenate([sums, jnp.zeros_like(sums[:, :1])], axis=1)
    return y.T, sums[lay.dof_local, lay.dof_div]
