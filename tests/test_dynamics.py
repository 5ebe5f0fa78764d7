"""Dynamics against invariants, closed forms and an independent ODE reference (float64).

References: M(q) symmetric positive definite; Mdot - 2C skew-symmetric; C qd from
Lagrange's equations (Mdot qd - dT/dq); energy conservation without damping and
dissipation with it (SoRoSim's free-fall rod, a hybrid chain); Euler-Bernoulli
cantilever frequencies; the elliptic-integral period of a rigid pendulum; a rigid double
pendulum integrated by scipy from Lagrange's equations (tests/references.py); central
differences for d(tip)/dE through simulate.

Compiles dominate the cost: each model structure is built once (module fixtures) and the
explicit solvers share one name (Dopri8) so that equal structures reuse programs.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
from references import (
    cantilever_natural_frequencies,
    gradient_vs_central_difference,
    pendulum_period,
    rigid_double_pendulum,
    rigid_double_pendulum_energy,
)

import sorojax as sj
from sorojax.scenes import cantilever, demo_linkage, free_fall_q0, free_fall_rod

G = 9.81
SOLVER = "dopri8"  # explicit 8th order: cheap steps at the tight tolerances used here


def _energies(linkage, traj):
    """Total and kinetic energy at every save time."""
    E = jax.vmap(lambda q, qd: sj.total_energy(linkage, q, qd))(traj.q, traj.qd)
    T = jax.vmap(lambda q, qd: sj.kinetic_energy(linkage, q, qd))(traj.q, traj.qd)
    return np.asarray(E), np.asarray(T)


# ------------------------------------------------------------------------- models
@pytest.fixture(scope="module")
def free_fall():
    """SoRoSim's free-fall rod: torsion + two bendings, cubic Legendre (12 DoF)."""
    rod = free_fall_rod()
    assert rod.n_dof == 12
    return rod


@pytest.fixture(scope="module")
def demo():
    """The demo linkage: rigid bar on a sprung revolute joint + damped soft rod with a
    follower tip force, gravity along -y (7 DoF)."""
    return demo_linkage()


def _hybrid_chain(joint_stiffness=20.0, eta=0.0):
    """The demo linkage's chain (rigid bar on R + two-division soft rod, 7 DoF) with
    gravity along -y and no point wrench: conservative when ``eta = 0``."""
    bend = (0, 1, 1, 0, 0, 0)
    link1 = sj.RigidLink(
        sj.Joint("R", axis=(0.0, 0.0, 1.0), stiffness=joint_stiffness),
        length=0.3,
        section=sj.RectangularSection(0.04, 0.04),
        rho=1000.0,
    )
    link2 = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection((0.02, 0.015)), sj.LegendreBasis(bend, 1)
            ),
            sj.Division(
                0.2, sj.CircularSection((0.015, 0.01)), sj.LegendreBasis(bend, 0)
            ),
        ],
        sj.Material(E=5e6, poisson=0.5, rho=1000.0, eta=eta),
    )
    c, s = math.cos(math.radians(15)), math.sin(math.radians(15))
    turn_y = jnp.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])
    return sj.Linkage(
        [link1, link2],
        parents=(0, 1),
        placements=jnp.stack([jnp.eye(4), turn_y]),
        gravity=(0.0, -G, 0.0),
    )


def _random_states(linkage, seed, n=3):
    """``n`` random (q, qd): q ~ U(-1, 1) (strains up to 1 / length, joints 1 rad)."""
    keys = jax.random.split(jax.random.PRNGKey(seed), 2 * n)
    shape = (linkage.n_dof,)
    return [
        (
            jax.random.uniform(keys[2 * i], shape, minval=-1.0, maxval=1.0),
            jax.random.normal(keys[2 * i + 1], shape),
        )
        for i in range(n)
    ]


MODELS = ["free_fall", "demo"]


def _mass_matrix_derivative(linkage, q):
    """dM/dq as (n, n, n) by forward-mode autodiff (one program serves Mdot and dT/dq)."""
    return np.asarray(jax.jacfwd(lambda q_: sj.mass_matrix(linkage, q_))(q))


# ------------------------------------------------------- 1. structural invariants
@pytest.mark.parametrize("model", MODELS)
def test_mass_matrix_symmetric_positive_definite(model, request):
    """M(q) is symmetric positive definite at random configurations.

    Reference: M = sum w J^T M_s J with every coordinate moving mass (DESIGN.md 4).
    Tolerances: symmetry to 1e-14 of |M| (roundoff); the smallest eigenvalue must be
    positive, and larger than 1e-12 of the largest (far above roundoff, so a rank
    deficiency cannot pass as positive).
    """
    lk = request.getfixturevalue(model)
    for i, (q, _) in enumerate(_random_states(lk, seed=1)):
        M = np.asarray(sj.mass_matrix(lk, q))
        scale = np.abs(M).max()
        asym = np.abs(M - M.T).max() / scale
        assert asym < 1e-14, f"{model} q#{i}: M asymmetric by {asym:.1e} of |M|"
        lam = np.linalg.eigvalsh(M)
        assert lam[0] > 1e-12 * lam[-1], (
            f"{model} q#{i}: M eigenvalues {lam[0]:.3e} .. {lam[-1]:.3e}"
        )


@pytest.mark.parametrize("model", MODELS)
def test_mdot_minus_2c_is_skew_symmetric(model, request):
    """Mdot - 2C is skew-symmetric, with Mdot = dM/dq . qd by forward-mode autodiff (jacfwd).

    Reference: passivity property of the chosen C (its docstring; DESIGN.md 4).
    Tolerance: 1e-10 of |Mdot| (both sides are autodiff/roundoff exact; 1e-10 leaves
    room for summation order over ~100 quadrature points).
    """
    lk = request.getfixturevalue(model)
    for i, (q, qd) in enumerate(_random_states(lk, seed=2)):
        Mdot = _mass_matrix_derivative(lk, q) @ np.asarray(qd)
        S = Mdot - 2.0 * np.asarray(sj.coriolis_matrix(lk, q, qd))
        err = np.abs(S + S.T).max() / np.abs(Mdot).max()
        assert err < 1e-10, f"{model} q#{i}: |sym(Mdot - 2C)| / |Mdot| = {err:.1e}"


@pytest.mark.parametrize("model", MODELS)
def test_coriolis_matrix_times_qd_equals_coriolis_force(model, request):
    """C(q, qd) qd equals the Jacobian-free recursion coriolis_force(q, qd).

    Reference: the same term computed two independent ways (matrix form with Jdot vs
    forward-mode twists + backward wrench recursion). Tolerance 1e-10 relative
    (roundoff of two different summation orders).
    """
    lk = request.getfixturevalue(model)
    for i, (q, qd) in enumerate(_random_states(lk, seed=3)):
        a = np.asarray(sj.coriolis_matrix(lk, q, qd) @ qd)
        b = np.asarray(sj.coriolis_force(lk, q, qd))
        err = np.linalg.norm(a - b) / np.linalg.norm(b)
        assert err < 1e-10, f"{model} q#{i}: |C qd - coriolis_force| rel {err:.1e}"


@pytest.mark.parametrize("model", MODELS)
def test_coriolis_force_follows_from_lagrange_equations(model, request):
    """C qd = Mdot qd - d/dq (1/2 qd^T M(q) qd), the velocity terms of Lagrange's
    equations for T = 1/2 qd^T M(q) qd.

    Reference: Lagrange's equations from M(q) alone (jacfwd of mass_matrix), an
    independent check that the recursive Coriolis term belongs to this mass matrix.
    Tolerance 1e-10 relative (roundoff; a wrong term is off by O(1)).
    """
    lk = request.getfixturevalue(model)
    for i, (q, qd) in enumerate(_random_states(lk, seed=4)):
        dM, v = _mass_matrix_derivative(lk, q), np.asarray(qd)
        expected = (dM @ v) @ v - 0.5 * np.einsum("i,ijk,j->k", v, dM, v)
        got = np.asarray(sj.coriolis_force(lk, q, qd))
        err = np.linalg.norm(got - expected) / np.linalg.norm(expected)
        assert err < 1e-10, f"{model} q#{i}: C qd vs Lagrange rel {err:.1e}"


@pytest.mark.parametrize("model", MODELS)
def test_equations_of_motion_assemble_the_terms(model, request):
    """equations_of_motion returns M and f = F_ext - C qd - K q - D qd.

    Reference: the public terms mass_matrix, generalized_external_force (gravity and,
    for the demo, a follower tip force), coriolis_force, stiffness_matrix and
    damping_matrix (the demo has material damping and a sprung joint). Tolerance
    1e-10 relative (roundoff of different evaluation orders).
    """
    lk = request.getfixturevalue(model)
    K, D = np.asarray(sj.stiffness_matrix(lk)), np.asarray(sj.damping_matrix(lk))
    if model == "demo":
        assert np.abs(D).max() > 0 and K[0, 0] == pytest.approx(20.0)
    t = 0.3
    for i, (q, qd) in enumerate(_random_states(lk, seed=5)):
        M, f = sj.equations_of_motion(lk, q, qd, t)
        F = np.asarray(sj.generalized_external_force(lk, q, qd, t))
        Cqd = np.asarray(sj.coriolis_force(lk, q, qd))
        qn, qdn = np.asarray(q), np.asarray(qd)
        expected = F - Cqd - K @ qn - D @ qdn
        err = np.linalg.norm(np.asarray(f) - expected) / np.linalg.norm(expected)
        assert err < 1e-10, f"{model} q#{i}: f vs F - C qd - K q - D qd rel {err:.1e}"
        M_ref = np.asarray(sj.mass_matrix(lk, q))
        err_M = np.abs(np.asarray(M) - M_ref).max() / np.abs(M_ref).max()
        assert err_M < 1e-12, f"{model} q#{i}: M from equations_of_motion {err_M:.1e}"


# ------------------------------------------------- 2. energy of the free-fall rod
@pytest.fixture(scope="module")
def free_fall_energy_runs(jit_optimised):
    """Free-fall rod from the 1 rad/m pre-bend at rest, 5 s, without and with material
    damping (eta = 1e4 Pa s): same structure, one compiled simulate (at -O2: ~10^4
    explicit steps)."""

    @jit_optimised
    def run(rod, q0):
        return sj.simulate(
            rod, 5.0, q0, solver=SOLVER, rtol=1e-8, atol=1e-10, n_save=101, throw=False
        )

    runs = {}
    for eta in (0.0, 1e4):
        rod = free_fall_rod(eta=eta)
        q0 = free_fall_q0(rod)
        traj = run(rod, q0)
        assert traj.result == sj.RESULTS.successful
        runs[eta] = (rod, traj, *_energies(rod, traj))
    return runs


def test_free_fall_rod_conserves_energy(free_fall_energy_runs):
    """Without damping the total energy of the 12-DoF free-fall rod stays constant.

    Reference: E = T + U_g + U_e is an exact invariant of the semi-discrete equations
    (same quadrature in energies and forces), so only the integrator changes it.
    Tolerance (issue): drift < 1e-6 relative over 5 s, measured against the energy
    exchanged (the largest kinetic energy, ~0.1 J, about |E(0)|; the gravitational
    zero is arbitrary, the exchanged energy is not). Dopri8 at rtol 1e-8 gives ~6e-9.
    """
    _, traj, E, T = free_fall_energy_runs[0.0]
    assert T.max() > 0.5 * abs(E[0]), "the rod must actually swing (T_max vs |E0|)"
    drift = np.abs(E - E[0]).max() / T.max()
    assert drift < 1e-6, f"energy drift {drift:.2e} of T_max = {T.max():.3e} J"


def test_free_fall_rod_with_damping_never_gains_energy(free_fall_energy_runs):
    """With Kelvin-Voigt damping (eta = 1e4 Pa s) the energy never increases.

    Reference: dE/dt = -qd^T D qd <= 0 (D symmetric positive semi-definite).
    Tolerance: between save times E may rise by at most 1e-7 of the initial energy
    scale |E(0)|: integration error alone (measured ~1e-8 of the scale for the
    undamped run at the same tolerances) must not be read as energy gain. The rod
    must also lose a sizeable part (> 10 %) of the energy available to it, so the
    test fails if damping is ignored.
    """
    _, traj, E, _ = free_fall_energy_runs[1e4]
    _, _, E_free, _ = free_fall_energy_runs[0.0]
    scale = abs(E[0])
    rise = np.diff(E).max() / scale
    assert rise < 1e-7, f"energy rose by {rise:.2e} of |E0| between two saves"
    lost = (E[0] - E[-1]) / (E[0] - E_free.min() + abs(E[0]))
    assert E[-1] < E[0] - 0.1 * scale, f"damped rod lost only {lost:.2e}"


# ------------------------------------------------ 3. cantilever bending frequencies
def test_default_solver_on_the_damped_free_fall_rod(free_fall_energy_runs):
    """simulate's defaults on the damped free-fall rod: ROS34PW2 at rtol 1e-3.

    "auto" picks the Rosenbrock-W solver here (the fastest eigenvalue, -7959 1/s,
    is a damped mode) and Tsit5 on the undamped rod (purely oscillatory) or at a
    tight rtol. Reference: the Dopri8 run at rtol 1e-8 (tip error ~1e-8 L). Tip
    error over 5 s measured 4.7e-5 L; tolerance 2e-4 L (the accuracy the defaults are
    chosen for; their speed: benchmarks/dynamics.py). Energy: never rises by more
    than 1e-6 of |E0| between saves (measured: falls at every save).
    """
    rod, ref, _, _ = free_fall_energy_runs[1e4]
    q0 = free_fall_q0(rod)
    assert sj.integrate.auto_solver(rod, q0, 0.0, 5.0, 1e-3) == "ros34pw2"
    assert sj.integrate.auto_solver(rod, q0, 0.0, 5.0, 1e-8) == "tsit5"
    undamped = free_fall_energy_runs[0.0][0]
    assert sj.integrate.auto_solver(undamped, q0, 0.0, 5.0, 1e-3) == "tsit5"
    traj = sj.simulate(rod, 5.0, q0, n_save=101)
    assert traj.solver == "RosenbrockW" and traj.result == sj.RESULTS.successful
    L = 0.5
    err = float(jnp.abs(traj.tip_positions(rod) - ref.tip_positions(rod)).max()) / L
    assert err < 2e-4, f"tip error {err:.2e} L at the default tolerances"
    E, _ = _energies(rod, traj)
    rise = np.diff(E).max() / abs(E[0])
    assert rise < 1e-6, f"energy rose by {rise:.2e} of |E0| between two saves"


def test_cantilever_frequencies_match_euler_bernoulli():
    """First two small-amplitude bending frequencies of a slender cantilever.

    Reference: Euler-Bernoulli, omega_k = (beta_k L)^2 sqrt(EI / (rho A L^4)) with
    beta L = 1.8751, 4.6941 (tests/references.py). Small-amplitude limit: the
    generalised eigenproblem K v = omega^2 M(0) v (scipy.linalg.eigh).
    Model: L = 1 m, r = 5 mm (L / r = 200), bending about z only (no shear or
    extension coordinates: Euler-Bernoulli kinematics), curvature of Legendre order 5.
    Error budget: rotary inertia (rho I in M_s, absent from Euler-Bernoulli) lowers
    omega_k by about (beta_k r_g)^2 / 2 with r_g = r / 2: 1.1e-5 and 6.9e-5;
    Rayleigh-Ritz truncation at order 5 raises them by < 2e-5 (orders 5 and 8 agree
    to that). Measured -1.5e-5 and -1.1e-4. Tolerance (issue): 0.5 %.
    """
    E, r, L, rho = 1e7, 0.005, 1.0, 1000.0
    lk = cantilever(L, r, E, modes=(0, 0, 1, 0, 0, 0), order=5, rho=rho)
    K = np.asarray(sj.stiffness_matrix(lk))
    M = np.asarray(sj.mass_matrix(lk, jnp.zeros(lk.n_dof)))
    omega = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)[:2])
    ref = cantilever_natural_frequencies(E, math.pi * r**4 / 4, rho, math.pi * r**2, L)
    err = omega / ref[:2] - 1.0
    assert np.all(np.abs(err) < 5e-3), (
        f"omega {omega} rad/s vs Euler-Bernoulli {ref[:2]}: rel errors {err}"
    )


# --------------------------------------------------------------- 4. rigid pendulum
def test_rigid_pendulum_period_matches_elliptic_integral():
    """A rigid bar on a revolute joint released from 60 degrees at rest.

    Reference: T = 4 sqrt(I_p / (m g d)) K(sin(theta0 / 2)) (tests/references.py)
    with d = L / 2 (RigidLink's CM is mid-length) and I_p = m (L^2 + w^2) / 12 + m d^2
    (cuboid inertia about the axis z, w the width along y, plus parallel axes).
    Measurement: simulate to T_ref / 4, where the exact angle from the vertical is 0
    and the speed w_max = sqrt(2 m g d (1 - cos theta0) / I_p); the angle theta left
    there shifts the crossing by theta / w_max, the period by 4 theta / w_max.
    Tolerance (issue): 1e-6 relative on the period; Dopri8 at rtol = atol = 1e-12.
    """
    L, h, w, rho = 0.4, 0.02, 0.03, 2700.0
    bar = sj.RigidLink(
        sj.Joint("R", axis=(0.0, 0.0, 1.0)),
        length=L,
        section=sj.RectangularSection(h, w),
        rho=rho,
    )
    lk = sj.Linkage([bar], gravity=(0.0, -G, 0.0))
    m, d = rho * L * h * w, L / 2
    I_p = m * (L**2 + w**2) / 12 + m * d**2
    theta0 = math.radians(60.0)
    T_ref = pendulum_period(d, G, theta0, inertia_about_pivot=I_p, mass=m)
    w_max = math.sqrt(2 * m * G * d * (1 - math.cos(theta0)) / I_p)
    q0 = jnp.array([theta0 - math.pi / 2])  # q = 0 is horizontal (+x), g along -y
    traj = sj.simulate(
        lk,
        T_ref / 4,
        q0,
        ts=jnp.array([T_ref / 4]),
        solver=SOLVER,
        rtol=1e-12,
        atol=1e-12,
    )
    theta = float(traj.q[-1, 0]) + math.pi / 2
    speed = -float(traj.qd[-1, 0])
    period_err = 4 * theta / (w_max * T_ref)
    assert abs(period_err) < 1e-6, (
        f"period rel error {period_err:.2e} (angle {theta:.2e} rad left at T_ref/4)"
    )
    assert abs(speed / w_max - 1) < 1e-6, f"speed {speed} vs w_max {w_max}"


# -------------------------------------------------------- 5. rigid double pendulum
DOUBLE = dict(m1=0.4, m2=0.25, L1=0.3, d1=0.15, d2=0.08, I1=4e-3, I2=1.5e-3, g=G)


def test_rigid_double_pendulum_matches_lagrange_reference():
    """Two rigid bars on revolute joints (z) under gravity -y, 2 s from a swing.

    Reference: Lagrange's equations for two rigid bars in absolute angles (derived in
    tests/references.py), integrated by scipy DOP853 at rtol = atol = 1e-12; its
    energy must be conserved to 1e-10 (a check on the derivation). Bar 2 has its CM
    off-centre (g_i = 8 cm, g_f = 17 cm) and given inertia; q1 = phi1, q2 = phi2 -
    phi1. Tolerance 1e-7 rad on both angles (issue): both integrators run at 1e-12,
    leaving room for the growth of errors over 2 s of this non-linear motion.
    """
    p = DOUBLE
    bar1 = sj.RigidLink(
        sj.Joint("R", axis=(0.0, 0.0, 1.0)),
        length=p["L1"],
        mass=p["m1"],
        inertia=np.diag([1e-4, 3e-3, p["I1"]]),
    )
    bar2 = sj.RigidLink(
        sj.Joint("R", axis=(0.0, 0.0, 1.0)),
        length=0.25,
        mass=p["m2"],
        inertia=np.diag([5e-5, 1e-3, p["I2"]]),
        g_i=sj.translation(p["d2"]),
        g_f=sj.translation(0.25 - p["d2"]),
    )
    lk = sj.Linkage([bar1, bar2], parents=(0, 1), gravity=(0.0, -G, 0.0))
    q0, qd0 = np.array([0.7 - math.pi / 2, 0.5]), np.array([0.5, -1.0])
    ts = np.linspace(0.0, 2.0, 21)
    y0 = [q0[0], q0[0] + q0[1], qd0[0], qd0[0] + qd0[1]]
    ref = rigid_double_pendulum(p, y0, ts)
    e = rigid_double_pendulum_energy(p, ref)
    assert np.abs(e - e[0]).max() < 1e-10 * np.abs(e).max(), "reference energy drift"
    traj = sj.simulate(lk, 2.0, q0, qd0, ts=ts, solver=SOLVER, rtol=1e-12, atol=1e-12)
    phi1 = np.asarray(traj.q[:, 0])
    phi2 = phi1 + np.asarray(traj.q[:, 1])
    err = max(np.abs(phi1 - ref[0]).max(), np.abs(phi2 - ref[1]).max())
    assert err < 1e-7, f"double pendulum angles off the scipy reference by {err:.2e}"
    assert np.ptp(ref[1]) > 1.0, "the motion must be large (non-linear regime)"


# ---------------------------------------------------------------- 6. hybrid chain
def test_hybrid_chain_conserves_energy(demo):
    """Rigid bar on a sprung revolute joint carrying a two-division soft rod (the demo
    linkage with its damping and its tip force switched off), under gravity.

    Reference: E = T + U_g + U_e (joint spring included in K) is invariant without
    damping and point wrenches. Tolerance: drift < 1e-6 of the largest kinetic
    energy over 1 s (Dopri8 at rtol 1e-8; measured ~1e-9). Same structure as the
    demo, so the mass matrix used for T is compiled once.
    """
    lk = eqx.tree_at(
        lambda l: (l.links[1].material.eta, l.point_wrenches[0].wrench),
        demo,
        (jnp.asarray(0.0), jnp.zeros(6)),
    )
    assert float(np.abs(np.asarray(sj.damping_matrix(lk))).max()) == 0.0
    q0 = jnp.array([0.6, 2.0, -1.0, 0.5, 1.0, -2.0, 1.0])
    qd0 = jnp.zeros(7).at[0].set(3.0)
    traj = sj.simulate(
        lk, 1.0, q0, qd0, solver=SOLVER, rtol=1e-8, atol=1e-10, n_save=51
    )
    E, T = _energies(lk, traj)
    drift = np.abs(E - E[0]).max() / T.max()
    assert drift < 1e-6, f"hybrid chain energy drift {drift:.2e} of T_max {T.max():.3e}"
    assert np.ptp(np.asarray(traj.q[:, 0])) > 0.1, "the joint must move"


# ------------------------------------------------------ 7. gradient through simulate
def _small_rod(E):
    """0.3 m rod, r 5 mm, bending about y with linear strain (2 DoF), gravity -z."""
    return cantilever(
        length=0.3,
        radius=0.005,
        E=E,
        modes=(0, 1, 0, 0, 0, 0),
        order=1,
        gravity=(0.0, 0.0, -G),
        n_gauss=6,
    )


def test_gradient_of_tip_through_simulate_matches_central_differences():
    """d(tip height at t = 0.3 s)/dE by reverse mode through simulate.

    Reference: central differences with step 1e-5 E, evaluated by the same compiled
    function (value_and_grad) so that one program serves both. Dopri8 with adaptive
    steps at rtol 1e-10: the step sequence does not change within +-1e-5 E, so both
    see the same discrete map; central-difference truncation ~(1e-5)^2 and roundoff
    ~1e-16 |z| / (1e-5 E |dz/dE|) are ~1e-10. Measured ~4e-10; tolerance 1e-6 (issue).
    """
    q0 = sj.strain_coordinates(_small_rod(1e6), [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])

    def tip_height(E):
        rod = _small_rod(E)
        traj = sj.simulate(
            rod, 0.3, q0, ts=jnp.array([0.3]), solver=SOLVER, rtol=1e-10, atol=1e-12
        )
        return sj.tip_pose(rod, traj.q[-1])[2, 3]

    f = jax.jit(jax.value_and_grad(tip_height))
    grad, fd, err = gradient_vs_central_difference(
        lambda E: f(jnp.asarray(E)), 1e6, 1e-5 * 1e6
    )
    assert err < 1e-6, f"dz/dE = {grad:.10e} vs central {fd:.10e}: {err:.1e}"


# ------------------------------------------------------------------ 8. bad input
def test_simulate_rejects_bad_input(free_fall):
    """Unknown solver name, q0 of the wrong shape, constant steps without dt0: each
    raises ValueError naming the offending argument (before anything compiles)."""
    with pytest.raises(ValueError, match="solver = 'rk45'"):
        sj.simulate(free_fall, 0.1, solver="rk45")
    with pytest.raises(ValueError, match=r"q0 has shape \(11,\)"):
        sj.simulate(free_fall, 0.1, jnp.zeros(11))
    with pytest.raises(ValueError, match=r"qd0 has shape \(3,\)"):
        sj.simulate(free_fall, 0.1, qd0=jnp.zeros(3))
    with pytest.raises(ValueError, match="dt0"):
        sj.simulate(free_fall, 0.1, solver=SOLVER, adaptive=False)
