"""Kernels of one Magnus step: its twist Omega, dOmega, exp(Omega) and T(Omega).

Twist of the 6th-order step (:func:`magnus6`, :func:`magnus6_apply`): between
significant points X_a -> X_a + h, with xi_1, xi_2, xi_3 the strains at the 3-point
Gauss-Legendre nodes X_a + h (1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10), the
moments

    a = h xi_2,  b = sqrt(15) h / 3 (xi_3 - xi_1),  e = 10 h / 3 (xi_3 - 2 xi_2 + xi_1)

give the 6th-order Magnus method with 3 commutators (Blanes, Casas & Ros 2000, BIT 40,
"Improved high order integrators based on the Magnus expansion"; also Blanes, Casas,
Oteo & Ros 2009, Phys. Rep. 470, section 5) for g' = g xi^ (right-invariant: every
commutator of the left-invariant formula has its arguments swapped, [x, y] -> ad(y) x)

    C1 = ad(b) a,   C2 = -1/60 ad(2 e + C1) a,
    Omega = a + e / 12 + 1/240 ad(b + C2) (-20 a - e + C1),

local error O(h^7): the Jacobian columns of modes up to degree 5 are integrated
exactly and higher ones with error O(h^6 |d^6 Phi / dX^6|), where the 4th-order step
(DESIGN.md section 3) leaves O(h^4 |d^4 Phi / dX^4|). dOmega is the exact derivative
of this Omega (so that J is the derivative of the discrete poses and Newton's
Jacobian is consistent), applied to columns (:func:`magnus6_apply`) or transposed
onto wrenches (:func:`magnus6_apply_transpose`) by cross products only.

Fused SE(3) kernel: exp(Omega) and T(Omega) sharing coefficients.

The recursion's inner loop needs, for each step, R and p of exp(Omega) and the tangent
operator T(Omega) = sum_k ad(Omega)^k / (k+1)! (the left Jacobian of SE(3)). Computing
them together from one set of trigonometric coefficients keeps the scan body small,
which is what dominates compile time. Block form (angular first), with W = hat(w),
V = hat(v), theta^2 = |w|^2 (Barfoot 2017, eqs. 7.85-7.86, rewritten angular first):

    R = I + A W + B W^2,   p = Tso3 v,   Tso3 = I + B W + C W^2,
    T = [[Tso3, 0], [Q, Tso3]],
    Q = V/2 + C (W V + V W + W V W) + D (W^2 V + V W^2 - 3 W V W)
        + F (W V W^2 + W^2 V W),

A = sin t / t, B = (1 - cos t)/t^2, C = (t - sin t)/t^3, D = (t^2/2 + cos t - 1)/t^4,
F = (2 t - 3 sin t + t cos t)/(2 t^5). Each coefficient is a smooth function of
theta^2; below a threshold a 7-term Taylor series is used (double-where: closed forms
are evaluated on a safe value), so values, first and second derivatives are exact and
NaN-free at zero. :mod:`sorojax.lie` holds the separate reference kernels; tests check
that both agree.
"""

import functools
import math
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np

from ..lie import hat3

# theta^2 below which Taylor series are used: 10 terms leave < 1e-20 there, and the
# closed forms (with cancellation ~ theta^5 in F) keep 2nd derivatives accurate above.
_SMALL = 1.0
_NTERMS = 10


def _series(first_power: int, sign_offset: int = 0, scale=Fraction(1)) -> tuple:
    """Coefficients c_k of sum_k c_k t^k for sum_k (-1)^k t^k / (first_power + 2k)!."""
    return tuple(
        float(
            scale
            * Fraction((-1) ** (k + sign_offset), math.factorial(first_power + 2 * k))
        )
        for k in range(_NTERMS)
    )


_A = _series(1)  # sin t / t = sum (-1)^k t^2k / (2k+1)!
_B = _series(2)  # (1 - cos t)/t^2
_C = _series(3)  # (t - sin t)/t^3
_D = _series(4)  # (t^2/2 + cos t - 1)/t^4
# (2t - 3 sin t + t cos t)/(2 t^5) = sum_j (-1)^j (j + 1) t^2j / (2j + 5)!
_F = tuple(
    float(Fraction((-1) ** j * (j + 1), math.factorial(2 * j + 5)))
    for j in range(_NTERMS)
)


# Rows: powers of theta^2 (highest last); columns: A, B, C, D, F. One Horner loop on
# the stacked columns keeps the traced program small (same arithmetic per entry).
_SERIES = np.array([_A, _B, _C, _D, _F]).T


@functools.cache
def _series_derivative(k: int) -> np.ndarray:
    """Rows of the k-th derivative (in theta^2) of the stacked series."""
    j = np.arange(_NTERMS)
    scale = np.array([math.perm(int(i), k) for i in j], dtype=float)
    return (_SERIES * scale[:, None])[k:]


@functools.partial(jax.custom_jvp, nondiff_argnums=(1,))
def _series(x, k: int = 0):
    """The k-th derivative of the stacked series at ``x = theta^2`` (Horner).

    Its derivative is the next one's Horner loop (a custom JVP): one loop per order
    of derivative instead of autodiff through the loop, whose tangent recurrence
    (and, in reverse mode, its transpose) is three times the loop's size; the
    coefficients' derivatives are the dynamics' most repeated kernel under ``grad``.
    """
    rows = _series_derivative(k)
    out = jnp.broadcast_to(jnp.asarray(rows[-1], x.dtype), x.shape[:-1] + (5,))
    for row in rows[-2::-1]:
        out = out * x + jnp.asarray(row, x.dtype)
    return out


@_series.defjvp
def _series_jvp(k, primals, tangents):
    (x,), (dx,) = primals, tangents
    return _series(x, k), _series(x, k + 1) * dx


def closed_forms(t, t2, s, c):
    """(A, B, C, D, F) in closed form from ``t``, ``t2 = t^2``, ``sin t``, ``cos t``."""
    return (
        s / t,
        (1.0 - c) / t2,
        (t - s) / (t2 * t),
        (t2 / 2 + c - 1.0) / (t2 * t2),
        (2.0 * t - 3.0 * s + t * c) / (2.0 * t2 * t2 * t),
    )


def coefficients(theta2):
    """(A, B, C, D, F) as smooth functions of theta^2 (see the module docstring)."""
    small = theta2 < _SMALL
    t2 = jnp.where(small, 1.0, theta2)
    t = jnp.sqrt(t2)
    closed = closed_forms(t, t2, jnp.sin(t), jnp.cos(t))
    series = _series(theta2[..., None])
    out = jnp.where(small[..., None], series, jnp.stack(closed, axis=-1))
    return tuple(out[..., i] for i in range(5))


def _outer(a, b):
    return a[:, None] * b[None, :]


def exp_and_tangent(Omega):
    """Rotation, translation of exp(Omega) and the 6x6 tangent operator T(Omega).

    Products of skew matrices are written in closed form (W = hat(w), V = hat(v)):
    W^2 = w w^T - |w|^2 I, W V = v w^T - (w.v) I, W V W = -(w.v) W,
    W^2 V = w (w x v)^T - |w|^2 V, V W^2 = (v x w) w^T - |w|^2 V,
    W V W^2 = W^2 V W = -(w.v) W^2, so the kernel is elementwise arithmetic (no
    matrix products), which XLA fuses into few kernels.

    Args:
        Omega: twist (angular first), shape ``(6,)``.

    Returns:
        ``(R, p, T)`` with shapes ``(3, 3)``, ``(3,)``, ``(6, 6)``.
    """
    w, v = Omega[:3], Omega[3:]
    W, V = hat3(Omega.reshape(2, 3))  # both in one batch
    theta2 = jnp.sum(w * w)
    wv = jnp.sum(w * v)
    eye = jnp.eye(3, dtype=Omega.dtype)
    W2 = _outer(w, w) - theta2 * eye
    A, B, C, D, F = coefficients(theta2)
    R = eye + A * W + B * W2
    Tso3 = eye + B * W + C * W2
    wxv = jnp.cross(w, v)
    p = v + B * wxv + C * (w * wv - theta2 * v)
    WV_VW = _outer(v, w) + _outer(w, v) - 2.0 * wv * eye
    W2V_VW2 = _outer(w, wxv) - _outer(wxv, w) - 2.0 * theta2 * V
    Q = (
        0.5 * V
        + C * (WV_VW - wv * W)
        + D * (W2V_VW2 + 3.0 * wv * W)
        - 2.0 * F * wv * W2
    )
    Z = jnp.zeros((3, 3), dtype=Omega.dtype)
    T = jnp.block([[Tso3, Z], [Q, Tso3]])
    return R, p, T


def tangent_apply(Omega, x):
    """``T(Omega) x`` for a twist ``x`` (both ``(6,)``), without forming T.

    T's blocks applied by cross products (W = hat(w), V = hat(v), x = (a, b)):
    ``Ts a = a + B w x a + C W^2 a`` and ``Q a = v x a / 2 + C (v (w.a) + w (v.a) -
    2 (w.v) a - (w.v) w x a) + D (w ((w x v).a) - (w x v)(w.a) - 2 |w|^2 v x a +
    3 (w.v) w x a) - 2 F (w.v) W^2 a``, ``W^2 a = w (w.a) - |w|^2 a``. Its forward
    derivative along ``dOmega`` is ``(dT/dOmega dOmega) x`` in a few cross
    products, where the derivative of :func:`exp_and_tangent` forms all 36 entries
    of ``dT`` to be read by one product.
    """
    w, v = Omega[:3], Omega[3:]
    a, b = x[:3], x[3:]
    theta2 = jnp.sum(w * w)
    wv = jnp.sum(w * v)
    _, B, C, D, F = coefficients(theta2)
    wa, wb, va, wxv = _crosses([w, w, v, w], [a, b, a, v])
    w_a = jnp.sum(w * a)
    W2a = w * w_a - theta2 * a
    W2b = w * jnp.sum(w * b) - theta2 * b
    Qa = (
        0.5 * va
        + C * (v * w_a + w * jnp.sum(v * a) - 2.0 * wv * a - wv * wa)
        + D * (w * jnp.sum(wxv * a) - wxv * w_a - 2.0 * theta2 * va + 3.0 * wv * wa)
        - 2.0 * F * wv * W2a
    )
    top = a + B * wa + C * W2a
    return jnp.concatenate([top, Qa + b + B * wb + C * W2b])


@jax.custom_jvp
def exp_and_tangent_many(Omega):
    """:func:`exp_and_tangent` of a stack of twists ``(n, 6)``, for many tangents.

    The same values; its derivative first forms the kernel's derivative along the
    6 coordinates of each twist (once, from the primal) and then contracts it with
    the tangents. Under ``jax.jacfwd`` (Newton's tangent in statics: one tangent
    per coordinate) that is one product with the tangents where differentiating the
    kernel itself repeats its coefficients' and its products' derivatives for every
    tangent. For one tangent (a rate) :func:`exp_and_tangent` costs less.
    """
    return jax.vmap(exp_and_tangent)(Omega)


@exp_and_tangent_many.defjvp
def _exp_and_tangent_many_jvp(primals, tangents):
    (Omega,), (dOmega,) = primals, tangents
    many = jax.vmap(exp_and_tangent)
    basis = jnp.broadcast_to(jnp.eye(6, dtype=Omega.dtype)[:, None], (6,) + Omega.shape)
    out, d = jax.vmap(lambda e: jax.jvp(many, (Omega,), (e,)), out_axes=(None, 0))(
        basis
    )
    dout = tuple(jnp.einsum("kn...,nk->n...", x, dOmega) for x in d)
    return out, dout


def _crosses(lhs, rhs):
    """Rows of cross products ``lhs_i x rhs_i``: ``(..., k, 3)`` from two such stacks.

    One ``jnp.cross`` on stacked operands: the same products and differences as k
    separate calls, in about a k-th of the traced program (each call slices every
    component out and stacks them back, and ``ad`` products are the kernels'
    commonest operation; compile time follows the program's size).
    """
    return jnp.cross(jnp.stack(lhs, axis=-2), jnp.stack(rhs, axis=-2))


def _ad_batch(pairs, transpose: bool):
    """``ad(a) b`` (or ``ad(a)^T b``) for every pair, in one batch of crosses.

    With ``a = (w, v)`` and ``b = (x, y)``: ``ad(a) b = (w x x, v x x + w x y)`` and,
    for a wrench ``b = (m, f)``, ``ad(a)^T b = (m x w + f x v, f x w)``. All operands
    are broadcast to one shape.
    """
    parts = [(a[..., :3], a[..., 3:], b[..., :3], b[..., 3:]) for a, b in pairs]
    flat = jnp.broadcast_arrays(*(x for part in parts for x in part))
    lhs, rhs = [], []
    for i in range(len(pairs)):
        w, v, x, y = flat[4 * i : 4 * i + 4]
        lhs += [x, y, y] if transpose else [w, v, w]
        rhs += [w, v, w] if transpose else [x, x, y]
    c = _crosses(lhs, rhs)
    out = []
    for i in range(len(pairs)):
        c0, c1, c2 = c[..., 3 * i, :], c[..., 3 * i + 1, :], c[..., 3 * i + 2, :]
        out.append(jnp.concatenate([c0 + c1, c2] if transpose else [c0, c1 + c2], -1))
    return out


def ad_apply_many(pairs):
    """``[ad(a) b for a, b in pairs]`` for stacks of twists, in one batch of crosses."""
    return _ad_batch(pairs, transpose=False)


def ad_apply(a, b):
    """``ad(a) b`` for stacks of twists (angular first), by cross products."""
    return ad_apply_many([(a, b)])[0]


_SQRT15 = math.sqrt(15.0)


def _moments6(xi, h):
    """The moments ``(a, b, e)`` of the strain over a step from its 3 node values."""
    x1, x2, x3 = xi[..., 0, :], xi[..., 1, :], xi[..., 2, :]
    h = jnp.asarray(h)[..., None]
    a = h * x2
    b = (_SQRT15 / 3.0) * h * (x3 - x1)
    e = (10.0 / 3.0) * h * (x3 - 2.0 * x2 + x1)
    return a, b, e


def _magnus6_terms(xi, h):
    """Omega of the 6th-order step and its terms ``(Omega, a, b, u, v, w)``.

    ``u = 2 e + C1``, ``v = -20 a - e + C1``, ``w = b + C2`` (module docstring).
    """
    a, b, e = _moments6(xi, h)
    C1 = ad_apply(b, a)
    u = 2.0 * e + C1
    C2 = (-1.0 / 60.0) * ad_apply(u, a)
    v = -20.0 * a - e + C1
    w = b + C2
    Omega = a + e / 12.0 + (1.0 / 240.0) * ad_apply(w, v)
    return Omega, a, b, u, v, w


def magnus6(xi, h):
    """Twist Omega of the 6th-order Magnus step (see the module docstring).

    Args:
        xi: strains at the step's 3 Gauss nodes, shape ``(..., 3, 6)`` (angular
            first) [1/m, -].
        h: step length [m], shape ``(...)``.

    Returns:
        Omega, shape ``(..., 6)``: ``g(X_a + h) = g(X_a) exp(Omega^)`` up to O(h^7).
    """
    return _magnus6_terms(xi, h)[0]


def magnus6_apply(xi, h, dxi):
    """Derivative of :func:`magnus6` applied to node perturbations (columns).

    The chain rule on the moments, with ``A_x y = ad(x) y`` by cross products (no
    6 x 6 matrices: elementwise work that XLA fuses):
    ``dC1 = A_b da - A_a db``, ``dC2 = (A_a (2 de + dC1) - A_u da) / 60``,
    ``dOmega = da + de / 12 + (A_w dv - A_v dw) / 240`` with
    ``dv = -20 da - de + dC1``, ``dw = db + dC2``.

    Args:
        xi: strains at the nodes, ``(..., 3, 6)``.
        h: step lengths, ``(...)``.
        dxi: perturbations of the node strains, ``(..., 3, k, 6)`` (k columns).

    Returns:
        ``(..., k, 6)``: dOmega of every column.
    """
    _, a, b, u, v, w = (x[..., None, :] for x in _magnus6_terms(xi, h))
    da, db, de = _moments6(jnp.moveaxis(dxi, -3, -2), jnp.asarray(h)[..., None])
    # independent products in one batch each (same arithmetic, a smaller program)
    bda, adb = ad_apply_many([(b, da), (a, db)])
    dC1 = bda - adb
    a2, uda = ad_apply_many([(a, 2.0 * de + dC1), (u, da)])
    dC2 = (a2 - uda) / 60.0
    dv = -20.0 * da - de + dC1
    dw = db + dC2
    wdv, vdw = ad_apply_many([(w, dv), (v, dw)])
    return da + de / 12.0 + (wdv - vdw) / 240.0


def ad_transpose_apply_many(pairs):
    """``[ad(a)^T z for a, z in pairs]`` (twists a, wrenches z), in one batch."""
    return _ad_batch(pairs, transpose=True)


def ad_transpose_apply(a, z):
    """``ad(a)^T z`` for stacks of twists ``a`` and wrenches ``z`` (moment first)."""
    return ad_transpose_apply_many([(a, z)])[0]


def magnus6_apply_transpose(xi, h, z):
    """``dOmega^T z`` of :func:`magnus6`: the covector of each node, ``(..., 3, 6)``.

    The transpose of :func:`magnus6_apply` (``A_x^T`` by cross products): with
    ``y = z / 240``, ``p_v = A_w^T y``, ``p_w = -A_v^T y``, ``p_u = A_a^T p_w / 60``
    and ``p = p_v + p_u``, the moments' covectors are
    ``g_a = z - 20 p_v - A_u^T p_w / 60 + A_b^T p``, ``g_b = p_w - A_a^T p``,
    ``g_e = z / 12 - p_v + 2 p_u``, and the nodes' follow from
    ``a = h xi_2``, ``b = s (xi_3 - xi_1)``, ``e = t (xi_3 - 2 xi_2 + xi_1)``.

    Args:
        xi: strains at the nodes, ``(..., 3, 6)``.
        h: step lengths, ``(...)``.
        z: wrenches (moment first), ``(..., 6)``.
    """
    _, a, b, u, v, w = _magnus6_terms(xi, h)
    y = z / 240.0
    # independent products in one batch each (same arithmetic, a smaller program)
    p_v, vy = ad_transpose_apply_many([(w, y), (v, y)])
    p_w = -vy
    apw, upw = ad_transpose_apply_many([(a, p_w), (u, p_w)])
    p_u = apw / 60.0
    p = p_v + p_u
    bp, ap = ad_transpose_apply_many([(b, p), (a, p)])
    g_a = z - 20.0 * p_v - upw / 60.0 + bp
    g_b = p_w - ap
    g_e = z / 12.0 - p_v + 2.0 * p_u
    h = jnp.asarray(h)[..., None]
    s = (_SQRT15 / 3.0) * h
    t = (10.0 / 3.0) * h
    return jnp.stack(
        [t * g_e - s * g_b, h * g_a - 2.0 * t * g_e, t * g_e + s * g_b], -2
    )
