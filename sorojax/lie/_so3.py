"""The rotation group SO(3): hat/vee, exponential, logarithm and tangent map.

All functions act on a single element (a 3-vector or a 3x3 matrix); batch them
with ``jax.vmap``. Every coefficient is evaluated as a smooth function of
``theta2 = |w|^2`` (see :mod:`sorojax.lie._utils`), so values, first and second
derivatives are finite at the identity and accurate in float32 and float64.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._utils import (
    ATAN_OVER_X_COEFFS,
    get_log_epsilon,
    half_cot_t2,
    horner,
    so3_coeffs,
)


def hat3(w: Float[Array, "... 3"]) -> Float[Array, "... 3 3"]:
    """Map 3-vectors to skew-symmetric matrices, ``hat3(w) @ x = cross(w, x)``.

    Args:
        w: A 3-vector, or a stack of them ``(..., 3)`` (one batch of operations for
            the stack, where a loop or ``vmap`` over calls traces them per call).

    Returns:
        The 3x3 skew-symmetric matrix of ``w``, ``(..., 3, 3)``.
    """
    w = jnp.asarray(w)
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    zero = jnp.zeros_like(w0)
    return jnp.stack(
        [
            jnp.stack([zero, -w2, w1], axis=-1),
            jnp.stack([w2, zero, -w0], axis=-1),
            jnp.stack([-w1, w0, zero], axis=-1),
        ],
        axis=-2,
    )


def vee3(W: Float[Array, "3 3"]) -> Float[Array, 3]:
    """Inverse of :func:`hat3`: extract ``(W[2,1], W[0,2], W[1,0])``.

    Args:
        W: A 3x3 (skew-symmetric) matrix.

    Returns:
        The 3-vector ``w`` with ``hat3(w) == W`` for skew-symmetric ``W``.
    """
    W = jnp.asarray(W)
    return jnp.stack([W[2, 1], W[0, 2], W[1, 0]])


def exp_so3(w: Float[Array, 3]) -> Float[Array, "3 3"]:
    """Exponential map of so(3) (Rodrigues' formula).

    ``R = I + sin(t)/t W + (1 - cos t)/t^2 W^2`` with ``W = hat3(w)``,
    ``t = |w|``.

    Args:
        w: Rotation vector (axis times angle).

    Returns:
        The 3x3 rotation matrix ``expm(hat3(w))``.
    """
    w = jnp.asarray(w)
    W = hat3(w)
    theta2 = w @ w
    A, B, _ = so3_coeffs(theta2)
    eye = jnp.eye(3, dtype=W.dtype)
    return eye + A * W + B * (W @ W)


def log_so3(R: Float[Array, "3 3"]) -> Float[Array, 3]:
    """Logarithm map of SO(3), returning a rotation vector with angle in [0, pi].

    Three branches, combined with the double-where trick:

    * ``cos t >= 0`` and ``tan^2 t`` small: ``w = (arctan(x)/x) / cos(t) a``
      with the Taylor series of ``arctan(x)/x`` in ``x^2 = s^2/cos(t)^2``,
      where ``a = vee3(R - R^T)/2 = sin(t) n`` and ``s = |a|`` (this is the
      same function of ``R`` as the next branch, so derivatives also agree
      off the rotation manifold);
    * ``cos t >= 0`` otherwise: ``w = atan2(s, cos t)/s a`` with ``s = |a|``;
    * ``cos t < 0`` (angle beyond pi/2, including near and at pi): the axis is
      read from the symmetric part ``(R + R^T)/2 = cos t I + (1 - cos t) n n^T``
      using its column with the largest diagonal element, and the signed angle
      is ``atan2(n . a, cos t)``, which fixes the sign of the axis smoothly.

    At exactly ``pi`` either of the two valid answers ``+-pi n`` is returned.

    Derivatives along rotations are continuous everywhere below pi. Derivatives
    with respect to raw matrix entries in directions *off* the rotation manifold
    (non-orthogonal perturbations) differ between the ``cos t >= 0`` and
    ``cos t < 0`` branches, which extend log differently to general matrices.

    Args:
        R: A 3x3 rotation matrix.

    Returns:
        The rotation vector ``w`` with ``exp_so3(w) == R`` and ``|w| <= pi``.
    """
    R = jnp.asarray(R)
    dtype = R.dtype
    a = 0.5 * vee3(R - R.T)
    s2 = a @ a
    c = 0.5 * (jnp.trace(R) - 1.0)
    one = jnp.ones_like(s2)

    near_pi = c < 0.0
    # Both front branches evaluate the same function atan2(s, c) / s for c > 0:
    # the small one as (1/c) * arctan(x)/x with x^2 = s^2 / c^2 = tan(t)^2.
    c_safe = jnp.where(near_pi, one, c)
    tan2 = s2 / (c_safe * c_safe)
    small = jnp.logical_and(~near_pi, tan2 < get_log_epsilon(dtype))
    regular = jnp.logical_and(~near_pi, ~small)

    # Branches with cos(t) >= 0: w = (t / sin t) a.
    s = jnp.sqrt(jnp.where(regular, s2, one))
    ratio_regular = jnp.arctan2(s, c) / s
    ratio_small = horner(ATAN_OVER_X_COEFFS, tan2) / c_safe
    w_front = jnp.where(small, ratio_small, ratio_regular) * a

    # Branch with cos(t) < 0: axis from the symmetric part.
    S = 0.5 * (R + R.T)
    j = jnp.argmax(jnp.diagonal(S))
    e_j = jnp.eye(3, dtype=dtype)[j]
    v = S[:, j] - c * e_j
    vv = v @ v
    n = v / jnp.sqrt(jnp.where(near_pi, vv, one))
    theta_signed = jnp.arctan2(n @ a, c)
    w_back = theta_signed * n

    return jnp.where(near_pi, w_back, w_front)


def dexp_so3(w: Float[Array, 3]) -> Float[Array, "3 3"]:
    """Tangent map (left Jacobian) of the SO(3) exponential.

    ``J(w) = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2 = sum_k W^k/(k+1)!``,
    so that ``d/de exp(hat3(w + e d)) = hat3(J(w) d) exp(hat3(w))`` at ``e = 0``.

    Args:
        w: Rotation vector.

    Returns:
        The 3x3 matrix ``J(w)``.
    """
    w = jnp.asarray(w)
    W = hat3(w)
    theta2 = w @ w
    _, B, C = so3_coeffs(theta2)
    eye = jnp.eye(3, dtype=W.dtype)
    return eye + B * W + C * (W @ W)


def dexp_so3_inv(w: Float[Array, 3]) -> Float[Array, "3 3"]:
    """Inverse of :func:`dexp_so3` in closed form (valid for ``|w| < 2 pi``).

    ``J(w)^{-1} = I - W/2 + (1 - (t/2) cot(t/2))/t^2 W^2``.

    Args:
        w: Rotation vector.

    Returns:
        The 3x3 matrix ``J(w)^{-1}``.
    """
    w = jnp.asarray(w)
    W = hat3(w)
    theta2 = w @ w
    eye = jnp.eye(3, dtype=W.dtype)
    return eye - 0.5 * W + half_cot_t2(theta2) * (W @ W)
