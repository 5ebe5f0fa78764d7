"""The Rosenbrock-W solver (ROS34PW2): order, W-method property, stability, gradients.

References: a tight Dopri8 (or diffrax Dopri8) solution for convergence orders; the
stability function of an L-stable method on y' = lambda y; the static equilibrium
(solve_statics) that a damped rod settles to; central differences for gradients.
A 2-DoF rod keeps compiles small; the free-fall rod is in test_dynamics.py.
"""

import math

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from references import gradient_vs_central_difference

import sorojax as sj
from sorojax.integrate import MechanicalTerm, RosenbrockW


def _rod(eta=0.0, E=1e6, loop=False):
    """0.3 m rod, r 5 mm, bending about y with linear strain (2 DoF), gravity -z.

    ``loop``: its tip held on the x axis by a closed-loop prismatic joint (along x).
    """
    div = sj.Division(
        0.3, sj.CircularSection(0.005), sj.LegendreBasis((0, 1, 0, 0, 0, 0), 1), 6
    )
    mat = sj.Material(E=E, poisson=0.5, rho=1000.0, eta=eta)
    loops = [
        sj.ClosedLoopJoint(
            sj.Joint("P", axis=(1.0, 0.0, 0.0)), 1, 0, g_B=sj.translation(0.3)
        )
    ]
    return sj.Linkage(
        [sj.SoftLink([div], mat)],
        gravity=(0.0, 0.0, -9.81),
        closed_loops=loops if loop else [],
    )


@pytest.fixture(scope="module")
def rod():
    return _rod()


def _orders(errs):
    errs = np.asarray(errs)
    return np.log2(errs[:-1] / errs[1:])


def test_third_order_on_a_nonlinear_ode_with_the_exact_jacobian():
    """Any diffrax term: W is the exact autodiff Jacobian (classical Rosenbrock).

    Reference: Dopri8 at rtol 1e-13 on the Van der Pol oscillator (mu = 2, one time
    unit). ROS34PW2 has order 3: halving h divides the error by ~8. Measured slopes
    2.86, 2.92, 2.95 for h = 0.1 ... 0.0125; bound 2.7-3.3 (order 2 or 4 fails).
    """

    def vdp(t, y, args):
        return jnp.stack([y[1], 2.0 * (1 - y[0] ** 2) * y[1] - y[0]])

    y0 = jnp.array([2.0, 0.0])
    ref = diffrax.diffeqsolve(
        diffrax.ODETerm(vdp),
        diffrax.Dopri8(),
        0.0,
        1.0,
        1e-3,
        y0,
        stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13),
    ).ys[-1]
    errs = []
    for h in (0.1, 0.05, 0.025, 0.0125):
        y1 = diffrax.diffeqsolve(
            diffrax.ODETerm(vdp), RosenbrockW(), 0.0, 1.0, h, y0
        ).ys[-1]
        errs.append(float(jnp.abs(y1 - ref).max()))
    p = _orders(errs)
    assert np.all((p > 2.7) & (p < 3.3)), f"observed orders {p} (errors {errs})"


def test_order_three_holds_for_any_w(rod):
    """W-method: the order does not depend on W (Hairer & Wanner IV.7).

    The mechanical term's W uses K scaled by 1 (the simulator's choice), 0 (W = 0:
    no implicitness at all) and 3 (a wrong stiffness); the true Jacobian also has
    the q-dependence of M and gravity, which W never has. Reference: Dopri8 at rtol
    1e-13 over 0.05 s from a 2 rad/m pre-bend. Measured slopes 2.94-3.27 for
    h = t1/4 ... t1/32; bound 2.7-3.4 on the last two (a Rosenbrock method that
    needs the exact Jacobian drops to order 2 or less here).
    """
    n = rod.n_dof
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    K = sj.stiffness_matrix(rod)
    t1 = 0.05
    ref = sj.simulate(rod, t1, q0, ts=[t1], solver="dopri8", rtol=1e-13, atol=1e-15)
    y_ref = jnp.concatenate([ref.q[-1], ref.qd[-1]])

    def field(t, y, k_scale):
        M, f = sj.equations_of_motion(rod, y[:n], y[n:], t)
        lin = (M, k_scale * K, jnp.zeros_like(K))
        return jnp.concatenate([y[n:], jnp.linalg.solve(M, f)]), lin

    @jax.jit
    def final(h, k_scale):
        y0 = jnp.concatenate([q0, jnp.zeros(n)])
        term = MechanicalTerm(field)
        sol = diffrax.diffeqsolve(term, RosenbrockW(), 0.0, t1, h, y0, args=k_scale)
        return sol.ys[-1]

    for k_scale in (1.0, 0.0, 3.0):
        errs = [
            float(jnp.abs(final(t1 / k, k_scale) - y_ref).max()) for k in (4, 8, 16, 32)
        ]
        p = _orders(errs)[1:]
        assert np.all((p > 2.7) & (p < 3.4)), (
            f"K x {k_scale}: observed orders {p} (errors {errs})"
        )


def test_l_stable_on_the_test_equation():
    """y' = lambda y: the method's stability function R(z) at z = h lambda.

    Reference: ROS34PW2 is L-stable and stiffly accurate, so R(z) -> 0 as
    z -> -inf (one step at z = -1e8 leaves < 1e-6 of y0) and |R(i w)| <= 1 on the
    imaginary axis (a rotation y' = [[0, w], [-w, 0]] y at h w = 100 never grows).
    """
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: -1e8 * y),
        RosenbrockW(),
        0.0,
        1.0,
        1.0,
        jnp.array([1.0]),
    )
    assert abs(float(sol.ys[-1, 0])) < 1e-6, f"R(-1e8) = {float(sol.ys[-1, 0])}"
    w = 100.0
    rot = jnp.array([[0.0, w], [-w, 0.0]])
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: rot @ y),
        RosenbrockW(),
        0.0,
        10.0,
        1.0,
        jnp.array([1.0, 0.0]),
        saveat=diffrax.SaveAt(steps=True),
    )
    norms = np.linalg.norm(np.asarray(sol.ys)[np.isfinite(sol.ys[:, 0])], axis=1)
    assert norms.max() <= 1.0 + 1e-12, f"|y| grew to {norms.max()}"


def test_damped_rod_settles_on_statics_with_steps_far_beyond_explicit_limits():
    """A strongly damped rod with a constant step 30x beyond Tsit5's stability limit.

    Reference: solve_statics (the rest state under gravity; the dynamics must settle
    on it). E = 100 MPa and Kelvin-Voigt damping eta = 2 MPa s make the fastest mode
    a damped one (eigenvalues -5223 and -29 +- 11i, -17 1/s; Tsit5's limit is
    h < 2.8 / |lambda|). Tsit5 at h = 0.03 s (h |lambda| = 157) diverges (result
    code, no silent NaN); ROS34PW2 at the same step completes 3 s and ends within
    1e-8 of the static coordinates (the slowest mode has decayed by exp(-17 * 3)),
    with the energy never rising.
    """
    lk = _rod(eta=2e6, E=1e8)
    q0 = sj.strain_coordinates(lk, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    lam = sj.integrate.stiffness_estimate(lk, q0)
    h = 0.03
    assert h * lam > 30 * 2.8, f"|lambda| = {lam:.0f} 1/s is not stiff enough"
    kw = dict(adaptive=False, dt0=h, throw=False, n_save=31)
    explicit = sj.simulate(lk, 3.0, q0, solver="tsit5", **kw)
    assert explicit.result == sj.RESULTS.unstable_step
    tr = sj.simulate(lk, 3.0, q0, solver="ros34pw2", **kw)
    assert tr.result == sj.RESULTS.successful
    rest = sj.solve_statics(lk)
    err = float(jnp.abs(tr.q[-1] - rest.q).max())
    assert err < 1e-8, f"final q vs statics: {err:.2e}"
    E = np.asarray(jax.vmap(lambda q, qd: sj.total_energy(lk, q, qd))(tr.q, tr.qd))
    assert np.diff(E).max() <= 1e-12 * abs(E[0]), "energy rose between saves"


def test_gradient_through_simulate_matches_central_differences():
    """d(tip height at 0.05 s)/dE through an adaptive ROS34PW2 simulate.

    Reference: central differences with step 1e-5 E from the same compiled function
    (one jitted ``value_and_grad``). At rtol 1e-7 (232 steps) the step sequence is
    the same within +-1e-5 E (the controller's decisions are smooth there), so both
    differentiate one discrete map: truncation ~1e-10, roundoff ~1e-11 / 1e-5;
    measured 4e-9. Tolerance 1e-6 relative.

    Forward mode (``jax.jacfwd`` with ``diffrax.ForwardMode()``, README's way for a
    few parameters) differentiates the same discrete map (the same 232 steps): equal
    to the reverse-mode gradient to rounding. Tolerance 1e-8 relative: E dz/dE is
    1.7e-3 m and 1e-8 of it (2e-11 m) is the rounding of 232 steps of a 0.1 m tip
    position that the two programs sum in different orders (measured 2e-9).
    """
    q0 = sj.strain_coordinates(_rod(), [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])

    def tip_height(E, adjoint=None):
        lk = _rod(eta=1e3, E=E)
        tr = sj.simulate(
            lk, 0.05, q0, ts=jnp.array([0.05]), solver="ros34pw2", rtol=1e-7,
            atol=1e-9, adjoint=adjoint,
        )  # fmt: skip
        return sj.tip_pose(lk, tr.q[-1])[2, 3]

    f = jax.jit(jax.value_and_grad(tip_height))
    grad, fd, err = gradient_vs_central_difference(
        lambda E: f(jnp.asarray(E)), 1e6, 1e-5 * 1e6
    )
    assert err < 1e-6, f"dz/dE {grad:.10e} vs central {fd:.10e}: {err:.1e}"
    forward = jax.jit(jax.jacfwd(lambda E: tip_height(E, diffrax.ForwardMode())))
    np.testing.assert_allclose(float(forward(1e6)), grad, rtol=1e-8)


def test_vmap_equals_loop(rod):
    """vmap of simulate over 3 initial bends equals a Python loop (1e-12)."""
    q0s = jax.vmap(
        lambda k: sj.strain_coordinates(rod, jnp.array([0, k, 0, 0, 0, 0.0]))
    )(jnp.array([0.5, 1.0, 2.0]))

    def final(q0):
        return sj.simulate(rod, 0.1, q0, solver="ros34pw2", throw=False, n_save=2).q[-1]

    batched = jax.vmap(final)(q0s)
    looped = jnp.stack([final(q0) for q0 in q0s])
    np.testing.assert_allclose(batched, looped, rtol=1e-12, atol=1e-12)


def test_mechanical_step_end_slope_is_the_last_stage(rod):
    """The mechanical step carries no state (no first-same-as-last evaluation); its
    dense output's end slope is the last stage's ``k_s``.

    Reference: ``h f(y1)``. Stiffly accurate, ``k_s = h f(y1) + h (W - J)(y1 - Y_s)``
    to second order in ``y1 - Y_s`` (module docstring): for a linear system with
    W = J (constant M, K, D) it equals ``h f(y1)`` to rounding (1e-12 relative);
    for the rod, whose W lacks gravity and M(q)'s dependence, the difference is
    O(h^3): halving h divides it by ~8 (measured slopes 2.9-3.0; bound 2.6-3.4).
    """
    n = rod.n_dof
    solver = RosenbrockW()
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    y0 = jnp.concatenate([q0, 0.1 * jnp.ones(n)])

    def rod_field(t, y, args):
        M, f = sj.equations_of_motion(rod, y[:n], y[n:], t)
        K = sj.stiffness_matrix(rod)
        return jnp.concatenate([y[n:], jnp.linalg.solve(M, f)]), (M, K, 0.0 * K)

    M = jnp.array([[2.0, 0.3], [0.3, 1.0]])
    K = jnp.array([[400.0, -50.0], [-50.0, 90.0]])
    D = 0.05 * K

    def linear_field(t, y, args):
        f = -K @ y[:n] - D @ y[n:]
        return jnp.concatenate([y[n:], jnp.linalg.solve(M, f)]), (M, K, D)

    def slope_gap(field, h):
        term = MechanicalTerm(field)
        assert solver.init(term, 0.0, h, y0, None) is None
        y1, _, dense, state, _ = solver.step(term, 0.0, h, y0, None, None, False)
        assert state is None
        f1 = term.vf(h, y1, None)
        np.testing.assert_allclose(dense["k0"], h * term.vf(0.0, y0, None), rtol=1e-13)
        return float(jnp.abs(dense["k1"] - h * f1).max() / jnp.abs(f1).max())

    gap = slope_gap(linear_field, 0.05)
    assert gap < 1e-12, f"linear system: |k_s - h f(y1)| / |f(y1)| = {gap:.1e}"
    gaps = [slope_gap(rod_field, h) for h in (4e-3, 2e-3, 1e-3)]
    p = _orders(gaps)
    assert np.all((p > 2.6) & (p < 3.4)), f"slopes {p} (gaps {gaps})"


def test_state_must_be_a_vector():
    """A non-vector state is refused with a message naming the shape."""
    with pytest.raises(ValueError, match=r"one-dimensional array state; got shape"):
        diffrax.diffeqsolve(
            diffrax.ODETerm(lambda t, y, a: -y),
            RosenbrockW(),
            0.0,
            1.0,
            0.1,
            jnp.ones((2, 2)),
        )


def test_tableau_is_stiffly_accurate_and_consistent():
    """ROS34PW2's published coefficients satisfy sum b = 1 and b = last row of
    (alpha + Gamma) (stiffly accurate), and the embedded weights sum to 1."""
    from sorojax.integrate import _rosenbrock as R

    np.testing.assert_allclose(R._B.sum(), 1.0, atol=1e-14)
    np.testing.assert_allclose(R._B_HAT.sum(), 1.0, atol=1e-14)
    np.testing.assert_allclose(R._ALPHA[-1] + R._GAMMA_MAT[-1], R._B, atol=1e-14)
    assert math.isclose(R.ROS34PW2.gamma, 0.435866521508459, rel_tol=1e-14)


def test_auto_decides_from_the_structure_when_traced():
    """Under jit with a traced E no eigenvalues can be computed on the host: "auto"
    takes ROS34PW2 for a soft linkage at rtol >= 1e-5 and Tsit5 at a tighter rtol or
    with closed loops (documented in sorojax.integrate.DEFAULT_SOLVER)."""
    q0 = jnp.zeros(2)
    picks = []

    def pick(E):
        lk = _rod(E=E)
        picks.append(sj.integrate.auto_solver(lk, q0, 0.0, 1.0, 1e-3))
        picks.append(sj.integrate.auto_solver(lk, q0, 0.0, 1.0, 1e-8))
        picks.append(sj.integrate.auto_solver(_rod(E=E, loop=True), q0, 0, 1, 1e-3))
        return E

    jax.jit(pick)(1e6)
    assert picks == ["ros34pw2", "tsit5", "tsit5"]


def test_auto_takes_tsit5_for_rigid_links_without_springs_and_compiles_nothing(
    monkeypatch,
):
    """Rigid links with neither joint stiffness nor damping: K = D = 0, so the
    linearised state matrix [[0, I], [0, 0]] has only zero eigenvalues and the
    eigenvalue test picks Tsit5 (Dopri8 at a tight rtol). "auto" and the stiffness estimate know it from the
    model, without the program of M, K, D; that program (run here) gives K and D
    exactly 0 and M symmetric positive definite. A joint spring sends the decision
    back to the eigenvalues."""
    from sorojax._mechanisms import four_bar, four_bar_assemble
    from sorojax.integrate import _simulate as S

    bar = four_bar()
    q0 = jnp.asarray(four_bar_assemble(0.3))
    real, calls = S._linear_terms, []
    monkeypatch.setattr(S, "_linear_terms", lambda *a: calls.append(1) or real(*a))
    assert sj.integrate.auto_solver(bar, q0, 0.0, 100.0, 1e-3) == "tsit5"
    # no stability bound at all: at a tight rtol accuracy sets the steps (Dopri8)
    assert sj.integrate.auto_solver(bar, q0, 0.0, 3.0, 1e-8) == "dopri8"
    assert S.stiffness_estimate(bar, q0) == 0.0
    assert not calls, "auto computed M, K, D"
    M, K, D = (np.asarray(a) for a in real(bar, q0))
    assert not K.any() and not D.any(), "K or D of the rigid four-bar is not 0"
    assert np.linalg.eigvalsh(M).min() > 0 and np.allclose(M, M.T, atol=1e-14)
    sprung = sj.Linkage(
        [sj.RigidLink(sj.Joint("R", stiffness=2.0), length=0.1, mass=0.1)]
    )
    assert not S._without_springs(sprung) and S._without_springs(bar)


def test_auto_keeps_explicit_with_closed_loops():
    """A damped soft rod over a long run takes ROS34PW2, but not once a closed loop
    ties its tip: the loop's Baumgarte rows are not in W (5 s of the manual's hybrid
    took 10 021 ROS34PW2 steps), so "auto" keeps to Tsit5 / Kvaerno5 there."""
    q0 = jnp.zeros(2)
    free = sj.integrate.auto_solver(_rod(eta=1e5), q0, 0.0, 100.0, 1e-3)
    tied = sj.integrate.auto_solver(_rod(eta=1e5, loop=True), q0, 0.0, 100.0, 1e-3)
    assert free == "ros34pw2" and tied in ("tsit5", "kvaerno5")
