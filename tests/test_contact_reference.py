"""Self-validation of ``contact_reference.py`` (heavy cantilever lying on a floor).

The reference shoots from the touchdown point (``scipy.integrate.solve_ivp``, rtol
1e-12). It is checked here against: the small-drop closed form (with the convergence
order the theory predicts), exact global force and moment balance computed from its
sampled shape, an exact first integral of the elastica, and an independent
``scipy.integrate.solve_bvp`` formulation in the arc length with ``a`` and ``R`` as
unknown parameters. Each tolerance states its reason.
"""

import math
import os
import sys

import numpy as np
import pytest
from scipy.integrate import simpson, solve_bvp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from contact_reference import (  # noqa: E402
    heavy_cantilever_on_floor,
    linear_touchdown,
)

L, EI, W = 1.0, 0.05, 1.0  # l = (EI/w)^(1/3) = 0.368 m
ELL = (EI / W) ** (1.0 / 3.0)


def test_linear_closed_form_satisfies_the_linear_bvp():
    # Linear problem, u = a - s: EI z'''' = -w, z = z_u = z_uu = 0 and EI z_uuu = R at
    # u = 0 give z(u) = (R u^3/6 - w u^4/24)/EI; check that a = (72 EI d/w)^(1/4),
    # R = w a/3 meet the clamp conditions z(a) = d, z_u(a) = 0 (rounding only).
    d = 0.01
    a = linear_touchdown(EI, W, d)
    R = W * a / 3.0
    assert a == pytest.approx((72.0 * EI * d / W) ** 0.25, rel=1e-15)
    z = (R * a**3 / 6.0 - W * a**4 / 24.0) / EI
    z_u = (R * a**2 / 2.0 - W * a**3 / 6.0) / EI
    assert z == pytest.approx(d, rel=1e-13)
    assert abs(z_u) < 1e-13 * W * a**3 / EI


def test_touchdown_converges_to_linear_form_at_order_three_halves():
    # Neglected terms are O(theta^2) ~ O((d/a)^2) ~ d^(3/2) (a ~ d^(1/4)): the
    # relative error of a must fall by 10^1.5 = 31.6 per decade of d. Measured:
    # 1.36e-4, 4.29e-6, 1.36e-7 at d/L = 1e-2, 1e-3, 1e-4; bounds with ~2x margin.
    ds = [1e-2, 1e-3, 1e-4]
    err = []
    for d in ds:
        a = heavy_cantilever_on_floor(L, EI, W, d)["a"]
        err.append(abs(a / linear_touchdown(EI, W, d) - 1.0))
    assert err[0] < 3e-4
    assert err[1] < 1e-5
    assert err[2] < 3e-7
    orders = np.diff(np.log10(err)) / np.diff(np.log10(ds))
    # d^(3/2) within +-0.05: the next correction is another factor (d/a)^2 smaller
    # and the solver error (~1e-12) is five decades below the smallest error.
    assert np.all(np.abs(orders - 1.5) < 0.05), orders


def test_linear_reaction_clamp_force_and_moment_in_small_drop_limit():
    # Linear solution: R = w a/3, F_z = w a - R = 2 w a/3, M_y = -w a^2/6. Relative
    # deviations are O(d^(3/2)) like a's: measured 1.5e-8 for R at d/L = 1e-4.
    d = 1e-4
    a_lin = linear_touchdown(EI, W, d)
    res = heavy_cantilever_on_floor(L, EI, W, d)
    assert res["R"] == pytest.approx(W * a_lin / 3.0, rel=1e-6)
    assert res["clamp_force"][1] == pytest.approx(2.0 * W * a_lin / 3.0, rel=1e-6)
    assert res["clamp_force"][0] == 0.0
    assert res["clamp_moment"] == pytest.approx(-W * a_lin**2 / 6.0, rel=1e-6)
    # And the ratio R/(w a) approaches 1/3 as d falls (O(d^(3/2)) too).
    dev = []
    for dd in (1e-2, 1e-3):
        r = heavy_cantilever_on_floor(L, EI, W, dd)
        dev.append(abs(r["R"] / (W * r["a"]) - 1.0 / 3.0))
    assert dev[1] < dev[0] / 20.0  # 10^1.5 = 31.6 expected


@pytest.mark.parametrize(
    ("Lr", "d"),
    [(1.0, 1e-3), (1.0, 0.05), (3.0, 3.0 * ELL)],  # linear, moderate, theta ~ -73 deg
)
def test_global_equilibrium(Lr, d):
    # Forces: clamp F_z + floor (R + w (L - a)) = w L, F_x = 0 (frictionless). This
    # is bookkeeping of the outputs' signs (exact to rounding, 1e-12).
    n = 20001
    res = heavy_cantilever_on_floor(Lr, EI, W, d, n=n)
    a, R, Mc = res["a"], res["R"], res["clamp_moment"]
    Fx, Fz = res["clamp_force"]
    assert Fx == 0.0
    assert Fz + res["total_floor_reaction"] == pytest.approx(W * Lr, rel=1e-12)

    # Moments about the clamp (0, d), positive about +y (a vertical force F_z at x
    # gives -x F_z): clamp + weight + touchdown reaction + distributed reaction = 0.
    # The load moments are computed from the sampled shape only, independently of
    # EI theta'(0): Simpson on 20001 points (h = L/2e4, error ~ h^4 ~ 1e-17 relative;
    # x is smooth across s = a since theta ~ (a-s)^2 there), the flat part exactly.
    s, x, z = res["s"], res["x"], res["z"]
    x_a = x[-1] - (Lr - a)  # flat part: x = x(a) + (s - a)
    weight = W * simpson(x, x=s)
    floor = R * x_a + W * (Lr - a) * (x_a + x[-1]) / 2.0
    assert Mc + weight - floor == pytest.approx(0.0, abs=1e-9 * abs(Mc))
    # Shape sanity: clamp at (0, d), hanging part above the floor, flat part on it.
    assert x[0] == 0.0 and z[0] == pytest.approx(d, rel=1e-10)
    assert np.all(z >= -1e-12 * d)
    assert np.all(z[s > a] == 0.0)
    flat = s > a
    assert np.allclose(np.diff(x[flat]), np.diff(s[flat]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("D", [1e-3, 0.1, 1.0, 3.0])
def test_clamp_moment_first_integral(D):
    # Exact first integral: EI theta'(0)^2 / 2 = w d (multiply EI theta'' = -n_z cos
    # theta by theta', integrate over [0, a], theta(0) = theta(a) = 0, n_z' = w), so
    # M_clamp = -sqrt(2 EI w d) at any drop; 1e-9 = solver tolerance with margin
    # (measured <= 1e-13).
    res = heavy_cantilever_on_floor(10.0, EI, W, D * ELL, n=11)
    assert res["clamp_moment"] == pytest.approx(
        -math.sqrt(2.0 * EI * W * D * ELL), rel=1e-9
    )


def _bvp_touchdown(EI, w, d):
    """Independent formulation: sigma = s / a in [0, 1], unknown parameters (a, R).

    States (theta, theta_s, z, x); 4 states + 2 parameters = 6 conditions:
    theta(0) = 0, z(0) = d, x(0) = 0, theta(1) = 0, theta_s(1) = 0, z(1) = 0.
    """

    def f(sig, y, p):
        a, R = p
        th, k, _, _ = y
        return np.vstack(
            [
                a * k,
                a * (w * a * (1.0 - sig) - R) * np.cos(th) / EI,
                a * np.sin(th),
                a * np.cos(th),
            ]
        )

    def bc(y0, y1, p):
        return np.array([y0[0], y0[2] - d, y0[3], y1[0], y1[1], y1[2]])

    a0 = linear_touchdown(EI, w, d)
    sig = np.linspace(0.0, 1.0, 41)
    u = a0 * (1.0 - sig)
    R0 = w * a0 / 3.0
    y0 = np.vstack(
        [
            -(R0 * u**2 / 2.0 - w * u**3 / 6.0) / EI,
            (R0 * u - w * u**2 / 2.0) / EI,
            (R0 * u**3 / 6.0 - w * u**4 / 24.0) / EI,
            a0 * sig,
        ]
    )
    sol = solve_bvp(f, bc, sig, y0, p=[a0, R0], tol=1e-10, max_nodes=20000)
    assert sol.success, sol.message
    return sol.p[0], sol.p[1], EI * sol.sol(0.0)[1]


def test_against_independent_solve_bvp():
    # Same physics, different unknowns/direction/solver (collocation, tol 1e-10):
    # agreement to 1e-9 relative (collocation error ~ tol; measured 3e-14).
    d = 0.05
    res = heavy_cantilever_on_floor(L, EI, W, d)
    a, R, M = _bvp_touchdown(EI, W, d)
    assert res["a"] == pytest.approx(a, rel=1e-9)
    assert res["R"] == pytest.approx(R, rel=1e-9)
    assert res["clamp_moment"] == pytest.approx(M, rel=1e-9)


def test_invalid_inputs_raise():
    with pytest.raises(ValueError, match="d must be > 0"):
        heavy_cantilever_on_floor(L, EI, W, 0.0)
    with pytest.raises(ValueError, match="d must be > 0"):
        heavy_cantilever_on_floor(L, EI, W, -0.1)
    # a = 0.652 m at d = 0.05: a 0.5 m rod cannot reach a flat contact.
    with pytest.raises(ValueError, match="too short"):
        heavy_cantilever_on_floor(0.5, EI, W, 0.05)
    # Outside the well-conditioned range of the shooting.
    with pytest.raises(RuntimeError, match="d/l"):
        heavy_cantilever_on_floor(100.0, EI, W, 10.0 * ELL)
