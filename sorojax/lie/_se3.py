"""The rigid-motion group SE(3): poses, twists, adjoints, exponential and logarithm.

Conventions (used throughout sorojax):

* 6-vectors (twists, strains, wrenches) are ANGULAR FIRST,
  ``xi = (wx, wy, wz, vx, vy, vz)``; a wrench is ``(moment, force)``.
* Poses are 4x4 homogeneous matrices ``g = [[R, p], [0, 1]]``.

All functions act on a single element; batch them with ``jax.vmap``.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._so3 import dexp_so3_inv, hat3, log_so3, vee3
from ._utils import so3_coeffs


def make_se3(R: Float[Array, "3 3"], p: Float[Array, 3]) -> Float[Array, "4 4"]:
    """Assemble the homogeneous matrix ``[[R, p], [0, 1]]``.

    Args:
        R: 3x3 rotation matrix.
        p: Translation 3-vector.

    Returns:
        The 4x4 pose matrix.
    """
    R = jnp.asarray(R)
    p = jnp.asarray(p, dtype=R.dtype)
    bottom = jnp.zeros((1, 4), dtype=R.dtype).at[0, 3].set(1.0)
    return jnp.concatenate([jnp.concatenate([R, p[:, None]], axis=1), bottom], axis=0)


def hat(xi: Float[Array, 6]) -> Float[Array, "4 4"]:
    """Map a twist ``(w, v)`` to the se(3) matrix ``[[hat3(w), v], [0, 0]]``.

    Args:
        xi: Twist, angular first.

    Returns:
        The 4x4 se(3) matrix.
    """
    xi = jnp.asarray(xi)
    top = jnp.concatenate([hat3(xi[:3]), xi[3:, None]], axis=1)
    return jnp.concatenate([top, jnp.zeros((1, 4), dtype=top.dtype)], axis=0)


def vee(X: Float[Array, "4 4"]) -> Float[Array, 6]:
    """Inverse of :func:`hat`: ``(vee3(X[:3, :3]), X[:3, 3])``.

    Args:
        X: A 4x4 se(3) matrix.

    Returns:
        The twist, angular first.
    """
    X = jnp.asarray(X)
    return jnp.concatenate([vee3(X[:3, :3]), X[:3, 3]])


def exp_se3(xi: Float[Array, 6]) -> Float[Array, "4 4"]:
    """Exponential map of se(3): ``expm(hat(xi)) = [[exp_so3(w), J(w) v], [0, 1]]``.

    ``J`` is the SO(3) tangent map :func:`~sorojax.lie.dexp_so3`.

    Args:
        xi: Twist ``(w, v)``, angular first.

    Returns:
        The 4x4 pose matrix.
    """
    xi = jnp.asarray(xi)
    w, v = xi[:3], xi[3:]
    W = hat3(w)
    W2 = W @ W
    A, B, C = so3_coeffs(w @ w)
    eye = jnp.eye(3, dtype=W.dtype)
    R = eye + A * W + B * W2
    J = eye + B * W + C * W2
    return make_se3(R, J @ v)


def log_se3(g: Float[Array, "4 4"]) -> Float[Array, 6]:
    """Logarithm map of SE(3), inverse of :func:`exp_se3` for rotation angle <= pi.

    ``w = log_so3(R)`` and ``v = J(w)^{-1} p``.

    Args:
        g: 4x4 pose matrix.

    Returns:
        The twist ``(w, v)``, angular first, with ``|w| <= pi``.
    """
    g = jnp.asarray(g)
    w = log_so3(g[:3, :3])
    v = dexp_so3_inv(w) @ g[:3, 3]
    return jnp.concatenate([w, v])


def inverse_se3(g: Float[Array, "4 4"]) -> Float[Array, "4 4"]:
    """Inverse pose ``[[R^T, -R^T p], [0, 1]]``.

    Args:
        g: 4x4 pose matrix.

    Returns:
        The 4x4 inverse pose.
    """
    g = jnp.asarray(g)
    Rt = g[:3, :3].T
    return make_se3(Rt, -Rt @ g[:3, 3])


def Ad(g: Float[Array, "4 4"]) -> Float[Array, "6 6"]:
    """Adjoint matrix of a pose, angular first: ``[[R, 0], [hat3(p) R, R]]``.

    Satisfies ``Ad(g) @ xi == vee(g @ hat(xi) @ inverse_se3(g))``.

    Args:
        g: 4x4 pose matrix.

    Returns:
        The 6x6 adjoint matrix.
    """
    g = jnp.asarray(g)
    R, p = g[:3, :3], g[:3, 3]
    zero = jnp.zeros_like(R)
    return jnp.block([[R, zero], [hat3(p) @ R, R]])


def Ad_inv(g: Float[Array, "4 4"]) -> Float[Array, "6 6"]:
    """Adjoint of the inverse pose, ``[[R^T, 0], [-R^T hat3(p), R^T]]``.

    Equal to ``Ad(inverse_se3(g))`` and to ``inv(Ad(g))``.

    Args:
        g: 4x4 pose matrix.

    Returns:
        The 6x6 matrix ``Ad(g)^{-1}``.
    """
    g = jnp.asarray(g)
    Rt, p = g[:3, :3].T, g[:3, 3]
    zero = jnp.zeros_like(Rt)
    return jnp.block([[Rt, zero], [-Rt @ hat3(p), Rt]])


def ad(xi: Float[Array, 6]) -> Float[Array, "6 6"]:
    """Adjoint of a twist (Lie bracket matrix): ``[[hat3(w), 0], [hat3(v), hat3(w)]]``.

    Satisfies ``ad(x) @ y == vee(hat(x) @ hat(y) - hat(y) @ hat(x))``.

    Args:
        xi: Twist ``(w, v)``, angular first.

    Returns:
        The 6x6 matrix ``ad(xi)``.
    """
    xi = jnp.asarray(xi)
    W, V = hat3(xi[:3]), hat3(xi[3:])
    return jnp.block([[W, jnp.zeros_like(W)], [V, W]])


def coad(xi: Float[Array, 6]) -> Float[Array, "6 6"]:
    """Co-adjoint of a twist acting on wrenches: ``-ad(xi).T``.

    Equals ``[[hat3(w), hat3(v)], [0, hat3(w)]]`` for wrenches ``(moment, force)``.

    Args:
        xi: Twist ``(w, v)``, angular first.

    Returns:
        The 6x6 matrix ``coad(xi)``.
    """
    xi = jnp.asarray(xi)
    W, V = hat3(xi[:3]), hat3(xi[3:])
    return jnp.block([[W, V], [jnp.zeros_like(W), W]])
