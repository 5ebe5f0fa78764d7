"""The actuated and closed-chain examples run and compute the right physics.

examples/mechanisms.py (four-bar and slider-crank with a prescribed crank) and
examples/cable_manipulator.py (four-cable arm: statics, PD tip control through the
actuator-strength hook). Each example's ``main(argv)`` runs in this process on small
settings; references are computed here independently of sorojax's model: the
mechanisms' geometry by loop closure, the crank torque by virtual work (statics) and
by Lagrange's equation of the one-dof mechanism (dynamics), the slider position by
the textbook formula.

The first run compiles closed-loop statics (~30 s per mechanism) and dynamics
(~40 s) on a 2-core CPU; the long cases are marked ``slow``.
"""

import math

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np
import pytest
from scipy.optimize import newton
from test_examples import _load  # one loader for the example scripts

import sorojax as sj

matplotlib.use("Agg")


G = 9.81
RHO, W = 1000.0, 0.02  # bar density [kg/m^3] and square section side [m]
# Geometry restated from the builders' documentation (sorojax/_mechanisms.py).
A_CR, B_CO, C_RO, D_GR = 0.1, 0.4, 0.3, 0.35  # four-bar: crank, coupler, rocker, ground
R_SC, L_SC, W_SL = 0.1, 0.3, 0.08  # slider-crank: crank, rod, slider block


def _mass(length):
    return RHO * W * W * length


# ------------------------------------------------------------------ references
def four_bar_potential(theta, psi_guess):
    """Gravitational energy of the four-bar at crank angle theta, and the rocker angle.

    The rocker angle psi solves |D + c e(psi) - a e(theta)| = b (Newton from
    ``psi_guess``, which picks the branch); the bars' CMs are at mid-length.
    """
    A = np.array([A_CR * math.cos(theta), A_CR * math.sin(theta)])
    D = np.array([D_GR, 0.0])

    def gap(psi):
        P = D + C_RO * np.array([math.cos(psi), math.sin(psi)])
        return float(np.sum((P - A) ** 2) - B_CO**2)

    psi = newton(gap, psi_guess, tol=1e-15, maxiter=100)
    P = D + C_RO * np.array([math.cos(psi), math.sin(psi)])
    y = [A[1] / 2, (A[1] + P[1]) / 2, P[1] / 2]
    m = [_mass(A_CR), _mass(B_CO), _mass(C_RO)]
    return G * float(np.dot(m, y)), psi


def slider_crank_torque(theta, omega):
    """Crank torque of the slider-crank at constant crank speed, by Lagrange.

    One dof theta: T = m_eff(theta) theta'^2 / 2 with m_eff = sum m |dc/dtheta|^2 +
    I (dphi/dtheta)^2, V = g sum m y_c; at theta'' = 0 the driving torque is
    tau = m_eff'(theta) omega^2 / 2 + V'(theta). Bars are prisms: I = m (L^2 + w^2)
    / 12 about the CM; the slider only translates.
    """
    m1, m2, m3 = _mass(R_SC), _mass(L_SC), _mass(W_SL)
    I1 = m1 * (R_SC**2 + W**2) / 12 + m1 * (R_SC / 2) ** 2  # about the crank pivot
    I2 = m2 * (L_SC**2 + W**2) / 12

    def rod_angle(th):
        return -jnp.arcsin(R_SC * jnp.sin(th) / L_SC)

    def rod_cm(th):
        phi = rod_angle(th)
        tip = R_SC * jnp.stack([jnp.cos(th), jnp.sin(th)])
        return tip + L_SC / 2 * jnp.stack([jnp.cos(phi), jnp.sin(phi)])

    def pin_x(th):
        return R_SC * jnp.cos(th) + L_SC * jnp.cos(rod_angle(th))

    def m_eff(th):
        dc = jax.jacfwd(rod_cm)(th)
        return (
            I1
            + m2 * jnp.dot(dc, dc)
            + I2 * jax.grad(rod_angle)(th) ** 2
            + m3 * jax.grad(pin_x)(th) ** 2
        )

    def V(th):
        return G * (m1 * R_SC / 2 * jnp.sin(th) + m2 * rod_cm(th)[1])

    def tau(th):
        return 0.5 * jax.grad(m_eff)(th) * omega**2 + jax.grad(V)(th)

    return np.asarray(jax.vmap(tau)(jnp.asarray(theta)))


# --------------------------------------------------------------------- tests
@pytest.mark.slow  # tests/test_closed_loops.py checks the same in the default run
def test_four_bar_statics_crank_torque_is_virtual_work(tmp_path):
    """examples/mechanisms.py --only four_bar --statics-only at 4 crank angles.

    Each solve starts 0.02 off the assembly. Reference: loop closure solved here
    (Newton on the rocker angle) and tau = dV/dtheta along the mechanism by central
    differences (step 1e-6: truncation ~1e-12 and rounding ~1e-10 of the torque;
    tolerance 1e-7 relative to the largest torque). The solved shape must be the
    closed loop (1e-10 rad) and the residuals at Newton's tolerance (< 1e-8), the
    planar loop's 5 rows of rank 2.
    """
    ex = _load("mechanisms")
    res = ex.main(
        [
            "--only",
            "four_bar",
            "--statics-only",
            "--n-angles",
            "4",
            "--out",
            str(tmp_path),
        ]
    )
    st = res["four_bar"]["statics"]
    assert st["residual"].max() < 1e-8, f"equilibrium residual {st['residual']}"
    assert st["constraint_error"].max() < 1e-8, f"loop error {st['constraint_error']}"
    assert st["constraint_rank"] == 2
    tau_ref = []
    h = 1e-6
    for th, q in zip(st["angles"], st["q"], strict=True):
        _, psi = four_bar_potential(th, float(q[2]))
        assert abs(psi - q[2]) < 1e-10, f"rocker angle {q[2]} vs closure {psi}"
        Vp, _ = four_bar_potential(th + h, psi)
        Vm, _ = four_bar_potential(th - h, psi)
        tau_ref.append((Vp - Vm) / (2 * h))
    tau_ref = np.asarray(tau_ref)
    err = np.abs(st["torque"] - tau_ref).max()
    assert err < 1e-7 * np.abs(tau_ref).max(), (
        f"crank torque {st['torque']} vs virtual work {tau_ref}"
    )
    assert (tmp_path / "mechanisms.png").stat().st_size > 10_000


@pytest.mark.slow
def test_mechanisms_driven_drift_slider_formula_and_lagrange_torque(tmp_path):
    """examples/mechanisms.py: 1 s at one revolution per second, both mechanisms.

    Drift of the loops (Baumgarte, rtol 1e-8) < 1e-6 over all saves; statics
    residuals < 1e-8; slider pin x equals r cos(theta) + sqrt(l^2 - r^2 sin^2(theta))
    to 1e-8 m (the drift bound, with margin); the slider-crank's crank torque equals
    the Lagrange torque of the one-dof mechanism to 1e-4 of its largest value (the
    Baumgarte correction and rtol 1e-8 leave ~1e-8). A second run must refuse to
    overwrite the PNG.
    """
    ex = _load("mechanisms")
    omega = 2 * math.pi
    argv = ["--t1", "1", "--n-angles", "4", "--n-save", "101", "--out", str(tmp_path)]
    res = ex.main(argv)
    for name in ("four_bar", "slider_crank"):
        r = res[name]
        assert r["traj"].result == sj.RESULTS.successful
        assert r["drift"].max() < 1e-6, f"{name}: drift {r['drift'].max():.2e}"
        assert r["statics"]["residual"].max() < 1e-8
        assert r["statics"]["constraint_error"].max() < 1e-8
    sc = res["slider_crank"]
    tr = sc["traj"]
    theta = np.asarray(tr.q[:, 0])
    np.testing.assert_allclose(theta, omega * np.asarray(tr.t), atol=1e-12)
    x_ref = R_SC * np.cos(theta) + np.sqrt(L_SC**2 - (R_SC * np.sin(theta)) ** 2)
    x = np.asarray(tr.q[:, 2]) + W_SL / 2
    assert np.abs(x - x_ref).max() < 1e-8, f"slider x off by {np.abs(x - x_ref).max()}"
    tau_ref = slider_crank_torque(theta, omega)
    tau = np.asarray(tr.efforts[:, 0])
    err = np.abs(tau - tau_ref).max()
    assert err < 1e-4 * np.abs(tau_ref).max(), f"crank torque off by {err:.2e} N m"
    size = (tmp_path / "mechanisms.png").stat().st_size
    assert size > 10_000
    with pytest.raises(SystemExit, match="overwrite"):
        ex.main(argv)


def test_cable_manipulator_statics_symmetry_and_inverse_statics():
    """The arm's statics through the example's helpers (order 1, one compiled solve).

    Without tension it hangs straight (tip at (0, 0, -0.9) to 1e-12); cable +y moves
    the tip in the y-z plane only and cable +z in the x-z plane, by the same amount
    (the section and paths are symmetric: 1e-10); equal tensions on +y and +z put the
    tip on the diagonal x = y; a larger tension bends further. The inverse statics
    hits its lateral target to 1e-10 m with pretension on every cable.
    """
    ex = _load("cable_manipulator")
    arm = ex.cable_manipulator(order=1, eta=ex.ETA)
    tip0, _ = ex.tip_of(arm, [0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(tip0, [0.0, 0.0, -0.9], atol=1e-12)
    ty, _ = ex.tip_of(arm, [5.0, 0.0, 0.0, 0.0])
    tz, _ = ex.tip_of(arm, [0.0, 5.0, 0.0, 0.0])
    assert abs(ty[0]) < 1e-12 and ty[1] > 0.05, f"+y cable: tip {ty}"
    assert abs(tz[1]) < 1e-12 and tz[0] > 0.05, f"+z cable: tip {tz}"
    assert abs(ty[1] - tz[0]) < 1e-10 and abs(ty[2] - tz[2]) < 1e-10
    td, _ = ex.tip_of(arm, [5.0, 5.0, 0.0, 0.0])
    assert abs(td[0] - td[1]) < 1e-10, f"diagonal: tip {td}"
    t10, _ = ex.tip_of(arm, [10.0, 0.0, 0.0, 0.0])
    assert t10[1] > ty[1]
    target = np.array([0.1, 0.15])
    T_ff, tip, _ = ex.inverse_statics(arm, target)
    assert np.abs(tip[:2] - target).max() < 1e-10
    assert np.all(T_ff >= ex.PRETENSION - 1e-12)


@pytest.mark.slow
def test_cable_manipulator_pd_reaches_target(tmp_path):
    """examples/cable_manipulator.py at order 1 over 8 s: PD tip control in dynamics.

    The tip must end within 1 mm of the 3D target (the equilibrium under the
    feedforward tensions), the tensions the hook applied never go below zero, and
    the error must have fallen from its start (the straight arm, ~19 cm away).
    """
    ex = _load("cable_manipulator")
    res = ex.main(
        ["--order", "1", "--t1", "8", "--n-save", "81", "--out", str(tmp_path)]
    )
    traj = res["traj"]
    assert traj.result == sj.RESULTS.successful
    assert res["final_error"] < 1e-3, f"tip error {res['final_error'] * 1e3:.3f} mm"
    assert res["tip_error"][0] > 0.1
    assert float(np.asarray(traj.u).min()) >= 0.0
    np.testing.assert_allclose(res["target"][:2], [0.1, 0.15], atol=1e-10)
    assert (tmp_path / "cable_manipulator.png").stat().st_size > 10_000
