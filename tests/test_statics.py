"""Statics against analytic and independent numerical references (float64).

References: exact circle under an end moment; Bisshopp-Drucker elliptic-integral large
deflections (tests/references.py, cross-checked there against shooting); Timoshenko
beam; scipy BVP solutions of the planar Cosserat rod for self-weight sag, with and
without a rigid tip body; joint stiffness; branched independence; implicit gradients.
"""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
from references import (
    cosserat_planar_static,
    cosserat_planar_static_with_rigid_tip_body,
    elastica_cantilever_tip_load,
    timoshenko_cantilever_tip_deflection,
)

import sorojax as sj
from sorojax.scenes import cantilever

PLANAR_Z = (0, 0, 1, 0, 0, 0)  # bending about z: a +y tip force bends in the x-y plane


def tip_xy(linkage, q):
    g = sj.tip_pose(linkage, q)
    return np.asarray(g[:3, 3])


# ----------------------------------------------------------------- end moment circle
@pytest.mark.parametrize(
    "follower, solver",
    [
        (False, None),
        (True, None),
        (False, optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12)),
    ],
    ids=["dead-newton", "follower-newton", "dead-levenberg-marquardt"],
)
def test_end_moment_gives_exact_circle(follower, solver):
    """Also with a user's optimistix solver (least squares) in place of Newton."""
    E, r, L = 1e6, 0.01, 0.5
    EI = E * math.pi * r**4 / 4
    M = 0.8 * EI / L * math.pi  # bends through 0.8 pi
    rod = sj.SoftLink(
        [sj.Division(L, sj.CircularSection(r), sj.LegendreBasis(PLANAR_Z, 0))],
        sj.Material(E),
    )
    lk = sj.Linkage(
        [rod], point_wrenches=[sj.PointWrench(1, [0, 0, M, 0, 0, 0], follower=follower)]
    )
    sol = sj.solve_statics(lk, solver=solver)
    k = M / EI
    expected = np.array([math.sin(k * L) / k, (1 - math.cos(k * L)) / k, 0.0])
    got = tip_xy(lk, sol.q)
    # Constant curvature is exactly representable and Magnus is exact for it: roundoff.
    err = np.linalg.norm(got - expected) / np.linalg.norm(expected)
    assert err < 1e-8, f"tip off the circle of curvature M/EI: rel error {err:.2e}"


# ------------------------------------------------ large deflection (elliptic integrals)
E_EL, R_EL, L_EL = 1e7, 0.01, 1.0
I_EL = math.pi * R_EL**4 / 4


def _elastica_linkage(order, alpha, n_gauss=None):
    P = alpha * E_EL * I_EL / L_EL**2
    return cantilever(
        L_EL,
        R_EL,
        E_EL,
        modes=PLANAR_Z,
        order=order,
        n_gauss=n_gauss,
        tip_wrench=jnp.array([0.0, 0, 0, 0, P, 0]),
    )


def _elastica_error(order, alpha, n_gauss=None):
    lk = _elastica_linkage(order, alpha, n_gauss)
    sol = sj.solve_statics(lk, load_steps=4)
    x, y, _ = tip_xy(lk, sol.q)
    xr, yr, _ = elastica_cantilever_tip_load(alpha)
    # Relative errors of the two tip displacements (vertical, horizontal).
    return abs(y - yr) / yr, abs((1 - x) - (1 - xr)) / (1 - xr)


@pytest.mark.parametrize("alpha", [1.0, 2.0, 5.0, 10.0])
def test_large_deflection_matches_elliptic_integrals(alpha):
    ey, ex = _elastica_error(8, alpha)
    # Order-8 Legendre curvature: the elastica curvature is smooth, so 1e-4 holds
    # with margin (measured ~1e-5 at alpha = 10).
    assert ey < 1e-4 and ex < 1e-4, (
        f"alpha={alpha}: tip deflection rel errors vertical {ey:.2e}, horizontal {ex:.2e}"
    )


def test_large_deflection_error_falls_with_order():
    # Fixed fine quadrature (30 points) so that the basis order, not the Magnus step,
    # sets the error.
    errs = [max(_elastica_error(order, 5.0, n_gauss=30)) for order in (2, 4, 6)]
    assert errs[0] > errs[1] > errs[2], f"errors for orders 2, 4, 6: {errs}"
    # Spectral convergence: tripling the order must cut the error by at least 10x.
    assert errs[2] < errs[0] / 10, f"errors for orders 2, 4, 6: {errs}"


# ------------------------------------------------------------------- Timoshenko beam
def test_short_thick_beam_matches_timoshenko():
    E, nu, r, L = 1e7, 0.3, 0.02, 0.1  # L / r = 5: shear matters
    G = E / (2 * (1 + nu))
    A, I = math.pi * r**2, math.pi * r**4 / 4
    P = 1e-5 * E * I / L**2  # small load: linear regime
    rod = sj.SoftLink(
        [
            sj.Division(
                L, sj.CircularSection(r), sj.LegendreBasis((1, 1, 1, 1, 1, 1), 1)
            )
        ],
        sj.Material(E, poisson=nu),
    )
    lk = sj.Linkage([rod], point_wrenches=[sj.PointWrench(1, [0, 0, 0, 0, P, 0])])
    sol = sj.solve_statics(lk)
    y = tip_xy(lk, sol.q)[1]
    k = 6 * (1 + nu) / (7 + 6 * nu)  # Cowper's shear coefficient of the circle
    ref = timoshenko_cantilever_tip_deflection(P, L, E, k * G, A, I)
    # Linear curvature and constant shear are exact in an order-1 basis; the remaining
    # difference is geometric nonlinearity of order (P L^2/EI)^2 = 1e-10.
    assert abs(y - ref) / ref < 1e-3, f"tip deflection {y:.6e} vs Timoshenko {ref:.6e}"
    shear_part = P * L / (k * G * A)
    assert shear_part / ref > 0.05, "the test must exercise shear (>5% of deflection)"


# --------------------------------------------------------- self-weight vs scipy BVP
SAG = dict(L=0.5, r=0.01, E=5e7, nu=0.5, rho=1000.0)


def _sag_rod(order, n_gauss=None):
    p = SAG
    basis = sj.LegendreBasis((0, 0, 1, 1, 1, 0), order)
    return sj.SoftLink(
        [sj.Division(p["L"], sj.CircularSection(p["r"]), basis, n_gauss=n_gauss)],
        sj.Material(p["E"], poisson=p["nu"], rho=p["rho"]),
    )


def _sag_reference(**kw):
    p = SAG
    A, I = math.pi * p["r"] ** 2, math.pi * p["r"] ** 4 / 4
    G = p["E"] / (2 * (1 + p["nu"]))
    k = 6 * (1 + p["nu"]) / (7 + 6 * p["nu"])  # Cowper's shear coefficient
    return dict(
        L=p["L"], E=p["E"], G=k * G, A=A, I=I, rho=p["rho"], g_vec=(0.0, -9.81), **kw
    )


def test_self_weight_sag_matches_cosserat_bvp():
    lk = sj.Linkage([_sag_rod(6)], gravity=(0.0, -9.81, 0.0))
    sol = sj.solve_statics(lk)
    got = tip_xy(lk, sol.q)[:2]
    ref = cosserat_planar_static(**_sag_reference(extensible=True, shearable=True))
    expected = np.asarray(ref["tip"][:2])
    # Polynomial strains of order 6 resolve the smooth sag; 1e-5 relative (the statics' accuracy bar).
    err = np.linalg.norm(got - expected) / np.linalg.norm(expected)
    assert err < 1e-5, f"self-weight tip {got} vs BVP {expected}: rel error {err:.2e}"
    assert expected[1] < -0.02 * SAG["L"], "the sag must be a visible deflection"


def test_rod_with_rigid_tip_body_matches_cosserat_bvp():
    m, c = 0.05, 0.05  # 50 g body, CM 5 cm beyond the rod tip along its tangent
    body = sj.RigidLink(sj.Joint("N"), length=2 * c, mass=m, inertia=1e-6 * np.eye(3))
    lk = sj.Linkage([_sag_rod(6), body], gravity=(0.0, -9.81, 0.0))
    sol = sj.solve_statics(lk)
    g = sj.forward_kinematics(lk, sol.q)
    cm = np.asarray(g[lk.layout.links[1].cm_point, :3, 3])[:2]
    rod_tip = np.asarray(g[lk.layout.links[0].tip_point, :3, 3])[:2]
    ref = cosserat_planar_static_with_rigid_tip_body(
        **_sag_reference(extensible=True, shearable=True),
        body_mass=m,
        body_com_offset=(c, 0.0),
    )
    exp_tip, exp_cm = np.asarray(ref["tip"][:2]), np.asarray(ref["cm"])
    err_tip = np.linalg.norm(rod_tip - exp_tip) / np.linalg.norm(exp_tip)
    err_cm = np.linalg.norm(cm - exp_cm) / np.linalg.norm(exp_cm)
    # Same discretisation as the self-weight test; 1e-5 relative.
    assert err_tip < 1e-5 and err_cm < 1e-5, (
        f"rod tip err {err_tip:.2e}, CM err {err_cm:.2e}"
    )


# ------------------------------------------------------------------- joint stiffness
def test_revolute_joint_settles_at_tau_over_k():
    k, tau = 2.5, 0.7
    link = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1), stiffness=k), length=0.3)
    lk = sj.Linkage([link], point_wrenches=[sj.PointWrench(1, [0, 0, tau, 0, 0, 0])])
    sol = sj.solve_statics(lk)
    # A pure moment about the joint axis: equilibrium k q = tau exactly.
    assert abs(float(sol.q[0]) - tau / k) < 1e-12, (
        f"q = {sol.q[0]} vs tau/k = {tau / k}"
    )


# ---------------------------------------------------------------- branched linkage
def _rot_z(a):
    c, s = math.cos(a), math.sin(a)
    g = np.eye(4)
    g[:2, :2] = [[c, -s], [s, c]]
    return g


def test_branched_statics_equals_branches_solved_alone():
    base = sj.RigidLink(sj.Joint("N"), length=0.1)

    def branch():
        return sj.SoftLink(
            [
                sj.Division(
                    0.3,
                    sj.CircularSection(0.01),
                    sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2),
                )
            ],
            sj.Material(1e7),
        )

    pl = [np.eye(4), _rot_z(0.5), _rot_z(-0.5)]
    grav = (0.0, 0.0, -9.81)
    full = sj.Linkage(
        [base, branch(), branch()],
        parents=(0, 1, 1),
        placements=jnp.asarray(np.stack(pl)),
        gravity=grav,
    )
    sol = sj.solve_statics(full)
    for k, idx in ((1, full.dof_slice(2)), (2, full.dof_slice(3))):
        alone = sj.Linkage(
            [base, branch()],
            parents=(0, 1),
            placements=jnp.asarray(np.stack([pl[0], pl[k]])),
            gravity=grav,
        )
        q_alone = sj.solve_statics(alone).q
        # The fixed base couples nothing: each branch's equilibrium is its own (roundoff).
        np.testing.assert_allclose(
            sol.q[idx],
            q_alone,
            atol=1e-10,
            err_msg=f"branch {k} q differs from solving it alone",
        )


# ---------------------------------------------------------------- solver reporting
def test_solver_failure_is_reported_not_nan():
    lk = _elastica_linkage(4, 10.0)
    sol = sj.solve_statics(lk, max_steps=1, throw=False)
    # One iteration cannot converge from the straight rod at P L^2/EI = 10.
    assert sol.result != sj.RESULTS.successful, "a 1-step solve must not report success"
    with pytest.raises(RuntimeError, match="did not converge"):
        sj.solve_statics(lk, max_steps=1, throw=True).q.block_until_ready()


# ------------------------------------------------------------- implicit gradients
def _tip_y_through_statics(E, r, P, throw=True, solver=None, order=4):
    lk = cantilever(
        1.0,
        r,
        E,
        modes=PLANAR_Z,
        order=order,
        tip_wrench=jnp.stack([0.0, 0.0, 0.0, 0.0, P, 0.0]),
    )
    q = sj.solve_statics(lk, solver=solver, throw=throw).q
    return sj.tip_pose(lk, q)[1, 3]


@functools.cache
def _tip_y_value_and_grad(solver=None):
    """One compiled value-and-gradient program per solver, shared by the tests."""
    return jax.jit(
        jax.value_and_grad(
            lambda x: _tip_y_through_statics(*x, throw=False, solver=solver)
        )
    )


def test_statics_gradients_match_central_differences():
    x0 = np.array([1e7, 0.01, 0.1])  # E [Pa], radius [m], tip load [N]: P L^2/EI ~ 1.3
    # One compiled program gives the gradient and, at shifted x, the differences.
    f = _tip_y_value_and_grad()
    y0, grad = f(jnp.asarray(x0))
    assert np.isfinite(float(y0))
    for i, name in enumerate(["E", "radius", "load"]):
        h = 1e-4 * x0[i]
        xp, xm = x0.copy(), x0.copy()
        xp[i] += h
        xm[i] -= h
        fd = (float(f(jnp.asarray(xp))[0]) - float(f(jnp.asarray(xm))[0])) / (2 * h)
        # Central differences: truncation ~ (1e-4)^2, solver noise ~1e-14 / 1e-4.
        rel = abs(float(grad[i]) - fd) / abs(fd)
        assert rel < 1e-6, (
            f"d tip_y / d {name}: autodiff {float(grad[i]):.8e} vs FD {fd:.8e}"
        )
    # With throw=False the differentiated program holds no host callback (JAX's
    # persistent cache refuses such programs): the implicit-function solve does not
    # throw either.
    jaxpr = jax.make_jaxpr(jax.grad(lambda x: _tip_y_through_statics(*x, throw=False)))(
        x0
    )
    assert "callback" not in str(jaxpr)


def test_implicit_gradient_reuses_newton_jacobian(monkeypatch):
    """The derivative solves with Newton's last Jacobian, to the solver's tolerance.

    That Jacobian is evaluated one converged step (|dx| <= 1e-10) before the root,
    so the implicit derivative must agree with one formed at the root itself (a user
    optimistix solver's path, which evaluates J there) to about that tolerance times
    the Jacobian's relative variation: 1e-8 leaves room for the two roots' own
    difference. And the differentiated program forms the residual's forward-mode
    Jacobian once (in the Newton loop), not again in the derivative.
    """
    x0 = jnp.asarray([1e7, 0.01, 0.1])  # P L^2 / EI ~ 1.3: a large deflection
    newton = optx.Newton(rtol=1e-12, atol=1e-12)
    g_loop = _tip_y_value_and_grad()(x0)[1]
    g_root = _tip_y_value_and_grad(newton)(x0)[1]
    np.testing.assert_allclose(g_loop, g_root, rtol=1e-8)

    calls = []
    jacfwd = jax.jacfwd
    monkeypatch.setattr(
        jax, "jacfwd", lambda *a, **k: calls.append(1) or jacfwd(*a, **k)
    )

    # order 2: a structure no other test traces (a cached trace calls nothing)
    jax.make_jaxpr(jax.grad(lambda x: _tip_y_through_statics(*x, False, order=2)))(x0)
    assert len(calls) == 1, f"{len(calls)} forward-mode Jacobians of the residual"


# ------------------------------------------------------- hooks, f(t) loads, reuse
def test_custom_wrench_hook_reproduces_gravity():
    p = SAG
    rhoA = p["rho"] * math.pi * p["r"] ** 2
    a = jnp.array([0.0, -9.81, 0.0])

    def hook(t, q, qd, kin):
        # Distributed weight per unit length, rotated into each body frame.
        f = rhoA * jnp.einsum("pji,j->pi", kin.g[:, :3, :3], a)
        return jnp.concatenate([jnp.zeros_like(f), f], axis=1)

    def hook_reading_J(t, q, qd, kin):
        # the same load; reading the Jacobians (times zero) makes statics map the
        # loads by J^T W instead of the backward wrench recursion
        return hook(t, q, qd, kin) + 0.0 * jnp.sum(kin.J, axis=2)

    with_hook = sj.Linkage([_sag_rod(6)], custom_wrench=hook)
    with_J = sj.Linkage([_sag_rod(6)], custom_wrench=hook_reading_J)
    with_grav = sj.Linkage([_sag_rod(6)], gravity=(0.0, -9.81, 0.0))
    q_h = sj.solve_statics(with_hook).q
    q_J = sj.solve_statics(with_J).q
    q_g = sj.solve_statics(with_grav).q
    # The same distributed load as a hook's and as gravity, and through the two
    # mappings (backward recursion, J^T W): equal to the solver's tolerance.
    np.testing.assert_allclose(q_h, q_g, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(q_J, q_g, rtol=1e-9, atol=1e-12)


def test_time_dependent_point_wrench_is_evaluated_at_t():
    k = 3.0
    link = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1), stiffness=k), length=0.3)
    ramp = sj.PointWrench(1, lambda t: jnp.stack([0.0, 0.0, 0.5 * t, 0.0, 0.0, 0.0]))
    lk = sj.Linkage([link], point_wrenches=[ramp])
    # Moment 0.5 t about the joint axis: q = 0.5 t / k.
    for t in (0.0, 1.0, 2.0):
        q = sj.solve_statics(lk, t=t).q
        assert abs(float(q[0]) - 0.5 * t / k) < 1e-12, f"t={t}: q={q[0]}"


def test_reused_link_builds_a_chain_of_copies():
    seg = sj.SoftLink(
        [sj.Division(0.25, sj.CircularSection(0.01), sj.LegendreBasis(PLANAR_Z, 0))],
        sj.Material(1e6),
    )
    lk = sj.Linkage([seg, seg, seg, seg])  # the same link object four times, in series
    assert lk.n_dof == 4
    EI = 1e6 * math.pi * 0.01**4 / 4
    M = 0.5 * math.pi * EI  # end moment bending the 1 m chain through pi/2
    lk = sj.Linkage([seg] * 4, point_wrenches=[sj.PointWrench(4, [0, 0, M, 0, 0, 0])])
    q = sj.solve_statics(lk).q
    # Each copy carries the same moment: a quarter of the total angle each, and the
    # tip lands on the circle of radius 2/pi through a quarter turn.
    np.testing.assert_allclose(q, np.full(4, math.pi / 8), atol=1e-12)
    R = 1 / (M / EI)
    np.testing.assert_allclose(tip_xy(lk, q)[:2], [R, R], atol=1e-12)
