"""Actuation: cables, joint actuators (wrench and prescribed), hooks (float64).

References: the exact constant-curvature arc of a cable at constant offset; the
pointwise equilibrium of an inextensible rod with a helical cable (the cable length is
a local functional of the strain, so the exact minimiser solves a 3 x 3 equation at
every s, solved here with scipy); hand-computed torques m g l cos(theta) and
I theta'' + m g l cos(theta); geometry of a straight external cable; central
differences for gradients.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

import sorojax as sj
from sorojax.dynamics._eom import mass_and_force
from sorojax.model._precompute import precompute

E, R_ROD, L_ROD = 1e6, 0.01, 0.5
POISSON = 0.5
EI = E * math.pi * R_ROD**4 / 4
GJ = E / (2 * (1 + POISSON)) * math.pi * R_ROD**4 / 2


def _rod(modes=(0, 1, 1, 0, 0, 0), order=0, n_gauss=None):
    return sj.SoftLink(
        [
            sj.Division(
                L_ROD,
                sj.CircularSection(R_ROD),
                sj.LegendreBasis(modes, order),
                n_gauss,
            )
        ],
        sj.Material(E, POISSON),
    )


# ------------------------------------------------------------------- constant offset
def test_cable_at_constant_offset_bends_rod_into_exact_arc():
    """Inextensible, unshearable rod: curvature (k_y, k_z) = (-T z, T y) / EI exactly.

    The cable length is int (1 - k_z y + k_y z) ds, so -T dl/dq is the constant end
    moment T (0, -z, y): constant curvature, represented exactly by an order-0 basis;
    the tip then lies on the circle of that curvature (roundoff).
    """
    y, z, T = 0.006, -0.004, 1.5
    lk = sj.Linkage(
        _rod(), actuators=[sj.Cable(sj.CableSpan(1, sj.ConstantPath(y, z)))]
    )
    sol = sj.solve_statics(lk, u=[T])
    assert sol.result == sj.RESULTS.successful
    xi = np.asarray(sj.screw_strains(lk, sol.q))
    rod_pts = lk.layout.point_kind == 2
    k_exp = np.array([0.0, -T * z / EI, T * y / EI])
    np.testing.assert_allclose(
        xi[rod_pts, :3], np.tile(k_exp, (rod_pts.sum(), 1)), rtol=1e-10, atol=1e-12
    )
    # Tip on the circle of curvature |k|, toward the cable side (centre along n x e1).
    # toward the cable's side (the centre lies along n x e1).
    k = np.linalg.norm(k_exp)
    n = k_exp / k  # rotation axis
    b = np.cross(n, [1.0, 0.0, 0.0])  # direction toward the centre of curvature
    expect = (
        np.array([1.0, 0.0, 0.0]) * math.sin(k * L_ROD) / k
        + b * (1 - math.cos(k * L_ROD)) / k
    )
    tip = np.asarray(sj.tip_pose(lk, sol.q)[:3, 3])
    np.testing.assert_allclose(tip, expect, atol=1e-12)


def test_actuation_matrix_is_minus_cable_length_gradient():
    """B = -dl/dq: autodiff column against central differences of the cable length.

    Step 1e-6 on O(1) coordinates, cable length ~0.5 m: truncation ~1e-12,
    roundoff ~1e-16 / 1e-6 = 1e-10: tolerance 1e-8 absolute.
    """
    cab = sj.Cable(sj.CableSpan(1, sj.ObliquePath((0.005, 0.0), (0.002, 0.003))))
    lk = sj.Linkage(_rod((1, 1, 1, 1, 0, 0), 1), actuators=[cab])
    q = jnp.asarray(np.random.default_rng(1).normal(size=lk.n_dof))
    B = np.asarray(sj.actuation_matrix(lk, q))[:, 0]
    h = 1e-6
    fd = np.array(
        [
            (sj.cable_lengths(lk, q + h * e)[0] - sj.cable_lengths(lk, q - h * e)[0])
            / (2 * h)
            for e in np.eye(lk.n_dof)
        ]
    )
    np.testing.assert_allclose(B, -fd, atol=1e-8)


# --------------------------------------------------------------------------- helical
def _helical_pointwise(radius, turns, T, s):
    """Exact local minimiser k(s) of 1/2 k^T C k + T |t(k, s)|, t the cable tangent.

    t = e1 + k x d + d' with d = radius (0, cos a, sin a), a = 2 pi turns s / L.
    """
    a = 2 * math.pi * turns * s / L_ROD
    d = radius * np.array([0.0, math.cos(a), math.sin(a)])
    dp = (
        radius
        * 2
        * math.pi
        * turns
        / L_ROD
        * np.array([0.0, -math.sin(a), math.cos(a)])
    )
    C = np.diag([GJ, EI, EI])

    def grad(k):
        t = np.array([1.0, 0.0, 0.0]) + np.cross(k, d) + dp
        # d|t|/dk = d x t_hat
        return C @ k + T * np.cross(d, t / np.linalg.norm(t))

    out = scipy.optimize.root(grad, np.zeros(3), tol=1e-13)
    # hybr may report slow progress once at roundoff: check the residual instead.
    assert np.abs(grad(out.x)).max() < 1e-12 * T * np.linalg.norm(d)
    return out.x


def test_helical_cable_couples_torsion_and_bending_like_pointwise_reference():
    """Helical cable (half a turn): torsion + bending from the Galerkin solve.

    With no gravity the equilibrium minimises int [1/2 k C k + T |t|] ds, local in
    k(s): the exact solution solves the pointwise 3 x 3 stationarity equations
    (scipy, independent of sorojax's kinematics). The Legendre Galerkin solution
    converges spectrally to it (measured max error / max |k|: 2e-1, 9e-3, 2e-4,
    2e-6, 1e-8 at orders 2..10): order 10 within 1e-7. Torsion is nonzero (coupling) and of the sign the
    pointwise solution gives.
    """
    radius, turns, T = 0.006, 0.5, 2.0
    cab = sj.Cable(sj.CableSpan(1, sj.HelicalPath(radius, turns)))
    lk = sj.Linkage(_rod((1, 1, 1, 0, 0, 0), 10), actuators=[cab])
    sol = sj.solve_statics(lk, u=[T])
    assert sol.result == sj.RESULTS.successful
    xi = np.asarray(sj.screw_strains(lk, sol.q))
    rod = lk.layout.point_kind == 2
    s = lk.layout.point_X1[rod] * L_ROD
    ref = np.array([_helical_pointwise(radius, turns, T, si) for si in s])
    scale = np.abs(ref).max()
    err = np.abs(xi[rod, :3] - ref).max() / scale
    assert err < 1e-7, f"helical cable strains off the pointwise reference by {err:.2e}"
    assert np.abs(ref[:, 0]).max() > 1e-3 * scale  # the reference really has torsion


# ----------------------------------------------------------------- external cable
def test_external_cable_between_anchors_gives_geometric_torque():
    """A straight cable from a ground anchor to a bar's tip: torque = -T dl/dtheta.

    Bar of length a on a revolute z joint at the origin, cable to the ground point
    p0: l = |a (cos th, sin th, 0) - p0|, dl/dth = a (p0_x sin th - p0_y cos th) / l.
    Statics with a torsion spring k: k th = -T dl/dth (residual at tolerance).
    """
    a, k, T = 0.3, 2.0, 4.0
    p0 = np.array([0.0, 0.4, 0.0])
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0), stiffness=k), length=a, mass=0.1)
    cab = sj.Cable([sj.CableAnchor(0, p0), sj.CableAnchor(1, at_tip=True)])
    lk = sj.Linkage([bar], actuators=[cab])
    th = 0.37
    ell = math.hypot(a * math.cos(th) - p0[0], a * math.sin(th) - p0[1])
    dl = a * (p0[0] * math.sin(th) - p0[1] * math.cos(th)) / ell
    assert abs(float(sj.cable_lengths(lk, jnp.array([th]))[0]) - ell) < 1e-14
    B = float(sj.actuation_matrix(lk, jnp.array([th]))[0, 0])
    assert abs(B + dl) < 1e-13
    sol = sj.solve_statics(lk, u=[T])
    th_s = float(sol.q[0])
    ell = math.hypot(a * math.cos(th_s) - p0[0], a * math.sin(th_s) - p0[1])
    dl = a * (p0[0] * math.sin(th_s) - p0[1] * math.cos(th_s)) / ell
    assert abs(k * th_s + T * dl) < 1e-9
    assert th_s > 0.1  # the cable pulls the tip up toward the anchor


# ----------------------------------------------------------------- joint actuators
M_BAR, L_BAR, G = 0.5, 0.3, 9.81
I_ZZ = 4e-3


def _arm_bar(stiffness=0.0):
    """The uniform bar on a revolute about z (joint stiffness [N m/rad])."""
    return sj.RigidLink(
        sj.Joint("R", axis=(0, 0, 1.0), stiffness=stiffness),
        length=L_BAR,
        mass=M_BAR,
        inertia=np.diag([1e-4, 3e-3, I_ZZ]),
    )


@pytest.fixture(scope="module")
def prescribed_arm():
    return sj.Linkage(
        [_arm_bar()],
        gravity=(0, -G, 0),
        actuators=[sj.JointActuator(1, prescribed=True)],
    )


@pytest.mark.parametrize("theta", [-math.pi / 4, 0.3, 1.2])
def test_prescribed_revolute_statics_returns_gravity_torque(prescribed_arm, theta):
    """Holding torque of a uniform bar: m g (L/2) cos(theta), exact (roundoff)."""
    sol = sj.solve_statics(prescribed_arm, u=[theta])
    assert sol.result == sj.RESULTS.successful
    assert abs(float(sol.q[0]) - theta) < 1e-14
    tau = M_BAR * G * L_BAR / 2 * math.cos(theta)
    assert abs(float(sol.efforts[0]) - tau) < 1e-12


def test_returned_effort_is_differentiable(prescribed_arm):
    """The efforts carry the solve's derivatives (forward and reverse):
    d/dtheta of m g (L/2) cos(theta) is -m g (L/2) sin(theta), exact (roundoff)."""

    def torque(th):
        return sj.solve_statics(prescribed_arm, u=jnp.stack([th])).efforts[0]

    th = 0.4
    exact = -M_BAR * G * L_BAR / 2 * math.sin(th)
    assert abs(float(jax.grad(torque)(th)) - exact) < 1e-12
    assert abs(float(jax.jacfwd(torque)(th)) - exact) < 1e-12


def test_effort_derivative_follows_the_free_coordinates():
    """d(effort)/d(theta) through a free joint whose equilibrium moves with theta.

    A prescribed revolute (angle theta) carries a bar and, on a sprung revolute (k),
    a second bar, under gravity: the second joint's angle phi(theta) moves with
    theta, so the holding torque's derivative is the explicit one plus the
    residual's slope times d(phi)/d(theta) (the solve's implicit derivative). Forward
    and reverse mode against central differences of the same solve (step 1e-5 rad:
    truncation ~1e-10, round-off ~1e-11 relative); the frozen-phi derivative differs
    from it by d(phi)/d(theta), which the test requires to be far from zero.
    """
    lk = sj.Linkage(
        [_arm_bar(), _arm_bar(stiffness=0.5)],
        gravity=(0, -G, 0),
        actuators=[sj.JointActuator(1, prescribed=True)],
    )

    def solve(th):
        sol = sj.solve_statics(lk, u=jnp.stack([th]), throw=False)
        return sol.efforts[0], sol.q[1]

    f = jax.jit(solve)
    th, h = 0.4, 1e-5
    fd = (np.asarray(f(th + h)) - np.asarray(f(th - h))) / (2 * h)  # (torque, phi)
    assert abs(fd[1]) > 0.05, f"d phi / d theta = {fd[1]}: the free joint barely moves"
    reverse = float(jax.jit(jax.grad(lambda t: solve(t)[0]))(th))
    forward = np.asarray(jax.jit(jax.jacfwd(solve))(th))
    for mode, got, want in (
        ("reverse, torque", reverse, fd[0]),
        ("forward, torque", forward[0], fd[0]),
        ("forward, phi", forward[1], fd[1]),
    ):
        assert abs(got - want) < 1e-7 * abs(want), f"{mode}: {got:.10e} vs {want:.10e}"


def test_prescribed_revolute_dynamics_follows_motion_and_returns_inverse_dynamics(
    prescribed_arm,
):
    """theta(t) = 0.3 sin 2t: the joint follows it and the effort is I th'' + m g l cos.

    I = I_zz + m (L/2)^2 about the joint. The prescribed coordinate is integrated
    from its exact derivative: agreement to solver tolerance (rtol 1e-10: 1e-9 rad);
    efforts are evaluated at the saved states: 1e-8 N m.
    """
    u = lambda t: jnp.array([0.3 * jnp.sin(2 * t)])  # noqa: E731
    tr = sj.simulate(prescribed_arm, 2.0, u=u, rtol=1e-10, atol=1e-12, n_save=41)
    t = np.asarray(tr.t)
    th = 0.3 * np.sin(2 * t)
    I_joint = I_ZZ + M_BAR * (L_BAR / 2) ** 2
    tau = I_joint * (-1.2 * np.sin(2 * t)) + M_BAR * G * L_BAR / 2 * np.cos(th)
    assert np.abs(np.asarray(tr.q[:, 0]) - th).max() < 1e-9
    assert np.abs(np.asarray(tr.efforts[:, 0]) - tau).max() < 1e-8
    np.testing.assert_allclose(np.asarray(tr.u[:, 0]), th, atol=1e-15)


def test_wrench_joint_actuator_is_a_generalized_force():
    """A torque tau on a sprung revolute joint (no gravity): theta = tau / k."""
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0), stiffness=3.0), length=0.2)
    lk = sj.Linkage([bar], actuators=[sj.JointActuator(1)])
    sol = sj.solve_statics(lk, u=[0.6])
    assert abs(float(sol.q[0]) - 0.2) < 1e-12
    assert sol.efforts.shape == (0,)


# -------------------------------------------------------------------------- hooks
def test_custom_actuation_equals_equivalent_cable():
    """Internal wrench (0, -T z, T y, -T, 0, 0) per unit length = constant-offset cable.

    For a straight-in-reference inextensible rod the cable's internal wrench is
    T (t x d, -t) with t the cable tangent; at the arc solution t = e1 and the
    custom hook returning that constant wrench must give the same equilibrium
    (roundoff).
    """
    y, z, T = 0.004, 0.002, 1.0
    cable = sj.Linkage(
        _rod(), actuators=[sj.Cable(sj.CableSpan(1, sj.ConstantPath(y, z)))]
    )
    n_pts = cable.layout.n_points
    W = np.tile([0.0, -T * z, T * y, -T, 0.0, 0.0], (n_pts, 1))
    hook = sj.Linkage(_rod(), custom_actuation=lambda t, q, qd, kin, u: jnp.asarray(W))
    q_cable = sj.solve_statics(cable, u=[T]).q
    q_hook = sj.solve_statics(hook).q
    np.testing.assert_allclose(np.asarray(q_hook), np.asarray(q_cable), rtol=1e-10)


def test_actuator_strength_hook_replaces_inputs():
    """Feedback u = k_p (theta_ref - theta) on a sprung joint: theta = kp ref/(k+kp)."""
    k, kp, ref = 2.0, 8.0, 0.5
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0), stiffness=k), length=0.2)
    lk = sj.Linkage(
        [bar],
        actuators=[sj.JointActuator(1)],
        actuator_strength=lambda t, q, qd, kin: kp * (ref - q[:1]),
    )
    sol = sj.solve_statics(lk, u=[123.0])  # ignored: the hook decides
    assert abs(float(sol.q[0]) - kp * ref / (k + kp)) < 1e-12


def _feedback(kp, ref, t, q, qd, kin):
    """u = k_p (theta_ref - theta): a module-level hook with array parameters."""
    return kp * (ref - q[:1])


def test_hook_array_parameters_reuse_program_and_take_gradients(jax_events):
    """A hook's array parameters are model arrays: no retrace, exact gradients.

    The sprung joint under u = k_p (theta_ref - theta) has theta = k_p ref / (k + k_p),
    so d theta / d k_p = k ref / (k + k_p)^2 and d theta / d ref = k_p / (k + k_p):
    the hook given as ``equinox.Partial(f, kp, ref)`` must solve a second parameter
    set with the first set's compiled program (JAX's trace events: a static hook
    would trace and compile again), solve a batch of them under ``jax.vmap``, and
    give these derivatives through the statics' implicit gradient (1e-9: the Newton
    tolerance).
    """
    k = 2.0
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0), stiffness=k), length=0.2)

    def theta(kp, ref):
        hook = eqx.Partial(_feedback, kp, ref)
        lk = sj.Linkage([bar], actuators=[sj.JointActuator(1)], actuator_strength=hook)
        return sj.solve_statics(lk).q[0]

    with jax_events("trace") as traced:
        for kp, ref in ((8.0, 0.5), (3.0, -0.2)):
            n_first = len(traced)
            th = float(theta(jnp.asarray(kp), jnp.asarray(ref)))
            assert abs(th - kp * ref / (k + kp)) < 1e-12
    again = [name for name in traced[n_first:] if "_solve_statics" in name]
    assert any("_solve_statics" in name for name in traced[:n_first])
    assert not again, "a new hook parameter value traced the solve again"
    refs = jnp.array([-0.3, 0.1, 0.4])  # vmap over stacked hook parameters
    batch = jax.vmap(theta, in_axes=(None, 0))(jnp.asarray(8.0), refs)
    np.testing.assert_allclose(batch, 8.0 * refs / (k + 8.0), rtol=0, atol=1e-12)
    kp, ref = 8.0, 0.5
    d_kp, d_ref = jax.grad(theta, argnums=(0, 1))(jnp.asarray(kp), jnp.asarray(ref))
    assert abs(float(d_kp) - k * ref / (k + kp) ** 2) < 1e-9
    assert abs(float(d_ref) - kp / (k + kp)) < 1e-9
    with pytest.raises(ValueError, match="Linkage.actuator_strength.*unhashable"):
        sj.Linkage([bar], actuator_strength=eqx.Partial(_feedback, {1.0}, 0.5))


def test_added_mass_adds_sum_of_weighted_JtMaJ():
    """M with added mass minus M without = sum_p w_p J_p^T M_a J_p (exact)."""
    rod = _rod((0, 1, 1, 0, 0, 0), 1)
    base = sj.Linkage(rod, gravity=(0, 0, -9.81))
    n_pts = base.layout.n_points
    Ma = np.tile(np.diag([0.0, 0.0, 0.0, 0.1, 0.3, 0.3]), (n_pts, 1, 1))
    lk = sj.Linkage(rod, gravity=(0, 0, -9.81), added_mass=Ma)
    q = jnp.asarray(np.random.default_rng(2).normal(size=base.n_dof))
    qd = jnp.zeros_like(q)
    M0, _ = eqx.filter_jit(mass_and_force)(base, precompute(base), 0.0, q, qd)
    M1, _ = eqx.filter_jit(mass_and_force)(lk, precompute(lk), 0.0, q, qd)
    J = np.asarray(sj.jacobians(base, q))
    w = np.asarray(precompute(base).point_weight)
    expect = np.einsum("p,pai,pab,pbj->ij", w, J, Ma, J)
    np.testing.assert_allclose(np.asarray(M1 - M0), expect, rtol=1e-12, atol=1e-16)


# ----------------------------------------------------------------------- gradients
def test_tip_gradient_wrt_cable_offset_and_tension_matches_central_differences():
    """d(tip)/d(y offset, T) through statics (implicit function theorem) vs central.

    Rod with bending + stretch under gravity, cable at (y, z); relative steps 1e-5:
    truncation ~1e-10, Newton noise ~1e-12 / 1e-5: tolerance 1e-6 relative.
    """
    rod = _rod((0, 1, 1, 1, 0, 0), 1)

    def tip(params):
        y, T = params
        lk = sj.Linkage(
            rod,
            gravity=(0, 0, -9.81),
            actuators=[sj.Cable(sj.CableSpan(1, sj.ConstantPath(y, 0.003)))],
        )
        sol = sj.solve_statics(lk, u=jnp.stack([T]), throw=False)
        x = sj.tip_pose(lk, sol.q)[:3, 3]
        return x, x

    # One compiled program gives the Jacobian and, at shifted p, the differences.
    jac_and_tip = jax.jit(jax.jacrev(tip, has_aux=True))
    p0 = jnp.array([0.006, 1.2])
    Jac, x0 = (np.asarray(a) for a in jac_and_tip(p0))
    assert np.all(np.isfinite(x0))
    for i in range(2):
        h = 1e-5 * float(p0[i])
        e = jnp.zeros(2).at[i].set(h)
        plus, minus = (np.asarray(jac_and_tip(p)[1]) for p in (p0 + e, p0 - e))
        fd = (plus - minus) / (2 * h)
        np.testing.assert_allclose(Jac[:, i], fd, rtol=1e-6, atol=1e-9)
    assert np.abs(Jac).max() > 1e-3  # non-trivial


def test_bad_actuator_inputs_raise_clear_errors():
    """Wrong u length, a cable span on a rigid link, actuating a fixed joint."""
    lk = sj.Linkage(
        _rod(), actuators=[sj.Cable(sj.CableSpan(1, sj.ConstantPath(0.01)))]
    )
    with pytest.raises(ValueError, match="n_inputs = 1"):
        sj.solve_statics(lk, u=[1.0, 2.0])
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0)))
    with pytest.raises(ValueError, match="SoftLink"):
        sj.Linkage([bar], actuators=[sj.Cable(sj.CableSpan(1, sj.ConstantPath(0.01)))])
    with pytest.raises(ValueError, match="fixed"):
        sj.Linkage([sj.RigidLink()], actuators=[sj.JointActuator(1)])
    with pytest.raises(ValueError, match="ObliquePath.start"):
        sj.ObliquePath((0.0, 0.0, 0.0), (0.0, 0.0))


def test_cable_through_two_links_and_chosen_divisions():
    """One cable through two serial soft links (0.25 m each), and one spanning only
    division 2 of a two-division rod.

    Through both links: the same exact arc curvature T y / EI in both links (the
    zero-length segment at the junction adds nothing). Division 2 only: division 1
    stays straight (1e-12) and division 2 bends with T y / EI.
    """
    y, T = 0.005, 1.0

    def half():
        return sj.SoftLink(
            sj.Division(
                L_ROD / 2,
                sj.CircularSection(R_ROD),
                sj.LegendreBasis((0, 0, 1, 0, 0, 0), 0),
            ),
            sj.Material(E, POISSON),
        )

    path = sj.ConstantPath(y, 0.0)
    two = sj.Linkage(
        [half(), half()],
        actuators=[sj.Cable([sj.CableSpan(1, path), sj.CableSpan(2, path)])],
    )
    sol = sj.solve_statics(two, u=[T])
    xi = np.asarray(sj.screw_strains(two, sol.q))[two.layout.point_kind == 2]
    np.testing.assert_allclose(xi[:, 2], T * y / EI, rtol=1e-10)

    div = sj.Division(
        L_ROD / 2, sj.CircularSection(R_ROD), sj.LegendreBasis((0, 0, 1, 0, 0, 0), 0)
    )
    one = sj.Linkage(
        sj.SoftLink([div, div], sj.Material(E, POISSON)),
        actuators=[sj.Cable(sj.CableSpan(1, path, divisions=(2, 2)))],
    )
    sol = sj.solve_statics(one, u=[T])
    xi = np.asarray(sj.screw_strains(one, sol.q))
    d = one.layout.point_division
    assert np.abs(xi[d == 1, 2]).max() < 1e-12
    np.testing.assert_allclose(xi[d == 2, 2], T * y / EI, rtol=1e-10)


def test_cable_force_by_point_wrenches_equals_length_gradient():
    """The statics and dynamics map a cable's segments outside the body as point
    wrenches (J^T W, or the backward recursion) and its spans by the strain
    quadrature; together they equal -T dl/dq of the cable length by autodiff.

    Route: ground anchor -> bar tip (offset) -> span on the soft link -> anchor at
    a soft point with an offset -> ground, at a random q (3D). Both sides are exact:
    roundoff, 1e-11 of the largest entry.
    """
    from sorojax.statics import equilibrium_residual

    bar = sj.RigidLink(sj.Joint("S"), length=0.2, mass=0.1)
    cab = sj.Cable(
        [
            sj.CableAnchor(0, (0.05, 0.1, 0.0)),
            sj.CableAnchor(1, (0.0, 0.01, 0.02), at_tip=True),
            sj.CableSpan(2, sj.ObliquePath((0.005, 0.0), (0.002, 0.003))),
            sj.CableAnchor(2, (0.0, -0.02, 0.01), division=1, X1=0.5),
            sj.CableAnchor(0, (0.3, -0.2, 0.1)),
        ]
    )
    lk = sj.Linkage([bar, _rod((1, 1, 1, 1, 0, 0), 1)], actuators=[cab])
    data = precompute(lk)
    q = jnp.asarray(np.random.default_rng(3).normal(size=lk.n_dof) * 0.5)
    T = 3.0
    ref = T * np.asarray(jax.grad(lambda q_: sj.cable_lengths(lk, q_)[0])(q))

    def r(u):
        return equilibrium_residual(lk, data, q, u=jnp.array([u]))

    statics = np.asarray(jax.jit(r)(T) - jax.jit(r)(0.0))  # r = K q - F - Q_act
    qd = jnp.zeros_like(q)
    dyn = jax.jit(lambda u: mass_and_force(lk, data, 0.0, q, qd, u=u)[1])
    dynamics = np.asarray(dyn(jnp.array([T])) - dyn(jnp.array([0.0])))
    scale = np.abs(ref).max()
    assert np.abs(statics - ref).max() < 1e-11 * scale
    assert np.abs(dynamics + ref).max() < 1e-11 * scale
