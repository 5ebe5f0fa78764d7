"""Closed-loop joints: four-bar statics and dynamics, clamped-clamped buckling (float64).

References: the four-bar's analytic assembly (circle intersection) and its potential
energy along the one-dof motion (virtual work gives the crank torque); the
work-energy balance of the driven mechanism; Euler's clamped-clamped buckling load
4 pi^2 E I / L^2; joint motions that must satisfy their own closure exactly.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.model._precompute import precompute
from sorojax.statics import equilibrium_residual

A_CR, B_CO, C_RO, D_GR = 0.1, 0.35, 0.3, 0.4  # crank, coupler, rocker, ground [m]
SEC, RHO, G = 0.02, 1000.0, 9.81
Z = (0.0, 0.0, 1.0)


def _bar(length):
    return sj.RigidLink(
        sj.Joint("R", axis=Z),
        length=length,
        section=sj.RectangularSection(SEC, SEC),
        rho=RHO,
    )


def _four_bar(actuated=True):
    return sj.Linkage(
        [_bar(A_CR), _bar(B_CO), _bar(C_RO)],
        parents=[0, 1, 0],
        placements=[np.eye(4), np.eye(4), np.asarray(sj.translation(D_GR))],
        gravity=(0.0, -G, 0.0),
        closed_loops=[sj.ClosedLoopJoint(sj.Joint("R", axis=Z), 2, 3)],
        actuators=[sj.JointActuator(1, prescribed=True)] if actuated else (),
    )


def assemble(theta1):
    """Joint coordinates (crank, coupler relative, rocker) of the open-upward branch."""
    a = np.array([A_CR * math.cos(theta1), A_CR * math.sin(theta1)])
    c = np.array([D_GR, 0.0])
    dist = np.linalg.norm(c - a)
    x = (B_CO**2 - C_RO**2 + dist**2) / (2 * dist)
    h = math.sqrt(B_CO**2 - x**2)
    e = (c - a) / dist
    p = a + x * e + h * np.array([-e[1], e[0]])
    t2 = math.atan2(p[1] - a[1], p[0] - a[0])
    t3 = math.atan2(p[1] - c[1], p[0] - c[0])
    return np.array([theta1, t2 - theta1, t3])


def potential(theta1):
    """Gravitational energy of the three bars (CMs at mid-length), by hand."""
    q = assemble(theta1)
    m = [RHO * SEC * SEC * L for L in (A_CR, B_CO, C_RO)]
    t2 = q[0] + q[1]
    y1 = A_CR / 2 * math.sin(q[0])
    y2 = A_CR * math.sin(q[0]) + B_CO / 2 * math.sin(t2)
    y3 = C_RO / 2 * math.sin(q[2])
    return G * (m[0] * y1 + m[1] * y2 + m[2] * y3)


@pytest.fixture(scope="module")
def four_bar():
    return _four_bar()


def test_four_bar_statics_residual_redundancy_and_virtual_work_torque(four_bar):
    """Prescribed crank at 0.6 rad under gravity, started 0.01 rad off assembly.

    The planar loop's five rows have rank 2 (wx, wy, vz vanish identically): the
    solve must succeed and report it. Residual and constraint error at Newton's
    tolerance (< 1e-8); q equals the analytic assembly (1e-10); the crank torque
    equals dV/dtheta1 along the mechanism (central difference, step 1e-5:
    truncation ~1e-11, relative tolerance 1e-7).
    """
    th = 0.6
    sol = sj.solve_statics(four_bar, assemble(0.5) + 0.01, u=[th])
    assert sol.result == sj.RESULTS.successful
    assert float(sol.residual_norm) < 1e-8
    assert float(sol.constraint_error) < 1e-8
    assert int(sol.constraint_rank) == 2 and four_bar.n_constraints == 5
    np.testing.assert_allclose(np.asarray(sol.q), assemble(th), atol=1e-10)
    h = 1e-5
    tau = (potential(th + h) - potential(th - h)) / (2 * h)
    assert abs(float(sol.efforts[0]) - tau) < 1e-7 * abs(tau)


def test_four_bar_statics_derivatives_follow_the_loop(four_bar):
    """Implicit derivatives through a closed loop (the pseudo-inverse path).

    d(rocker angle)/d(theta1) from the analytic assembly and d(torque)/d(theta1) =
    d^2 V / d theta1^2 along the mechanism, both by central differences of the
    closed forms (steps 1e-5 and 1e-4: the second difference is good to ~1e-7
    relative, measured 8e-8), against forward mode (both) and reverse mode (the
    torque) through the solve: the root's derivative solves with the loop's last
    Jacobian (singular: the planar loop's redundant rows), the effort's adds its
    rows' slope along it (without that term the torque's derivative is 2x off).
    """
    th = 0.6

    def solve(t):
        sol = sj.solve_statics(four_bar, assemble(0.6), u=jnp.stack([t]), throw=False)
        return jnp.stack([sol.efforts[0], sol.q[2]])

    h, h2 = 1e-5, 1e-4
    want = np.array(
        [
            (potential(th + h2) - 2 * potential(th) + potential(th - h2)) / h2**2,
            (assemble(th + h)[2] - assemble(th - h)[2]) / (2 * h),
        ]
    )
    forward = np.asarray(jax.jit(jax.jacfwd(solve))(th))
    reverse = float(jax.jit(jax.grad(lambda t: solve(t)[0]))(th))
    np.testing.assert_allclose(forward, want, rtol=1e-6)
    assert abs(reverse - want[0]) < 1e-6 * abs(want[0])


def test_statics_q_is_one_small_newton_step_past_the_reported_iterate(four_bar):
    """Newton stops without an evaluation only to confirm convergence.

    The residual, efforts and loop error are those of its last iterate; q is that
    iterate plus a Newton step already within the tolerances (StaticsSolution's
    docstring). Started at the assembly for 1.0 rad with the crank prescribed at 0.6
    (a jump: two load increments), the last iterate's residual is ~1e-12. Re-evaluated
    at q, with the returned multipliers, the free rows' residual and the loop error are
    at least 1e3 times smaller (quadratic convergence: about the square of that step;
    floor 1e-14 for roundoff), so the step was taken; the crank row (the effort)
    equals the reported effort to 1e-9 relative (the step times the stiffness).
    """
    u = jnp.array([0.6])
    sol = sj.solve_statics(four_bar, assemble(1.0), u=u)
    assert sol.result == sj.RESULTS.successful
    qi, _ = four_bar.prescribed
    free = np.setdiff1d(np.arange(four_bar.n_dof), qi)

    @jax.jit  # one compile instead of op-by-op dispatch
    def at_q(q, lam):
        r = equilibrium_residual(four_bar, precompute(four_bar), q, u=u, mu=lam)
        return r, sj.closure_errors(four_bar, q)

    r, e = at_q(sol.q, sol.lam)
    assert float(jnp.abs(r[free]).max()) <= max(1e-3 * float(sol.residual_norm), 1e-14)
    assert float(jnp.abs(e).max()) <= max(1e-3 * float(sol.constraint_error), 1e-14)
    tau = float(sol.efforts[0])
    assert abs(float(r[qi][0]) - tau) <= 1e-9 * abs(tau)


def test_four_bar_driven_dynamics_drift_and_work_energy_balance(four_bar):
    """Crank driven at pi t / 2 for 5 s from rest: constraint drift and power balance.

    Drift of the loop (Baumgarte, T_bs = 0.01 s, rtol 1e-8) stays below 1e-6 [rad, m];
    the work of the crank torque int tau theta1' dt equals the change of kinetic +
    gravitational energy (trapezoid on 1001 saves: ~1e-6 relative; tolerance 1e-4 of
    the energy swing).
    """
    w = math.pi / 2
    tr = sj.simulate(
        four_bar,
        5.0,
        assemble(0.0),
        u=lambda t: jnp.array([w * t]),
        rtol=1e-8,
        atol=1e-10,
        n_save=1001,
    )
    assert tr.result == sj.RESULTS.successful
    e = jax.vmap(lambda q: sj.closure_errors(four_bar, q))(tr.q)
    assert float(jnp.abs(e).max()) < 1e-6
    # the Trajectory's batched queries are the same functions (to rounding)
    np.testing.assert_allclose(tr.closure_errors(four_bar), e, rtol=0, atol=1e-15)
    E = np.asarray(
        jax.vmap(lambda q, qd: sj.total_energy(four_bar, q, qd))(tr.q, tr.qd)
    )
    np.testing.assert_allclose(tr.energies(four_bar)[:, 3], E, rtol=1e-12, atol=1e-14)
    P = np.asarray(tr.efforts[:, 0]) * w
    t = np.asarray(tr.t)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(t))])
    swing = E.max() - E.min()
    assert np.abs((E - E[0]) - work).max() < 1e-4 * swing


@pytest.mark.slow  # a second ~40 s dynamics compile; the driven case covers drift
def test_four_bar_free_motion_conserves_energy():
    """Unactuated four-bar swinging under gravity (1 s): energy and loop both kept.

    No damping: total energy constant to the integrator's tolerance (1e-7 relative
    at rtol 1e-9); drift below 1e-8.
    """
    lk = _four_bar(actuated=False)
    tr = sj.simulate(lk, 1.0, assemble(0.3), rtol=1e-9, atol=1e-11, n_save=51)
    E = np.asarray(jax.vmap(lambda q, qd: sj.total_energy(lk, q, qd))(tr.q, tr.qd))
    assert np.abs(E - E[0]).max() < 1e-7 * abs(E[0])
    e = jax.vmap(lambda q: sj.closure_errors(lk, q))(tr.q)
    assert float(jnp.abs(e).max()) < 1e-8
    assert np.abs(np.asarray(tr.q[:, 0]) - 0.3).max() > 0.05  # it really moved


# ------------------------------------------------------------------------ buckling
E_B, R_B, L_B = 1e6, 0.005, 0.4
EI_B = E_B * math.pi * R_B**4 / 4


def test_clamped_clamped_rod_buckles_at_euler_load():
    """Clamped base; tip held by a prismatic closure along x to a world frame at L.

    Inextensible rod bending about z (Legendre order 8). Under an axial dead load P
    the tangent stiffness is K - P G (the closure reaction is zero on the straight
    rod); restricted to the null space of the constraint Jacobian A (5 rows, rank 2:
    a planar rod), the lowest generalised eigenvalue is the buckling load, within 1%
    of 4 pi^2 E I / L^2 (measured: well inside; the mode is cos(2 pi s / L)).
    """
    rod = sj.SoftLink(
        [
            sj.Division(
                L_B, sj.CircularSection(R_B), sj.LegendreBasis((0, 0, 1, 0, 0, 0), 8)
            )
        ],
        sj.Material(E_B),
    )

    def linkage(P):
        return sj.Linkage(
            rod,
            point_wrenches=[
                sj.PointWrench(1, jnp.stack([0.0, 0.0, 0.0, -P, 0.0, 0.0]))
            ],
            closed_loops=[
                sj.ClosedLoopJoint(
                    sj.Joint("P", axis=(1.0, 0.0, 0.0)), 1, 0, g_B=sj.translation(L_B)
                )
            ],
        )

    q0 = jnp.zeros(rod.n_dof)

    @jax.jit
    def tangent(P):
        lk = linkage(P)
        data = precompute(lk)
        mu = jnp.zeros(lk.n_constraints)
        return jax.jacfwd(lambda q: equilibrium_residual(lk, data, q, mu=mu))(q0)

    K0 = np.asarray(tangent(0.0))
    G1 = K0 - np.asarray(tangent(1.0))  # K_t(P) = K0 - P G1
    lk = linkage(1.0)
    assert float(jnp.abs(sj.closure_errors(lk, q0)).max()) < 1e-15
    A = np.asarray(sj.constraint_jacobian(lk, q0))
    u, s, vt = np.linalg.svd(A)
    rank = int(np.sum(s > 1e-9 * s[0]))
    assert rank == 2
    Zn = vt[rank:].T
    Kr, Gr = Zn.T @ K0 @ Zn, Zn.T @ G1 @ Zn
    Kr, Gr = 0.5 * (Kr + Kr.T), 0.5 * (Gr + Gr.T)
    lam = np.linalg.eigvals(np.linalg.solve(Kr, Gr))  # 1 / P_critical
    P_cr = 1.0 / np.max(lam.real)
    P_euler = 4 * math.pi**2 * EI_B / L_B**2
    assert abs(P_cr - P_euler) < 0.01 * P_euler, f"{P_cr=} vs {P_euler=}"


# ------------------------------------------------------------------ every joint type
@pytest.mark.parametrize("kind", ["R", "P", "H", "C", "A", "S"])
def test_closure_of_every_joint_type_holds_along_its_own_motion(kind):
    """A free-floating link at pose exp(Phi q_j), closed to the ground by a joint of
    that type: the closure holds (roundoff) for any q_j, and its Jacobian with respect
    to all six free coordinates has full row rank 6 - n_joint_dof (the constrained
    directions are independent, none spurious)."""
    kw = {"pitch": 0.05} if kind == "H" else {}
    joint = sj.Joint(kind, axis=(0.0, 0.6, 0.8), **kw)
    link = sj.RigidLink(
        sj.Joint("F"), length=0.1, g_i=np.eye(4), g_f=np.eye(4), mass=1.0
    )
    lk = sj.Linkage([link], closed_loops=[sj.ClosedLoopJoint(joint, 1, 0)])
    q_j = np.random.default_rng(3).uniform(-0.8, 0.8, joint.n_dof)
    q = jnp.asarray(np.asarray(joint.basis()) @ q_j)
    assert float(jnp.abs(sj.closure_errors(lk, q)).max()) < 1e-14
    A = np.asarray(sj.constraint_jacobian(lk, q))
    assert A.shape == (6 - joint.n_dof, 6)
    assert np.linalg.matrix_rank(A, tol=1e-9) == 6 - joint.n_dof
    # and a step off the joint's motion breaks it
    assert float(jnp.abs(sj.closure_errors(lk, q + 1e-3 * A[0])).max()) > 1e-5


def test_universal_closure_holds_for_a_cardan_pair_of_rotations():
    """Two zero-length revolute links (about y, then z) realise R_y(a) R_z(b); a
    universal closure (free axes y, z) to the ground holds for all (a, b) (exact
    error u . R v = 0), and an extra twist about x breaks it."""

    def pivot(axis, joint="R"):
        return sj.RigidLink(
            sj.Joint(joint, axis=axis),
            length=0.1,
            g_i=np.eye(4),
            g_f=np.eye(4),
            mass=1.0,
        )

    lk = sj.Linkage(
        [pivot((0.0, 1.0, 0.0)), pivot((0.0, 0.0, 1.0)), pivot((1.0, 0.0, 0.0))],
        closed_loops=[sj.ClosedLoopJoint(sj.Joint("U", axis=(1.0, 0.0, 0.0)), 3, 0)],
    )
    assert lk.n_constraints == 4
    for a, b in [(0.4, -0.9), (1.2, 0.7)]:
        e = sj.closure_errors(lk, jnp.array([a, b, 0.0]))
        assert float(jnp.abs(e).max()) < 1e-15
        e = sj.closure_errors(lk, jnp.array([a, b, 0.05]))
        assert float(jnp.abs(e).max()) > 1e-3


def test_large_prescribed_jump_is_load_stepped(four_bar):
    """From the assembly at 0 to a prescribed crank angle of 1.5 rad in one call: the
    automatic schedule counts the prescribed jump (one full-size Newton step from so
    far diverges), and lands on the analytic assembly (1e-10)."""
    sol = sj.solve_statics(four_bar, assemble(0.0), u=[1.5])
    assert sol.result == sj.RESULTS.successful
    np.testing.assert_allclose(np.asarray(sol.q), assemble(1.5), atol=1e-10)


@pytest.mark.parametrize("kind", ["R", "P", "H", "U", "C", "A", "S", "N"])
def test_constraint_terms_from_kinematics_equal_autodiff(kind):
    """The dynamics' A and Adot qd from the body Jacobians, twists and rates, and the
    statics' A^T mu from tip wrenches, equal forward-mode autodiff of e(q) (twice) on
    a two-link chain closed to a third link's tip (frames with offsets), at a random
    state. Both are exact: roundoff, 1e-12 of the largest entry."""
    from sorojax.dynamics._constraints import (
        constraint_terms,
        constraint_terms_from_kinematics,
    )
    from sorojax.kinematics._recursion import kinematics_and_rates
    from sorojax.model._precompute import precompute

    kw = {"pitch": 0.05} if kind == "H" else {}
    bar = sj.RigidLink(sj.Joint("F"), length=0.2, mass=1.0)
    arm = sj.RigidLink(sj.Joint("S"), length=0.3, mass=1.0)
    off = np.asarray(sj.translation(0.01, 0.02, -0.03))
    lk = sj.Linkage(
        [bar, arm, sj.RigidLink(sj.Joint("U", axis=(0, 0, 1)), 0.1, mass=1.0)],
        parents=(0, 1, 0),
        closed_loops=[
            sj.ClosedLoopJoint(sj.Joint(kind, axis=(0.0, 0.6, 0.8), **kw), 2, 3, off)
        ],
    )
    rng = np.random.default_rng(7)
    q = jnp.asarray(rng.normal(size=lk.n_dof) * 0.5)
    qd = jnp.asarray(rng.normal(size=lk.n_dof))
    mu = jnp.asarray(rng.normal(size=lk.n_constraints))

    @jax.jit  # one program for the three (one compile per joint type)
    def terms(q, qd, mu):
        data = precompute(lk)
        ref = constraint_terms(lk, data, q, qd)
        got = constraint_terms_from_kinematics(lk, *kinematics_and_rates(data, q, qd))
        # The statics maps the multipliers as tip wrenches: A^T mu without forming A.
        force = equilibrium_residual(
            lk, data, q, mu=jnp.zeros_like(mu)
        ) - equilibrium_residual(lk, data, q, mu=mu)
        return ref, got, force

    ref, got, force = terms(q, qd, mu)
    ref, got = (*ref, ref[1].T @ mu), (*got, force)
    for name, a, b in zip(("e", "A", "Adot qd", "A^T mu"), ref, got, strict=True):
        scale = max(float(jnp.abs(a).max()), 1e-12)
        err = float(jnp.abs(a - b).max()) / scale
        assert err < 1e-12, f"{kind}: {name} differs by {err:.1e} (relative)"


def test_baumgarte_time_is_a_parameter_of_one_program(four_bar):
    """At rest off the assembled shape the loop rows ask ``A qdd = -e / T^2``
    (Baumgarte, qd = 0): for two times T through one compiled program (T is an
    array, not structure), and d(A qdd)/dT = 2 e / T^3 by autodiff."""
    q = jnp.asarray(assemble(0.3)) + jnp.array([0.0, 0.02, -0.01])
    qd = jnp.zeros(3)
    u = jnp.array([0.3])  # the crank where q has it: its row is satisfied
    A = np.asarray(sj.constraint_jacobian(four_bar, q))
    e = np.asarray(sj.closure_errors(four_bar, q))
    assert np.abs(e).max() > 1e-3  # off the assembly

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def rows(lk):
        return jnp.asarray(A) @ sj.forward_dynamics(lk, q, qd, u=u)

    for T in (0.01, 0.05):
        lk = eqx.tree_at(lambda m: m.baumgarte_time, four_bar, jnp.asarray(T))
        # exact rows: 1e-9 of |e| / T^2 (the solve's 1e-10 regularisation)
        np.testing.assert_allclose(
            np.asarray(rows(lk)), -e / T**2, atol=1e-9 * np.abs(e).max() / T**2
        )

    def rows_of_T(T):
        return rows(eqx.tree_at(lambda m: m.baumgarte_time, four_bar, T))

    T = 0.02
    d = np.asarray(jax.jacfwd(rows_of_T)(jnp.asarray(T)))
    np.testing.assert_allclose(d, 2 * e / T**3, atol=1e-6 * np.abs(e).max() / T**3)


def test_four_bar_and_slider_crank_are_one_structure():
    """examples/mechanisms.py's two linkages differ in values only (the third
    joint revolute about z or prismatic along x, the loop's g_B), so they share
    every compiled program (the example compiles its integration once)."""
    from sorojax._mechanisms import four_bar as fb
    from sorojax._mechanisms import slider_crank as sc

    a, b = fb(), sc()
    assert jax.tree.structure(a) == jax.tree.structure(b)
    assert [x.shape for x in jax.tree.leaves(a)] == [
        x.shape for x in jax.tree.leaves(b)
    ]
    assert (a.links[2].joint.kind, b.links[2].joint.kind) == ("R", "P")
