"""Fused SE(3) kernel for one Magnus step: exp(Omega) and T(Omega) sharing coefficients.

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

import math
from fractions import Fraction

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


def coefficients(theta2):
    """(A, B, C, D, F) as smooth functions of theta^2 (see the module docstring)."""
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
    x = theta2[..., None]
    series = jnp.broadcast_to(
        jnp.asarray(_SERIES[-1], theta2.dtype), x.shape[:-1] + (5,)
    )
    for row in _SERIES[-2::-1]:
        series = series * x + jnp.asarray(row, theta2.dtype)
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
    W = hat3(w)
    V = hat3(v)
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
