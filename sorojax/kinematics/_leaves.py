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
value costing more than what it saves. A stack's rows are each formed whole before
it (``[a[i] + c * b[i] for i in range(6)]``, not ``a + c * stack(b)``): a stack that
further arithmetic reads is a kernel of its own, writing rows another kernel reads
back, where one kernel forms each row in a single pass. A stack's kernel evaluates
each row's expression on its own, so terms shared by its rows are stored before
(the steps' scalars ``k``: ``p`` reads them from their stack).

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

    ``k`` ``(18, n)``: each step's twist ``Omega = (w, v)`` and the scalars of its
    exp and tangent (:func:`_step_rows`), from which :func:`_ts` and :func:`_q`
    apply ``Ts`` and ``Q`` (T(Omega) = [[Ts, 0], [Q, Ts]]) to rows without forming
    them; ``p`` ``(3, n)`` and ``R`` ``(3, 3, n)``: exp(Omega), ``R`` formed
    (:func:`_rot_matrix`) for the leaves' poses, twists and Jacobians and the
    wrenches given on them (XLA drops it where none of those is read); ``xi`` ``(2,
    6, n)``: the strains at the step's Zanna points.
    """

    k: Array
    p: Array
    R: Array
    xi: Array

    @property
    def theta2(self) -> Array:
        """Each step's squared turn ``|w|^2`` ``(n,)``."""
        return self.k[13]


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


def _step_rows(Omega):
    """``(k, p)``: the rows of :class:`LeafRecord` for the steps ``Omega`` ``(6, n)``.

    ``k``: ``w``, ``v``, ``w x v``, the exp's coefficients ``A, B, C, D`` (the same
    closed forms and Taylor series as :func:`~sorojax.kinematics._step.
    exp_and_tangent`, by Horner's rule, each coefficient's own), ``theta^2`` and
    the products of ``Q`` (:func:`_q`) ``0.5 - 2 D theta^2``, ``w.v (3D - C)``,
    ``2 w.v (F theta^2 - C)`` and ``2 F w.v``; ``p`` ``(3, n)``: exp's translation.
    ``Ts`` and ``Q`` are applied from these (each a cross product, two or three dot
    products and a sum of scaled rows) rather than formed: their nine entries each
    cost more than the products they serve. ``R`` is formed from them
    (:func:`_rot_matrix`), read by several products where it is needed. The
    closed forms (a square root, a sine, a cosine and five divisions per step) are
    evaluated only where some step turns by a radian or more (a ``lax.cond``):
    XLA's CPU runs sine and cosine element by element (~9 ns per value and
    function, the largest kernel of a thousand leaves), and short steps take the
    series.
    """
    w, v = Omega[:3], Omega[3:]
    th2 = _dot(w, w)
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
    A, B, C, D, F = coef
    wv = _dot(w, v)
    wxv = _cross(w, v)
    k = _kept(
        list(w) + list(v) + wxv
        + [A, B, C, D, th2, 0.5 - 2.0 * D * th2, wv * (3.0 * D - C),
           2.0 * wv * (F * th2 - C), 2.0 * F * wv]
    )  # fmt: skip
    # p = Ts v (:func:`_ts` with a = v), from the stored rows and their w x v: its
    # kernel evaluates no coefficient's series or cross product again
    w, v, wxv, B, C, th2 = k[0:3], k[3:6], k[6:9], k[10], k[11], k[13]
    wv = _dot(w, v)
    p = [v[i] + B * wxv[i] + C * (w[i] * wv - th2 * v[i]) for i in range(3)]
    return k, _kept(p)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _ts(k, a, transpose: bool = False):
    """``Ts a`` (or ``Ts^T a``), ``Ts = I + B W + C W^2``, for rows ``a``: 3 rows."""
    w, B, C, th2 = k[0:3], k[10], k[11], k[13]
    wa, wxa = _dot(w, a), _cross(w, a)
    sB = -B if transpose else B
    return [a[i] + sB * wxa[i] + C * (w[i] * wa - th2 * a[i]) for i in range(3)]


def _q(k, a, transpose: bool = False):
    """``Q a`` (or ``Q^T a``) for rows ``a``: 3 rows.

    ``Q = V/2 + C (v w^T + w v^T - 2 (w.v) I - (w.v) W) + D (w (w x v)^T - (w x v)
    w^T - 2 theta^2 V) + 3 D (w.v) W - 2 F (w.v) W^2``, applied as
    ``(1/2 - 2 D theta^2) v x a + w.v (3D - C) w x a + C (w.a) v + (C v.a + D (w x
    v).a - 2 F w.v w.a) w - D (w.a) w x v + 2 w.v (F theta^2 - C) a``; its
    transpose turns the signs of the antisymmetric terms (``V``, ``W`` and ``D``'s).
    """
    w, v, wxv, C, D = k[0:3], k[3:6], k[6:9], k[11], k[12]
    al1, al2, beta, tfw = k[14], k[15], k[16], k[17]
    wa, va, xa = _dot(w, a), _dot(v, a), _dot(wxv, a)
    vxa, wxa = _cross(v, a), _cross(w, a)
    if transpose:
        al1, al2, D = -al1, -al2, -D
    sv, sw, sx = C * wa, C * va + D * xa - tfw * wa, D * wa
    return [
        al1 * vxa[i] + al2 * wxa[i] + sv * v[i] + sw * w[i] - sx * wxv[i]
        + beta * a[i]
        for i in range(3)
    ]  # fmt: skip


def _rot_matrix(k):
    """``R``'s entries ``[[R_ij]]`` as rows (the world frames read its columns)."""
    w, A, B, th2 = k[0:3], k[9], k[10], k[13]
    W = [[None, -w[2], w[1]], [w[2], None, -w[0]], [-w[1], w[0], None]]
    return [
        [
            1.0 + B * (w[i] * w[i] - th2) if i == j
            else A * W[i][j] + B * w[i] * w[j]
            for j in range(3)
        ]
        for i in range(3)
    ]  # fmt: skip


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
    h, c = st.h, st.c
    x1, x2, d1, d2 = xi[0], xi[1], xd[0], xd[1]
    a12, a1d, a2d = _ad(x1, x2), _ad(x1, d2), _ad(x2, d1)
    Omega = [0.5 * h * (x1[i] + x2[i]) + c * a12[i] for i in range(6)]
    Od = [0.5 * h * (d1[i] + d2[i]) + c * (a1d[i] - a2d[i]) for i in range(6)]
    Omega, Od = _kept(Omega), _kept(Od)
    k, p = _step_rows(Omega)
    # x = eta_c + T Od; the twist at the step's end: (R^T x_w, R^T (x_v + x_w x p))
    gT = jnp.transpose(g_core[:, :3], (1, 2, 0))[..., lay.leaf_row]
    eT = eta_core.T[:, lay.leaf_row]
    Tw = _ts(k, Od[:3])
    Tv = _add(_q(k, Od[:3]), _ts(k, Od[3:]))
    x = _kept(_add(list(eT[:3]), Tw) + _add(list(eT[3:]), Tv))
    xv = _add(list(x[3:]), _cross(x[:3], p))
    # world pose: (R_c R, R_c p + p_c); world velocities: R_c x_w, R_c xv
    Rc, pc = gT[:, :3], gT[:, 3]
    R = _kept(_rot_matrix(k))  # formed where the poses or twists are read
    eta = jnp.stack(_mat_vec(R, x[:3], True) + _mat_vec(R, xv, True), axis=1)
    cols = [_mat_vec(Rc, [R[i][j] for i in range(3)]) for j in range(3)]
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
        _stacked([R[i][0] for i in range(3)]),
    )
    zero, unit = jnp.zeros_like(p[0]), jnp.ones_like(p[0])
    g = [[cols[0][i], cols[1][i], cols[2][i], pw[i]] for i in range(3)]
    g = jnp.transpose(_stacked(g + [[zero, zero, zero, unit]]), (2, 0, 1))
    return g, eta, LeafRecord(k, p, R, xi), frames


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
    z = _add(_ts(rec.k, y[:3], True), _q(rec.k, y[3:], True))
    z = _kept(z + _ts(rec.k, y[3:], True))
    x1, x2 = rec.xi[0], rec.xi[1]
    h, c = st.h, st.c
    t2, t1 = _ad_transpose(x2, z), _ad_transpose(x1, z)
    Z1 = _stacked([0.5 * h * z[i] - c * t2[i] for i in range(6)])
    Z2 = _stacked([0.5 * h * z[i] + c * t1[i] for i in range(6)])
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
    h, c = st.h[None], st.c[None]  # rows against (n_dof, n)
    a12, a21 = _ad(x1, P2), _ad(x2, P1)
    dO = _kept([0.5 * h * (P1[i] + P2[i]) + c * (a12[i] - a21[i]) for i in range(6)])
    # rows (1, n) against (n_dof, n)
    k, p, R = rec.k[:, None], rec.p[:, None], rec.R[..., None, :]
    Jc = jnp.transpose(J_chain, (1, 2, 0))
    Tw = _ts(k, dO[:3])
    Tv = _add(_q(k, dO[:3]), _ts(k, dO[3:]))
    x = _kept(_add(list(Jc[:3]), Tw) + _add(list(Jc[3:]), Tv))
    xv = _add(list(x[3:]), _cross(x[:3], p))
    J = jnp.stack(_mat_vec(R, x[:3], True) + _mat_vec(R, xv, True))
    return jnp.transpose(J, (2, 0, 1))
