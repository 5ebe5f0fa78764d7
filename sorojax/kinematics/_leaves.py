"""The leaves' steps in the dynamics, computed component by component.

A leaf (a contact sample off the kinematic chain, :mod:`sorojax.model._layout`) is one
Magnus step from its chain point: its pose, its twist, its Jacobian (the contacts'
tangent in ROS34PW2's W) and, backwards, the generalised force of a wrench on it need
that step's ``exp(Omega)`` and tangent ``T(Omega)``
(:mod:`sorojax.kinematics._recursion`, :func:`~sorojax.kinematics._recursion.
point_rates`, :func:`~sorojax.dynamics._wrench_recursion.leaf_wrenches`). With many
leaves (a rod sampled every few millimetres) this is most of an evaluation. Here the
same formulas run on the leaves stored component by component: every quantity is a
row of shape ``(n_leaves,)`` (structure of arrays), so each XLA kernel is a loop over
the leaves, vectorised along them, instead of one over ``(n, 3, 3)`` and ``(n, 6, 6)``
stacks whose minor axes are three or six numbers long.

XLA's CPU fusion copies an elementwise producer into every kernel that reads it,
unless the producer is an expensive operation (a division, a square root): terms that
many rows share (the exp's coefficients, the step's twist, the rotated wrench) would
be recomputed in every kernel that reads them. :func:`_kept` stacks such terms behind
an optimisation barrier, so that XLA stores the stack rather than moving its work
into the kernels that read it. The barrier is lifted before XLA's fusion, which may
still recompute a few terms in a reader; dividing the stack by ones computed at run
time (an expensive operation, never recomputed) measured slower, a division per
value costing more than what it saves.

In the dynamics the leaves' contact with the obstacles reads their world positions
and velocities (:class:`LeafFrames`: from the chain point's frame, without the
leaves' rotations) and gives its wrenches back at the chain points, so that neither
the leaves' ``(n, 4, 4)`` poses nor their body twists are formed there.

The strains at the steps' nodes and the generalised force of the steps' covectors
read the bases by their nonzero entries (:class:`~sorojax.model._precompute.
LeafBasis`: a polynomial basis's column is nonzero on one strain row, and a leaf
reads its own division's columns only), not the full-width ``Phi_t``.

For 4th-order steps (a linkage whose bases are below quartic,
:func:`~sorojax.model._precompute.magnus_order`) and at least :data:`MIN_LEAVES`
leaves; otherwise the stacked kernels of :mod:`sorojax.kinematics._recursion` serve.
The values agree with those to rounding (tests/test_leaves.py).
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array

from ..model._precompute import MIN_LEAVES
from ._step import _SERIES, _SMALL, closed_forms


class LeafFrames(NamedTuple):
    """The leaves' positions and velocities, component by component.

    ``R`` ``(3, 3, n)`` and ``o`` ``(3, n)``: the world frame of each leaf's chain
    point; ``x`` ``(3, n)``: the leaf's world position; ``w``, ``v`` ``(3, n)``: its
    world angular velocity and the world velocity of its origin; ``axis`` ``(3,
    n)``: its first body axis in the world; ``p``, ``w_c``, ``v_c``, ``axis_c``
    ``(3, n)``: its position, angular velocity, velocity and first body axis in
    its chain point's frame. What the obstacles' contact reads
    (:func:`~sorojax.dynamics._contact.contact_loads`: a static plane in the
    chain points' frames, any other obstacle in the world; XLA drops what none
    reads); a wrench there comes back in the chain point's frame, as
    :func:`leaf_wrenches` takes it.
    """

    R: Array
    o: Array
    x: Array
    w: Array
    v: Array
    axis: Array
    p: Array
    w_c: Array
    v_c: Array
    axis_c: Array


class LeafRecord(NamedTuple):
    """The leaves' steps, component by component (rows over the leaves).

    ``R`` ``(3, 3, n)`` and ``p`` ``(3, n)``: exp(Omega); ``Ts``, ``Q`` ``(3, 3, n)``:
    the blocks of T(Omega) = [[Ts, 0], [Q, Ts]]; ``xi`` ``(2, 6, n)``: the strains at
    the step's Zanna points.
    """

    R: Array
    p: Array
    Ts: Array
    Q: Array
    xi: Array


def applies(data) -> bool:
    """Whether the dynamics poses the leaves of ``data`` here (static)."""
    st = data.leaf_steps
    return (
        st is not None
        and st.compact is not None
        and len(data.leaf_points) >= MIN_LEAVES
    )


def _kept(x):
    """``x`` (an array or nested lists of ``(n,)`` rows) stacked and stored.

    Behind an optimisation barrier (see the module docstring); the values are those
    of the stack.
    """
    return jax.lax.optimization_barrier(_stacked(x))


def _stacked(x):
    if isinstance(x, list | tuple):
        return jnp.stack([_stacked(y) for y in x])
    return x


def _cross(a, b):
    return [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]


def _mat_vec(M, x, transpose: bool = False):
    """``M x`` (or ``M^T x``) for a ``(3, 3, n)`` stack and rows ``x``."""
    if transpose:
        return [M[0, i] * x[0] + M[1, i] * x[1] + M[2, i] * x[2] for i in range(3)]
    return [M[i, 0] * x[0] + M[i, 1] * x[1] + M[i, 2] * x[2] for i in range(3)]


def _add(a, b):
    return [x + y for x, y in zip(a, b, strict=True)]


def _exp_and_tangent(Omega):
    """``R, p, Ts, Q`` of :func:`~sorojax.kinematics._step.exp_and_tangent`.

    ``Omega``: the twists ``(6, n)``; returns ``(3, 3, n)``, ``(3, n)``, ``(3, 3, n)``,
    ``(3, 3, n)``. The same closed forms (W = hat(w), V = hat(v)) and Taylor series
    (by Horner's rule, each coefficient's own). The closed forms (a square root, a
    sine, a cosine and five divisions per step) are evaluated only where some step
    turns by a radian or more (a ``lax.cond``): XLA's CPU runs sine and cosine
    element by element (~9 ns per value and function, the largest kernel of a
    thousand leaves), and short steps take the series.
    """
    w, v = Omega[:3], Omega[3:]
    th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    small = th2 < _SMALL

    def closed_rows(th2):
        t2 = jnp.where(small, 1.0, th2)
        t = jnp.sqrt(t2)
        sc = _kept([jnp.sin(t), jnp.cos(t)])
        return _kept(list(closed_forms(t, t2, sc[0], sc[1])))

    closed = jax.lax.cond(
        jnp.all(small),
        lambda th2: jnp.zeros((5,) + th2.shape, th2.dtype),  # not read
        closed_rows,
        th2,
    )
    coef = []
    for col, closed_form in zip(_SERIES.T, closed, strict=True):
        series = jnp.full_like(th2, col[-1])
        for ck in col[-2::-1]:
            series = series * th2 + ck
        coef.append(jnp.where(small, series, closed_form))
    wv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2]
    k = _kept(coef + [th2, wv] + _cross(w, v))
    A, B, C, D, F, th2, wv = (k[i] for i in range(7))
    wxv = k[7:]
    zero = jnp.zeros_like(th2)
    W = [[zero, -w[2], w[1]], [w[2], zero, -w[0]], [-w[1], w[0], zero]]
    V = [[zero, -v[2], v[1]], [v[2], zero, -v[0]], [-v[1], v[0], zero]]

    def eye(i, j, x=1.0):
        return x if i == j else 0.0

    W2 = [[w[i] * w[j] - eye(i, j, th2) for j in range(3)] for i in range(3)]
    R = [[eye(i, j) + A * W[i][j] + B * W2[i][j] for j in range(3)] for i in range(3)]
    Ts = [[eye(i, j) + B * W[i][j] + C * W2[i][j] for j in range(3)] for i in range(3)]
    p = [v[i] + B * wxv[i] + C * (w[i] * wv - th2 * v[i]) for i in range(3)]
    Q = [
        [
            0.5 * V[i][j]
            + C * (v[i] * w[j] + w[i] * v[j] - eye(i, j, 2.0 * wv) - wv * W[i][j])
            + D * (w[i] * wxv[j] - wxv[i] * w[j] - 2.0 * th2 * V[i][j])
            + 3.0 * D * wv * W[i][j]
            - 2.0 * F * wv * W2[i][j]
            for j in range(3)
        ]
        for i in range(3)
    ]
    return _kept(R), _kept(p), _kept(Ts), _kept(Q)


def _ad(a, b):
    """``ad(a) b`` for twists ``(6, ...)``, as a list of 6 rows."""
    w, v, x, y = a[:3], a[3:], b[:3], b[3:]
    return _cross(w, x) + _add(_cross(v, x), _cross(w, y))


def _ad_transpose(a, z):
    """``ad(a)^T z`` for a twist ``a`` and a wrench ``z = (m, f)``, as 6 rows."""
    w, v, m, f = a[:3], a[3:], z[:3], z[3:]
    return _add(_cross(m, w), _cross(f, v)) + _cross(f, w)


def leaf_rates(data, lay, q, qd, g_core, eta_core):
    """The leaves' world poses ``(n, 4, 4)``, body twists ``(n, 6)``, record, frames.

    ``g_core``, ``eta_core``: poses and twists of the chain's points (rows of
    ``lay.core``). The twist of a leaf is ``Ad(E)^-1 (eta_c + T(Omega) dOmega qd)``
    (E its step from its chain point c), its pose ``g_c E``.
    """
    st = data.leaf_steps
    xi, xd = st.compact.strains(q, st.xi_ref_t), st.compact.strains(qd)
    xi = _kept(xi)
    h, c = st.h[None], st.c[None]  # rows against (6, n) stacks
    x1, x2, d1, d2 = xi[0], xi[1], xd[0], xd[1]
    Omega = 0.5 * h * (x1 + x2) + c * _stacked(_ad(x1, x2))
    Od = 0.5 * h * (d1 + d2) + c * (_stacked(_ad(x1, d2)) - _stacked(_ad(x2, d1)))
    Omega, Od = _kept(Omega), _kept(Od)
    R, p, Ts, Q = _exp_and_tangent(Omega)
    # x = eta_c + T Od, then the twist at the step's end: (R^T x_w, R^T (x_v + x_w x p))
    gT = jnp.transpose(g_core[:, :3], (1, 2, 0))[..., lay.leaf_row]
    eT = eta_core.T[:, lay.leaf_row]
    Tw = _mat_vec(Ts, Od[:3])
    Tv = _add(_mat_vec(Q, Od[:3]), _mat_vec(Ts, Od[3:]))
    x = _kept(_add(list(eT[:3]), Tw) + _add(list(eT[3:]), Tv))
    xv = _add(list(x[3:]), _cross(x[:3], p))
    eta = jnp.stack(_mat_vec(R, x[:3], True) + _mat_vec(R, xv, True), axis=1)
    # world pose: (R_c R, R_c p + p_c); world velocities: R_c x_w, R_c xv
    Rc, pc = gT[:, :3], gT[:, 3]
    cols = [_mat_vec(Rc, R[:, j]) for j in range(3)]
    pw = _add(_mat_vec(Rc, p), list(pc))
    frames = LeafFrames(
        Rc,
        pc,
        _stacked(pw),
        _stacked(_mat_vec(Rc, x[:3])),
        _stacked(_mat_vec(Rc, xv)),
        _stacked(cols[0]),
        p,
        x[:3],
        _stacked(xv),
        R[:, 0],
    )
    zero, unit = jnp.zeros_like(p[0]), jnp.ones_like(p[0])
    g = [[cols[0][i], cols[1][i], cols[2][i], pw[i]] for i in range(3)]
    g = jnp.transpose(_stacked(g + [[zero, zero, zero, unit]]), (2, 0, 1))
    return g, eta, LeafRecord(R, p, Ts, Q, xi), frames


def leaf_wrenches(data, rec: LeafRecord, W, rows=None):
    """The leaves' wrenches at their chain points and their steps' force.

    ``W``: the leaves' body wrenches ``(n, 6)``, or None; ``rows``: wrenches
    already at the chain points (in their frames), component by component ``(6,
    n)`` (the obstacles' contact, :func:`~sorojax.dynamics._contact.
    contact_loads`), or None. Returns ``y = Ad(E)^-T W`` plus ``rows`` (each
    wrench at its step's start, ``(n, 6)``) and the generalised force of the
    leaves' own steps ``sum dOmega^T T^T y`` ``(n_dof,)``, as
    :func:`~sorojax.dynamics._wrench_recursion.leaf_wrenches` forms them.
    """
    st = data.leaf_steps
    if W is None:
        y = _kept(rows)
    else:
        Wt = W.T
        Rf = _mat_vec(rec.R, Wt[3:])
        y = _add(_mat_vec(rec.R, Wt[:3]), _cross(rec.p, Rf)) + Rf
        y = _kept(y if rows is None else _add(y, list(rows)))
    z = _add(_mat_vec(rec.Ts, y[:3], True), _mat_vec(rec.Q, y[3:], True))
    z = _kept(z + _mat_vec(rec.Ts, y[3:], True))
    x1, x2 = rec.xi[0], rec.xi[1]
    h, c = st.h[None], st.c[None]
    Z1 = 0.5 * h * z - c * _stacked(_ad_transpose(x2, z))
    Z2 = 0.5 * h * z + c * _stacked(_ad_transpose(x1, z))
    return y.T, st.compact.transpose((Z1, Z2), data.n_dof)


def leaf_jacobians(data, rec: LeafRecord, J_chain):
    """The leaves' Jacobians ``(n, 6, n_dof)``: ``Ad(E)^-1 (J_c + T dOmega)``.

    ``J_chain``: each leaf's chain point's Jacobian ``(n, 6, n_dof)``. Every
    quantity is a row over the coordinates and the leaves, ``(n_dof, n)``: the
    bases' columns (:meth:`~sorojax.model._precompute.LeafBasis.columns`),
    ``dOmega`` as in :func:`leaf_rates`.
    """
    st = data.leaf_steps
    P1, P2 = st.compact.columns(data.n_dof)  # (6, n_dof, n) at each node
    x1, x2 = rec.xi[0][:, None], rec.xi[1][:, None]  # (6, 1, n) against (n_dof, n)
    h, c = st.h[None, None], st.c[None, None]
    dO = 0.5 * h * (P1 + P2) + c * (_stacked(_ad(x1, P2)) - _stacked(_ad(x2, P1)))
    dO = _kept(dO)
    Ts, Q, R, p = (m[..., None, :] for m in (rec.Ts, rec.Q, rec.R, rec.p))
    Jc = jnp.transpose(J_chain, (1, 2, 0))
    Tw = _mat_vec(Ts, dO[:3])
    Tv = _add(_mat_vec(Q, dO[:3]), _mat_vec(Ts, dO[3:]))
    x = _kept(_add(list(Jc[:3]), Tw) + _add(list(Jc[3:]), Tv))
    xv = _add(list(x[3:]), _cross(x[:3], p))
    J = jnp.stack(_mat_vec(R, x[:3], True) + _mat_vec(R, xv, True))
    return jnp.transpose(J, (2, 0, 1))
