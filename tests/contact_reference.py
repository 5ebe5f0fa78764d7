r"""Reference solution: heavy planar elastica cantilever resting on a rigid floor.

Pure NumPy/SciPy, derived from the mathematics; it imports neither JAX nor sorojax
so that it can serve as an independent oracle for contact tests.

Problem
-------
A planar, inextensible, unshearable (Euler) elastica of length ``L``, bending
stiffness ``EI`` [N m^2] and weight per unit length ``w`` [N/m] is clamped at
``s = 0`` at the point ``(x, z) = (0, d)`` with its tangent along ``+x``. Gravity acts
along ``-z``. A rigid, frictionless floor occupies ``z <= 0``. The rod is long enough
to reach the floor: the part ``s in [0, a)`` hangs freely, touches the floor at the
*touchdown* arc length ``a`` and the part ``s in [a, L]`` lies flat on the floor
(straight, horizontal, zero curvature), carried by a distributed floor reaction
``w`` per unit length equal to its weight. A concentrated upward reaction ``R`` acts
at the touchdown point.

Conventions
-----------
* Right-handed frame: ``x`` forward, ``z`` up, ``y = z x x`` (so ``x x y = z``). The
  rod lives in the ``x``-``z`` plane.
* ``theta(s)``: tangent angle, ``(dx/ds, dz/ds) = (cos theta, sin theta)``; positive
  when the tangent turns from ``+x`` towards ``+z`` (the hanging part has
  ``theta < 0``).
* A moment "about ``+y``" is positive when it rotates ``+z`` towards ``+x``
  (right-hand rule about ``y``). Turning ``+x`` towards ``+z`` is a rotation about
  ``-y``, so the internal bending moment (about ``+y``) that the part ``s+`` exerts on
  the part ``s-`` is ``m_y(s) = -EI theta'(s)``.
* ``n(s) = (n_x, n_z)``: internal force that the part ``s+`` exerts on the part ``s-``.

Equations
---------
Force balance ``n' + f = 0`` with the load per unit length ``f = (0, -w)`` on the
hanging part, ``f = (0, -w + w) = 0`` on the flat part. The floor is frictionless and
the free end ``s = L`` is unloaded, so ``n_x = 0`` everywhere and ``n_z = 0`` on the flat
part. The concentrated reaction ``R`` makes ``n_z`` jump by ``R`` at ``s = a``:
``n_z(a-) = R``. Hence on the hanging part

    n_x(s) = 0,        n_z(s) = R - w (a - s),        0 <= s < a.

Moment balance ``m_y' + (r' x n)_y = 0`` with ``(r' x n)_y = n_x sin theta - n_z cos
theta`` and ``m_y = -EI theta'`` gives

    EI theta''(s) = -n_z(s) cos theta(s) = (w (a - s) - R) cos theta(s),
    x'(s) = cos theta(s),     z'(s) = sin theta(s),

with the five boundary conditions, for three first-order states ``(theta, theta',
z)`` plus the two unknown parameters ``a`` and ``R``::

    theta(0) = 0,   z(0) = d,             (horizontal clamp at height d)
    theta(a) = 0,   theta'(a) = 0,        (horizontal, zero moment at touchdown:
                                           continuity with the flat part)
    z(a) = 0.                             (on the floor)

``x`` follows by quadrature with ``x(0) = 0``. The moment ``EI theta'`` is continuous
at ``s = a`` while the shear force, and so ``theta''``, jumps by ``R / EI``.

Solution method: shooting *backwards from the touchdown point*, where ``theta``,
``theta'`` and ``z`` are all known, in the variable ``u = a - s``; the two unknowns
``(a, R)`` are found with ``scipy.optimize.root`` from the two clamp conditions
``theta(0) = 0`` and ``z(0) = d``. Everything is made dimensionless with the
gravity-bending length ``l = (EI / w)^(1/3)`` and force ``w l``: with ``U = u / l``,
``rho = R / (w l)``, ``D = d / l``, the equation is ``d^2 theta / dU^2 = (U - rho) cos
theta`` on ``U in [0, a / l]``; the solution depends on ``D`` only.

First integral (exact, used as a check): multiplying by ``theta'`` and integrating
over ``[0, a]`` with ``theta = 0`` at both ends and ``n_z' = w`` gives
``EI theta'(0)^2 / 2 = w d``, so the clamp moment is exactly ``-sqrt(2 EI w d)``.

Range: as ``D`` grows the hanging part becomes vertical (``theta -> -pi/2``),
``rho -> 1.2027`` and the upper part is in tension; shooting across it is
exponentially ill-conditioned; beyond ``D = 7.5`` (``a = 8.9 l``) a ``RuntimeError``
is raised. Solutions with a loop (``theta'(0) > 0``) are rejected.

Small-drop (linear) limit
-------------------------
For ``d -> 0``, ``theta = z'`` is small, ``cos theta ~ 1`` and ``EI z'''' = -w``.
With ``u = a - s``, the touchdown conditions ``z = z_u = z_uu = 0`` and
``EI z_uuu(0) = R`` give ``z(u) = (R u^3 / 6 - w u^4 / 24) / EI``. The clamp slope
``z_u(a) = 0`` gives ``R = w a / 3`` and ``z(a) = d`` gives ``w a^4 / (72 EI) = d``::

    a = (72 EI d / w)^(1/4),   R = w a / 3,   F_z = 2 w a / 3,   M_y = -w a^2 / 6.

The neglected terms are of relative order ``theta^2 ~ (d / a)^2``, i.e. ``d^(3/2)``
at fixed ``EI`` and ``w``.

Outputs (see :func:`heavy_cantilever_on_floor`)
-----------------------------------------------
* ``clamp_force = (F_x, F_z) = -n(0) = (0, w a - R)``: force the clamp exerts on the
  rod; ``F_z > 0`` is upward.
* ``clamp_moment = -m_y(0) = EI theta'(0)``: moment about ``+y`` that the clamp
  exerts on the rod (negative for a hanging rod: the clamp turns ``+x`` towards
  ``+z`` to hold the rod up). It balances the loads about the clamp point:
  ``M = R x(a) - w * integral_0^a x(s) ds``.
* ``R >= 0`` upward, ``total_floor_reaction = R + w (L - a)`` upward.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

__all__ = ["heavy_cantilever_on_floor", "linear_touchdown"]

_RTOL = 1e-12
_D_MAX = 7.5  # largest d / l attempted (see "Range" in the module docstring)
_ALPHA_MAX = 12.0  # a / l bound for the root finder (a / l = 8.9 at d / l = 7.5)


def linear_touchdown(EI: float, w: float, d: float) -> float:
    """Small-deflection touchdown arc length of the heavy cantilever on a floor.

    Linear (Euler-Bernoulli, ``cos theta = 1``) solution of the problem described in
    the module docstring: ``a = (72 EI d / w)^(1/4)``; the touchdown reaction is then
    ``R = w a / 3``.

    Args:
        EI: Bending stiffness [N m^2].
        w: Weight per unit length [N/m].
        d: Clamp height above the floor [m].

    Returns:
        The touchdown arc length ``a`` [m].
    """
    return (72.0 * EI * d / w) ** 0.25


def _rhs(tau, y, alpha, rho):
    """Dimensionless ODE in ``tau = U / alpha`` (``U = (a - s) / l``), see module.

    States: ``theta``, ``q = d theta / dU``, ``X = (x(a) - x(s)) / l``, ``Z = z / l``.
    """
    theta, q = y[0], y[1]
    c, s = math.cos(theta), math.sin(theta)
    U = alpha * tau
    return [alpha * q, alpha * (U - rho) * c, alpha * c, -alpha * s]


def _shoot(alpha, rho, D, dense=False):
    """Integrate from touchdown (``tau = 0``) to the clamp (``tau = 1``)."""
    return solve_ivp(
        _rhs,
        (0.0, 1.0),
        [0.0, 0.0, 0.0, 0.0],
        method="DOP853",
        args=(alpha, rho),
        rtol=_RTOL,
        atol=1e-15 * min(1.0, D),
        dense_output=dense,
        # At least 20 steps: with few steps the error estimate of this (nearly
        # polynomial, for small D) solution is optimistic and the residual becomes
        # non-smooth in (alpha, rho) at the 1e-9 level, which stalls the root finder.
        max_step=0.05,
    )


def _residual(p, D):
    alpha, rho = p
    if not 0.0 < alpha < _ALPHA_MAX:  # keep the root finder on 0 < a < 12 l
        return [1.0 + abs(alpha), 1.0]
    sol = _shoot(alpha, rho, D)
    theta0, Z0 = sol.y[0, -1], sol.y[3, -1]
    # Both residuals are O(D) near the solution; scale them to O(1).
    return [theta0 / D, (Z0 - D) / D]


def _solve_root(D, guess):
    sol = root(_residual, guess, args=(D,), method="hybr", options={"xtol": 1e-13})
    # Judge by the residual: near machine precision hybr may stop with "xtol is too
    # small" although the residual is already at the ODE tolerance level.
    ok = bool(np.max(np.abs(sol.fun)) < 1e-10 and sol.x[0] > 0.0)
    if ok:
        # Physical branch only: the clamp holds the rod up (theta'(0) < 0, i.e.
        # q > 0 at the clamp) and the hanging part does not loop (-pi < theta <= 0).
        # A far-off guess can converge to a looped shape with theta'(0) > 0.
        y = _shoot(sol.x[0], sol.x[1], D).y
        ok = bool(y[1, -1] > 0.0 and np.all(y[0] > -np.pi) and np.all(y[0] < 1e-9))
    return ok, sol.x


def _solve_dimensionless(D):
    """Return ``(alpha, rho) = (a / l, R / (w l))`` for ``D = d / l``."""
    if D > _D_MAX:
        raise RuntimeError(
            f"heavy_cantilever_on_floor: d/l = {D:.6g} > {_D_MAX} with l = "
            "(EI/w)^(1/3): shooting over the long, nearly vertical tension zone is "
            "ill-conditioned there (outside this reference's range)"
        )
    alpha0 = (72.0 * D) ** 0.25
    ok, p = _solve_root(D, [alpha0, alpha0 / 3.0])
    if ok:
        return p
    # Continuation in D from the linear regime (log-spaced steps).
    D_start = min(D, 1e-2)
    alpha = (72.0 * D_start) ** 0.25
    p = np.array([alpha, alpha / 3.0])
    for Dk in np.geomspace(D_start, D, 60):
        ok, pk = _solve_root(Dk, p)
        if not ok:
            raise RuntimeError(
                f"heavy_cantilever_on_floor: shooting failed at d/l = {Dk:.6g} "
                f"(target {D:.6g}, l = (EI/w)^(1/3)); shooting over the long, "
                "nearly vertical tension zone is reliable up to d/l ~ 7.5 only"
            )
        p = pk
    return p


def heavy_cantilever_on_floor(
    L: float, EI: float, w: float, d: float, n: int = 201
) -> dict:
    """Heavy elastica cantilever clamped horizontally at height ``d`` above a floor.

    Solves the nonlinear boundary-value problem of the module docstring (shooting
    from the touchdown point, tolerances ``1e-12``) for the suspended part and
    appends the flat part lying on the floor.

    Args:
        L: Rod length [m].
        EI: Bending stiffness [N m^2].
        w: Weight per unit length [N/m], gravity along ``-z``.
        d: Height of the clamp above the floor [m], ``> 0``.
        n: Number of sample points over ``[0, L]`` (``>= 2``).

    Returns:
        A dict with

        * ``"a"``: touchdown arc length [m].
        * ``"R"``: concentrated upward floor reaction at touchdown [N], ``>= 0``.
        * ``"clamp_force"``: ``np.array([F_x, F_z])`` [N], force the clamp exerts on
          the rod (``F_x = 0`` on a frictionless floor, ``F_z = w a - R > 0``
          upward).
        * ``"clamp_moment"``: moment about ``+y`` [N m] that the clamp exerts on
          the rod, ``EI theta'(0)``; positive rotates ``+z`` towards ``+x`` (frame
          ``x`` forward, ``z`` up, ``y = z x x``); negative here.
        * ``"s"``: ``n`` arc lengths ``linspace(0, L, n)`` [m].
        * ``"x"``, ``"z"``: centre-line coordinates at ``s`` [m], clamp at
          ``(0, d)``, flat part included (``z = 0`` there).
        * ``"theta"``: tangent angle at ``s`` [rad], positive from ``+x`` towards
          ``+z``.
        * ``"total_floor_reaction"``: ``R + w (L - a)`` [N], upward.

    Raises:
        ValueError: If ``d <= 0``, a parameter is not positive, ``n < 2``, or the
            rod is too short to lie on the floor (``L < a``).
        RuntimeError: If ``d / l > 7.5`` with ``l = (EI / w)^(1/3)`` (outside the
            range where the shooting is well conditioned) or it does not converge.
    """
    if not d > 0.0:
        raise ValueError(f"clamp height d must be > 0 (the floor is z = 0), got {d}")
    for name, val in (("L", L), ("EI", EI), ("w", w)):
        if not val > 0.0:
            raise ValueError(f"{name} must be > 0, got {val}")
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n}")

    ell = (EI / w) ** (1.0 / 3.0)
    D = d / ell
    alpha, rho = _solve_dimensionless(D)
    a, R = alpha * ell, rho * w * ell
    if a > L:
        raise ValueError(
            f"rod too short to lie on the floor: touchdown needs a = {a:.6g} m > "
            f"L = {L:.6g} m (this reference covers a flat part on the floor only)"
        )
    if R < 0.0:
        raise ValueError(f"inconsistent contact: touchdown reaction R = {R:.6g} < 0")

    sol = _shoot(alpha, rho, D, dense=True)
    X_clamp = sol.y[2, -1]
    q_clamp = sol.y[1, -1]

    s = np.linspace(0.0, L, n)
    hang = s < a
    tau = np.clip((a - s[hang]) / a, 0.0, 1.0)
    Y = sol.sol(tau)
    x = s - a + ell * X_clamp  # flat part: x(a) + (s - a), x(a) = l X(alpha)
    z = np.zeros(n)
    theta = np.zeros(n)
    x[hang] = ell * (X_clamp - Y[2])
    z[hang] = ell * Y[3]
    theta[hang] = Y[0]
    if np.any(z[hang] < -1e-9 * max(d, ell)):
        raise ValueError("suspended part penetrates the floor: no valid solution")

    # theta_s = d theta / ds = -q / l; clamp moment about +y = EI theta_s(0).
    clamp_moment = -EI * q_clamp / ell
    return {
        "a": a,
        "R": R,
        "clamp_force": np.array([0.0, w * a - R]),
        "clamp_moment": clamp_moment,
        "s": s,
        "x": x,
        "z": z,
        "theta": theta,
        "total_floor_reaction": R + w * (L - a),
    }


def equivalent_touchdown(
    force_z: np.ndarray, x: np.ndarray, w: float, L: float, x_tip: float
) -> float:
    """Arc length of the touchdown point of a rigid floor with the same reaction.

    A penalty or barrier floor spreads the touchdown reaction over a zone; a rigid
    floor puts a point reaction R at the touchdown point (arc length a) and carries
    w per length on the flat part from there to the tip. Given the floor's vertical
    contact forces ``force_z`` at horizontal positions ``x``, their resultant
    F = R + w u and moment M = F x_tip - u (F - w u / 2) about x = 0 (u = L - a, the
    flat length, ``x_tip`` the tip's horizontal position) give u as the smaller
    root of ``w u^2 / 2 - F u + F x_tip - M = 0``.
    """
    F = float(np.sum(force_z))
    M = float(np.sum(force_z * x))
    u = (F - math.sqrt(F * F - 2.0 * w * (F * x_tip - M))) / w
    return L - u
