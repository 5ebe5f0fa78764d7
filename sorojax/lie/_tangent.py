"""Tangent operators (differential of the exponential) of SE(3).

The tangent operator of the SE(3) exponential is

``T(Omega) = sum_{k>=0} ad(Omega)^k / (k+1)!``,

so that ``d/de exp(hat(Omega + e d)) |_{e=0} = hat(T(Omega) d) @ exp(hat(Omega))``.
Because the minimal polynomial of ``ad(Omega)`` is ``x (x^2 + t^2)^2`` with
``t^2 = |w|^2``, ``T`` is a polynomial of degree four in ``ad(Omega)`` whose
coefficients are smooth functions of ``t^2`` (see
:func:`sorojax.lie._utils.dexp_se3_coeffs`).

The Geometric Variable-Strain kinematics, which right-multiplies by the
exponential (``g(X + h) = g(X) exp(hat(Omega))``), needs the *right* tangent
operator ``sum_k (-ad)^k/(k+1)! = dexp_se3(-Omega)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._se3 import ad
from ._so3 import dexp_so3_inv
from ._utils import dexp_se3_coeffs


def dexp_se3(xi: Float[Array, 6]) -> Float[Array, "6 6"]:
    """Tangent operator ``T(Omega) = sum_k ad(Omega)^k/(k+1)!`` of SE(3).

    Evaluated as ``I + a1 ad + a2 ad^2 + a3 ad^3 + a4 ad^4`` with

    * ``a1 = (4 - t sin t - 4 cos t)/(2 t^2)``,
    * ``a2 = (4 t - 5 sin t + t cos t)/(2 t^3)``,
    * ``a3 = (2 - t sin t - 2 cos t)/(2 t^4)``,
    * ``a4 = (2 t - 3 sin t + t cos t)/(2 t^5)``,

    each a smooth function of ``t^2 = |w|^2`` (Taylor branch near zero).

    Args:
        xi: Twist ``Omega = (w, v)``, angular first.

    Returns:
        The 6x6 matrix ``T(Omega)``.
    """
    xi = jnp.asarray(xi)
    w = xi[:3]
    a1, a2, a3, a4 = dexp_se3_coeffs(w @ w)
    A = ad(xi)
    A2 = A @ A
    A3 = A2 @ A
    A4 = A2 @ A2
    eye = jnp.eye(6, dtype=A.dtype)
    return eye + a1 * A + a2 * A2 + a3 * A3 + a4 * A4


def dexp_se3_inv(xi: Float[Array, 6]) -> Float[Array, "6 6"]:
    """Inverse of :func:`dexp_se3` in closed block form (valid for ``|w| < 2 pi``).

    ``T = [[J, 0], [Q, J]]`` with ``J = dexp_so3(w)``, hence
    ``T^{-1} = [[J^{-1}, 0], [-J^{-1} Q J^{-1}, J^{-1}]]`` where ``J^{-1}`` is the
    closed form :func:`~sorojax.lie.dexp_so3_inv`.

    Args:
        xi: Twist ``Omega = (w, v)``, angular first.

    Returns:
        The 6x6 matrix ``T(Omega)^{-1}``.
    """
    xi = jnp.asarray(xi)
    Q = dexp_se3(xi)[3:, :3]
    Ji = dexp_so3_inv(xi[:3])
    return jnp.block([[Ji, jnp.zeros_like(Ji)], [-Ji @ Q @ Ji, Ji]])


def dexp_se3_dot(xi: Float[Array, 6], xi_dot: Float[Array, 6]) -> Float[Array, "6 6"]:
    """Time derivative of ``T(Omega(t))`` given ``Omega' = xi_dot``.

    Computed as the forward-mode directional derivative of :func:`dexp_se3`.

    Args:
        xi: Twist ``Omega``, angular first.
        xi_dot: Its time derivative.

    Returns:
        The 6x6 matrix ``d/dt T(Omega(t))``.
    """
    xi = jnp.asarray(xi)
    xi_dot = jnp.asarray(xi_dot, dtype=xi.dtype)
    return jax.jvp(dexp_se3, (xi,), (xi_dot,))[1]
