"""Numerical helpers shared by the Lie-group routines of :mod:`sorojax.lie`.

Every trigonometric coefficient that appears in the exponential, logarithm and
tangent operators of SO(3) and SE(3) is an analytic (even) function of the
rotation angle ``theta``, i.e. an entire or at least smooth function of
``theta2 = theta**2``. This module evaluates such coefficients without ever
differentiating through ``theta = sqrt(theta2)`` at ``theta2 = 0``:

* for ``theta2 < get_epsilon(dtype)`` a Taylor polynomial in ``theta2`` with
  ``NUM_TAYLOR_TERMS`` terms is used (exact rational coefficients, derived
  below from the general term of each series);
* otherwise the closed form is evaluated on a *safe* copy of ``theta2`` (the
  "double-where" trick), so that the branch that is not selected never produces
  ``inf``/``nan`` values or cotangents.

The switching threshold is deliberately large (order one) and the polynomials
are long: the truncation error is then far below the dtype roundoff, while the
closed forms, which suffer from cancellation for small ``theta``, are only used
where that cancellation is harmless even for second derivatives.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from fractions import Fraction

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

NUM_TAYLOR_TERMS = 16
"""Number of terms (powers ``theta2**0 .. theta2**15``) of every Taylor branch."""


def get_epsilon(dtype) -> float:
    """Return the small-angle switching threshold on ``theta**2`` for a dtype.

    Below this value of ``theta2 = |w|^2`` the Taylor branches are used. The
    value balances the truncation error of the ``NUM_TAYLOR_TERMS``-term Taylor
    polynomials (negligible at this size) against the cancellation error of the
    closed forms and of their first and second derivatives (which grows like
    ``eps_machine / theta2**k`` as ``theta2 -> 0``).

    Args:
        dtype: A floating point dtype (anything accepted by ``jnp.dtype``).

    Returns:
        The threshold as a Python float: ``2.0`` for 64-bit floats and ``4.0``
        for 32-bit and lower precision floats (i.e. the Taylor branch covers
        angles up to about 1.4 rad resp. 2 rad). With 16 Taylor terms the
        truncation error there is below 1e-13 (relative, up to second
        derivatives), while closed-form second derivatives at the switch are
        accurate to about 1e-12 (float64) resp. 1e-5 (float32).
    """
    dtype = jnp.dtype(dtype)
    if not jnp.issubdtype(dtype, jnp.floating):
        dtype = jnp.dtype(jnp.result_type(float))
    if jnp.finfo(dtype).bits >= 64:
        return 2.0
    return 4.0


def get_log_epsilon(dtype) -> float:
    """Return the small-angle threshold on ``tan(theta)**2`` used by ``log_so3``.

    The Taylor series of ``arctan(x)/x`` in ``x**2`` converges slowly near
    ``x = 1``, hence a smaller threshold than :func:`get_epsilon`.

    Args:
        dtype: A floating point dtype.

    Returns:
        ``0.05`` for 64-bit floats and ``0.1`` otherwise.
    """
    dtype = jnp.dtype(dtype)
    if not jnp.issubdtype(dtype, jnp.floating):
        dtype = jnp.dtype(jnp.result_type(float))
    if jnp.finfo(dtype).bits >= 64:
        return 0.05
    return 0.1


def horner(
    coeffs: Sequence[Sequence[float]] | Sequence[float], x: Float[Array, ""]
) -> Float[Array, "*k"]:
    """Evaluate one or several polynomials in a scalar with Horner's scheme.

    Args:
        coeffs: Coefficients lowest order first, either a sequence of floats
            (one polynomial) or a sequence of length-``k`` rows (``k``
            polynomials evaluated together as a vector).
        x: Scalar evaluation point.

    Returns:
        The polynomial value(s), with the dtype of ``x``.
    """
    x = jnp.asarray(x)
    table = np.asarray(coeffs, dtype=np.float64)
    acc = jnp.asarray(table[-1], dtype=x.dtype)
    for row in table[-2::-1]:
        acc = acc * x + jnp.asarray(row, dtype=x.dtype)
    return acc


def series_or_closed_form(
    theta2: Float[Array, ""],
    coeffs: Sequence[Sequence[float]] | Sequence[float],
    closed_form: Callable[[Float[Array, ""]], Float[Array, "*k"]],
    threshold: float | None = None,
) -> Float[Array, "*k"]:
    """Evaluate smooth function(s) of ``theta2`` with the double-where trick.

    Args:
        theta2: The squared angle (non-negative scalar).
        coeffs: Taylor coefficients in powers of ``theta2`` (lowest first), in
            the layout accepted by :func:`horner`.
        closed_form: Closed form(s), valid for ``theta2 > 0``, returning an
            array of the same shape as the Horner result.
        threshold: Switching threshold; defaults to ``get_epsilon(dtype)``.

    Returns:
        The Taylor polynomial(s) for ``theta2 < threshold`` and the closed
        form(s) otherwise; both branches have finite values and derivatives.
    """
    theta2 = jnp.asarray(theta2)
    if threshold is None:
        threshold = get_epsilon(theta2.dtype)
    small = theta2 < threshold
    safe_theta2 = jnp.where(small, jnp.ones_like(theta2), theta2)
    return jnp.where(small, horner(coeffs, theta2), closed_form(safe_theta2))


# ---------------------------------------------------------------------------
# Exact Taylor coefficients (general terms derived by hand, see comments).
# ---------------------------------------------------------------------------


def _bernoulli(n_max: int) -> list[Fraction]:
    """Bernoulli numbers B_0..B_n_max from ``sum_{k<=m} C(m+1, k) B_k = 0``."""
    b = [Fraction(1)]
    for m in range(1, n_max + 1):
        acc = sum(Fraction(math.comb(m + 1, k)) * b[k] for k in range(m))
        b.append(-acc / (m + 1))
    return b


def _coeffs(term: Callable[[int], Fraction]) -> tuple[float, ...]:
    return tuple(float(term(n)) for n in range(NUM_TAYLOR_TERMS))


def _f(n: int) -> Fraction:
    return Fraction(math.factorial(n))


def _table(*columns: tuple[float, ...]) -> tuple[tuple[float, ...], ...]:
    """Stack coefficient sequences as rows ``(c_n of f_1, ..., c_n of f_k)``."""
    return tuple(zip(*columns, strict=True))


_BERNOULLI = _bernoulli(2 * NUM_TAYLOR_TERMS + 2)

# sin(t)/t = sum (-1)^n t2^n / (2n+1)!
SINC_COEFFS = _coeffs(lambda n: (-1) ** n / _f(2 * n + 1))
# (1 - cos t)/t^2 = sum (-1)^n t2^n / (2n+2)!
ONE_MINUS_COS_COEFFS = _coeffs(lambda n: (-1) ** n / _f(2 * n + 2))
# (t - sin t)/t^3 = sum (-1)^n t2^n / (2n+3)!
T_MINUS_SIN_COEFFS = _coeffs(lambda n: (-1) ** n / _f(2 * n + 3))
# (1 - (t/2) cot(t/2))/t^2 = sum |B_{2n+2}| t2^n / (2n+2)!
HALF_COT_COEFFS = _coeffs(lambda n: abs(_BERNOULLI[2 * n + 2]) / _f(2 * n + 2))
# arctan(x)/x in y = x^2: sum (-1)^n y^n / (2n+1)
ATAN_OVER_X_COEFFS = _coeffs(lambda n: Fraction((-1) ** n, 2 * n + 1))
# SE(3) dexp coefficients (see sorojax.lie._tangent.dexp_se3):
# a1 = (4 - t sin t - 4 cos t)/(2 t^2)   = sum (-1)^n (1 - n) t2^n / (2n+2)!
# a2 = (4 t - 5 sin t + t cos t)/(2 t^3) = sum (-1)^n (1 - n) t2^n / (2n+3)!
# a3 = (2 - t sin t - 2 cos t)/(2 t^4)   = sum (-1)^n (n + 1) t2^n / (2n+4)!
# a4 = (2 t - 3 sin t + t cos t)/(2 t^5) = sum (-1)^n (n + 1) t2^n / (2n+5)!
DEXP_A1_COEFFS = _coeffs(lambda n: (-1) ** n * Fraction(1 - n) / _f(2 * n + 2))
DEXP_A2_COEFFS = _coeffs(lambda n: (-1) ** n * Fraction(1 - n) / _f(2 * n + 3))
DEXP_A3_COEFFS = _coeffs(lambda n: (-1) ** n * Fraction(n + 1) / _f(2 * n + 4))
DEXP_A4_COEFFS = _coeffs(lambda n: (-1) ** n * Fraction(n + 1) / _f(2 * n + 5))

_SO3_TABLE = _table(SINC_COEFFS, ONE_MINUS_COS_COEFFS, T_MINUS_SIN_COEFFS)
_DEXP_SE3_TABLE = _table(DEXP_A1_COEFFS, DEXP_A2_COEFFS, DEXP_A3_COEFFS, DEXP_A4_COEFFS)


# ---------------------------------------------------------------------------
# Coefficient functions of theta2 (all smooth, NaN-free derivatives).
# ---------------------------------------------------------------------------


def so3_coeffs(theta2: Float[Array, ""]) -> tuple[Array, Array, Array]:
    """Return ``(sin t/t, (1 - cos t)/t^2, (t - sin t)/t^3)`` for ``t^2 = theta2``.

    These are the coefficients of Rodrigues' formula and of the SO(3) tangent
    map. ``1 - cos t`` is evaluated as ``2 sin(t/2)^2`` (no cancellation).

    Args:
        theta2: Squared rotation angle.

    Returns:
        The three coefficients as scalars.
    """

    def closed(x):
        t = jnp.sqrt(x)
        s = jnp.sin(t)
        one_minus_c = 2.0 * jnp.sin(0.5 * t) ** 2
        return jnp.stack([s / t, one_minus_c / x, (t - s) / (t * x)])

    out = series_or_closed_form(theta2, _SO3_TABLE, closed)
    return out[0], out[1], out[2]


def half_cot_t2(theta2: Float[Array, ""]) -> Float[Array, ""]:
    """Return ``(1 - (t/2) cot(t/2))/t^2``, finite for ``t < 2 pi``.

    Args:
        theta2: Squared rotation angle.

    Returns:
        The coefficient of ``W^2`` in the inverse SO(3) tangent map.
    """

    def closed(x):
        h = 0.5 * jnp.sqrt(x)
        return (1.0 - h * jnp.cos(h) / jnp.sin(h)) / x

    return series_or_closed_form(theta2, HALF_COT_COEFFS, closed)


def dexp_se3_coeffs(
    theta2: Float[Array, ""],
) -> tuple[Array, Array, Array, Array]:
    """Return the coefficients ``(a1, a2, a3, a4)`` of the SE(3) tangent map.

    ``T(Omega) = I + a1 ad + a2 ad^2 + a3 ad^3 + a4 ad^4`` with ``ad = ad(Omega)``
    and ``theta2 = |w|^2`` (``w`` the angular part of ``Omega``).

    Args:
        theta2: Squared rotation angle.

    Returns:
        The four coefficients as scalars.
    """

    def closed(x):
        t = jnp.sqrt(x)
        s, c = jnp.sin(t), jnp.cos(t)
        one_minus_c = 2.0 * jnp.sin(0.5 * t) ** 2
        ts = t * s
        return jnp.stack(
            [
                (4.0 * one_minus_c - ts) / (2.0 * x),
                (4.0 * t - 5.0 * s + t * c) / (2.0 * x * t),
                (2.0 * one_minus_c - ts) / (2.0 * x * x),
                (2.0 * t - 3.0 * s + t * c) / (2.0 * x * x * t),
            ]
        )

    out = series_or_closed_form(theta2, _DEXP_SE3_TABLE, closed)
    return out[0], out[1], out[2], out[3]
