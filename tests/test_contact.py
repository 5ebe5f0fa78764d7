"""Contact: reactions, penetration law, friction on an incline, dissipation, rod-rod.

Each scene is small (a few coordinates, tens of samples) and compiled once per module.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.dynamics._contact import segment_closest

G = 9.81


def _pose(z=0.0, R=None):
    g = np.eye(4)
    if R is not None:
        g[:3, :3] = R
    g[2, 3] = z
    return g


# ----------------------------------------------------------------- rod on the floor
R_ROD, L_ROD, RHO = 0.01, 0.3, 1000.0
W_LINE = RHO * np.pi * R_ROD**2 * G  # weight per length [N/m]


def floor_rod(rho=RHO, stiffness=1e5):
    """A stiff rod free to move vertically (prismatic z), lying on a floor."""
    rod = sj.SoftLink(
        [
            sj.Division(
                L_ROD,
                sj.CircularSection(R_ROD),
                sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1),
            )
        ],
        sj.Material(E=1e9, poisson=0.5, rho=rho),
        joint=sj.Joint("P", axis=(0, 0, 1)),
    )
    law = sj.ContactLaw(stiffness=stiffness, smoothing=1e-6)
    return sj.Linkage(
        [rod],
        placements=_pose(R_ROD)[None],
        gravity=(0, 0, -G),
        contact=sj.Contact(sj.Plane(), law, spacing=0.03),
    )


@pytest.fixture(scope="module")
def floor_solution():
    lk = floor_rod()
    return lk, sj.solve_statics(lk)


def test_floor_reaction_equals_weight(floor_solution):
    lk, sol = floor_solution
    cs = sj.contact_state(lk, sol.q)
    weight = W_LINE * L_ROD
    # statics: the reaction balances the weight up to the solver's tolerance (1e-10)
    np.testing.assert_allclose(float(cs.total_force()[2]), weight, rtol=1e-6)
    assert np.all(np.asarray(cs.obstacle) == 0) and cs.point.shape[0] == 11
    # the solution carries the same report (computed inside the solve's program)
    np.testing.assert_allclose(sol.contact.force, cs.force, rtol=1e-12, atol=1e-15)


def test_floor_penetration_follows_the_law(floor_solution):
    lk, sol = floor_solution
    cs = sj.contact_state(lk, sol.q)
    predicted = float(lk.contact.law.penetration(jnp.asarray(W_LINE)))
    d = np.asarray(cs.penetration)
    w = np.full(d.size, 1.0)
    w[0] = w[-1] = 0.5  # the samples' lengths (trapezoid cells)
    # past the smoothing depth the law is linear: the length-weighted mean
    # penetration carries the weight per length exactly
    np.testing.assert_allclose(np.sum(w * d) / np.sum(w), predicted, rtol=1e-6)
    # the rod bends slightly where the sampled support and the Gauss-point weight
    # differ (second order in the sample spacing): 1 % of the penetration here
    np.testing.assert_allclose(d, predicted, rtol=0.02)
    # the joint coordinate is the rod's drop at its base: minus the penetration
    np.testing.assert_allclose(float(sol.q[0]), -d[0], rtol=1e-9)


def test_barrier_law_is_the_derivative_of_its_potential_and_inverts():
    """The barrier's force, potential and inverse law agree with one another."""
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-3, kind="barrier")
    d = jnp.linspace(-1.2e-3, 2e-4, 4001)  # beyond its reach, the log, the floor
    f = law.normal_force(d)
    # U' = f by autodiff of the closed-form potential (rounding: 1e-12 of max f)
    dU = jax.vmap(jax.grad(law.potential))(d)
    np.testing.assert_allclose(dU, f, rtol=0, atol=1e-12 * float(jnp.max(f)))
    # zero beyond the reach, positive and strictly rising as the gap closes
    assert np.all(np.asarray(f)[np.asarray(d) <= -1e-3] == 0.0)
    inside = np.asarray(d) > -1e-3
    assert np.all(np.diff(np.asarray(f)[inside]) > 0)
    # the gradient is finite everywhere (the log's argument is clipped)
    assert np.all(np.isfinite(np.asarray(jax.vmap(jax.grad(law.normal_force))(d))))
    # inverse: 60 bisections, the force at the returned depth to 1e-9 relative;
    # loads up to k g_hat = 10 N/m leave a gap, a far larger one presses through
    for load in (1e-3, 1.0, 10.0, 100.0):
        dd = law.penetration(jnp.asarray(load))
        np.testing.assert_allclose(float(law.normal_force(dd)), load, rtol=1e-9)
        assert float(dd) < 0.0
    # far from the surface (x -> 0): f ~ k g_hat / x, the gap about k g_hat^2 / f
    dd = float(law.penetration(jnp.asarray(1e3)))
    np.testing.assert_allclose(-dd, 1e4 * 1e-6 / 1e3, rtol=0.3)


def test_barrier_floor_carries_the_weight_across_a_gap():
    """A rod on a barrier floor: the reaction is its weight, the rod never touches."""
    law = sj.ContactLaw(stiffness=2e3, smoothing=1e-4, kind="barrier")
    lk = floor_rod()
    lk = sj.Linkage(lk.links, placements=_pose(R_ROD + 5e-5)[None],
                    gravity=(0, 0, -G), contact=sj.Contact(sj.Plane(), law,
                                                           spacing=0.03))  # fmt: skip
    sol = sj.solve_statics(lk)
    cs = sol.contact
    # statics: the balance holds to the solver's tolerance (1e-10)
    np.testing.assert_allclose(float(cs.total_force()[2]), W_LINE * L_ROD, rtol=1e-6)
    d = np.asarray(cs.penetration)
    assert np.all(d < 0), "the barrier let the rod touch the floor"
    # every sample carries about w per length at the law's gap (1 % spread from the
    # sampled support, as for the penalty above)
    np.testing.assert_allclose(
        d, float(law.penetration(jnp.asarray(W_LINE))), rtol=0.02
    )
    assert bool(np.all(np.asarray(cs.active)))


def test_rod_started_deep_in_the_floor_is_reported():
    """A rod whose centre line starts 3 radii below the floor: a result code."""
    lk = floor_rod()
    lk = sj.Linkage(lk.links, placements=_pose(-3 * R_ROD)[None], gravity=(0, 0, -G),
                    contact=lk.contact)  # fmt: skip
    sol = sj.solve_statics(lk, throw=False)
    assert sol.result == sj.RESULTS.contact_too_deep
    with pytest.raises(RuntimeError, match="penetration exceeds"):
        sj.solve_statics(lk)


def test_floor_gradient_matches_finite_differences(floor_solution):
    """d(drop)/d(density) through the statics with contact (implicit derivative)."""

    def drop(rho):
        return sj.solve_statics(floor_rod(rho)).q[0]

    g = jax.grad(drop)(RHO)
    h = 1.0
    fd = (drop(RHO + h) - drop(RHO - h)) / (2 * h)
    # the law is linear past the smoothing depth: central differences exact to ~1e-9
    np.testing.assert_allclose(float(g), float(fd), rtol=1e-5)
    # and the law's own derivative: drop = -(w / k + delta / 2), w = rho pi r^2 g,
    # up to the slight bending at the base (0.2 %, see the penetration test)
    np.testing.assert_allclose(float(g), -np.pi * R_ROD**2 * G / 1e5, rtol=1e-2)


# ------------------------------------------------------------------ inclined plane
MU = 0.5
HALF = np.array([0.02, 0.02, 0.01])
MASS = 0.1


def incline(alpha, mu=MU):
    """A rigid block (free joint, box contact shape) resting on a plane at alpha."""
    n = np.array([-np.sin(alpha), 0.0, np.cos(alpha)])
    c, s = np.cos(alpha), np.sin(alpha)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # block x along the slope
    place = np.eye(4)
    place[:3, :3] = R
    place[:3, 3] = n * HALF[2]
    block = sj.RigidLink(
        sj.Joint("F"), length=0.04, mass=MASS, inertia=np.diag([1e-5] * 3),
        g_i=np.eye(4), g_f=np.eye(4),
    )  # fmt: skip
    law = sj.ContactLaw(
        stiffness=1e4, smoothing=1e-5, damping=20.0, static_friction=mu,
        stick_velocity=1e-3,
    )  # fmt: skip
    contact = sj.Contact(sj.Plane(normal=n), law, shapes={1: sj.ContactBox(HALF)})
    return sj.Linkage(
        [block], placements=place[None], gravity=(0, 0, -G), contact=contact
    )


def _downhill(lk, tr, alpha):
    P = np.asarray(jax.vmap(lambda q: sj.forward_kinematics(lk, q)[1, :3, 3])(tr.q))
    return (P - P[0]) @ np.array([-np.cos(alpha), 0.0, -np.sin(alpha)])


@pytest.mark.parametrize("alpha_deg", [15.0, 35.0])
def test_block_on_incline_sticks_or_slides(alpha_deg):
    alpha = np.radians(alpha_deg)
    lk = incline(alpha)
    tr = sj.simulate(lk, 1.0, solver="tsit5", n_save=41, rtol=1e-6, atol=1e-9,
                     max_steps=100_000)  # fmt: skip
    s = _downhill(lk, tr, alpha)
    if np.tan(alpha) < MU:
        # friction angle 26.6 deg: held; it creeps at the regularisation's
        # v_s r / sqrt(1 - r^2) = 0.63 mm/s (r = tan(alpha) / mu)
        assert abs(s[-1]) < 1e-3, f"drift {s[-1]:.2e} m in 1 s below the friction angle"
    else:
        t = np.asarray(tr.t)
        a = 2 * np.polyfit(t[20:], s[20:], 2)[0]
        a_exact = G * (np.sin(alpha) - MU * np.cos(alpha))
        # Coulomb sliding: mu is the kinetic one far above the Stribeck speed
        np.testing.assert_allclose(a, a_exact, rtol=0.02)


def test_stick_load_bounds_the_friction_slope_and_keeps_sliding_friction():
    """With a stick load f* the stick velocity is v_s sqrt(1 + (f_n / f*)^2): at
    rest, friction's viscous slope (ROS34PW2's tangent, equal by central
    differences to the law's own derivative, 1e-6) stays below mu f* / v_s at every
    load and within (f_n / f*)^2 / 2 of mu f_n / v_s below f* (holding as before);
    sliding at 1 m/s meets Coulomb's mu f_n to 0.5 % up to 100 f* (the stick
    velocity there 0.1 m/s)."""
    from sorojax.dynamics._contact import _law_forces, _tangent_slopes

    mu, vs, fstar, k, delta = 0.5, 1e-3, 2.0, 1e4, 1e-6
    law = sj.ContactLaw(k, delta, static_friction=mu, stick_velocity=vs,
                        stick_load=fstar)  # fmt: skip
    ratio = np.array([0.1, 1.0, 10.0, 100.0])
    fn = fstar * ratio
    d = jnp.asarray(fn / k + 0.5 * delta)  # past the ramp: f_n = k (d - delta / 2)
    n = jnp.tile(jnp.array([0.0, 0.0, 1.0]), (4, 1))
    w = jnp.ones(4)
    np.testing.assert_allclose(law.normal_force(d), fn, rtol=1e-12)
    _, _, ct = _tangent_slopes(law, w, d, n, jnp.zeros((4, 3)))
    ct = np.asarray(ct)
    np.testing.assert_allclose(ct, mu * fn / (vs * np.sqrt(1 + ratio**2)), rtol=1e-12)
    assert np.all(ct <= mu * fstar / vs), "the slope passed mu f* / v_s"
    assert ct[0] >= (1 - 0.5 * ratio[0] ** 2) * mu * fn[0] / vs
    h = 1e-7  # slip far below v_s: the law's derivative at rest

    def friction_x(vx):
        v = jnp.zeros((4, 3)).at[:, 0].set(vx)
        return np.asarray(_law_forces(law, d, n, v, w, True)[0][:, 0])

    slope = (friction_x(h) - friction_x(-h)) / (2 * h)
    np.testing.assert_allclose(-slope, ct, rtol=1e-6)
    slide = -friction_x(1.0)
    assert np.all(slide <= mu * fn) and np.all(slide >= 0.995 * mu * fn)


def test_sliding_gradient_through_the_contact_dynamics():
    """d(slide distance)/d(mu) by forward mode through simulate: central differences
    and the Coulomb law's own derivative, -g cos(alpha) T^2 / 2."""
    import diffrax

    alpha, T = np.radians(35.0), 0.3

    def slide(mu):
        lk = incline(alpha, mu)
        tr = sj.simulate(lk, T, solver="ros34pw2", dt0=1e-3, adaptive=False, n_save=2,
                         adjoint=diffrax.ForwardMode())  # fmt: skip
        x = sj.forward_kinematics(lk, tr.q[-1])[1, :3, 3]
        return -(x[0] * np.cos(alpha) + x[2] * np.sin(alpha))  # downhill

    value, deriv = jax.jvp(slide, (jnp.asarray(MU),), (jnp.asarray(1.0),))
    h = 1e-4
    fd = (slide(MU + h) - slide(MU - h)) / (2 * h)
    # fixed steps: a smooth function of mu, central differences exact to ~h^2
    np.testing.assert_allclose(float(deriv), float(fd), rtol=1e-6)
    # Coulomb sliding from rest (the block settles on its contact in ~ms)
    np.testing.assert_allclose(float(deriv), -G * np.cos(alpha) * T**2 / 2, rtol=0.02)
    assert float(value) > 0


# ------------------------------------------------------- drop with contact damping
def dropped_rod():
    rod = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1)
            )
        ],
        sj.Material(E=1e6, poisson=0.5, rho=1000.0, eta=1e3),
        joint=sj.Joint("A", axis=(0, 1, 0)),
    )
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, damping=10.0)
    return sj.Linkage(
        [rod], placements=_pose(0.05)[None], gravity=(0, 0, -G),
        contact=sj.Contact(sj.Plane(), law, spacing=0.02),
    )  # fmt: skip


def test_drop_energy_never_rises_and_rod_comes_to_rest():
    lk = dropped_rod()
    q0 = jnp.zeros(lk.n_dof).at[0].set(0.1)  # tilted: one end lands first
    tr = sj.simulate(lk, 1.5, q0, solver="tsit5", n_save=151, rtol=1e-7, atol=1e-9)
    E = np.asarray(jax.vmap(lambda q, qd: sj.total_energy(lk, q, qd))(tr.q, tr.qd))
    # contact (penalty potential) + rod + gravity: damping only removes energy;
    # the integrator's error at rtol 1e-7 is far below 1e-6 of E0
    assert np.max(np.diff(E)) <= 1e-6 * abs(E[0]), (
        f"energy rose by {np.max(np.diff(E)):.2e} J"
    )
    assert E[-1] < 0.5 * E[0]
    cs = sj.contact_state(lk, tr.q[-1], tr.qd[-1])
    # the trajectory carries the contact report at every save time
    assert tr.contact.force.shape == (151, cs.force.shape[0], 3)
    np.testing.assert_allclose(tr.contact.force[-1], cs.force, rtol=1e-10, atol=1e-14)
    # an environment's touch observation: the resultant on the rod
    env = sj.Environment(lk, period=0.01, solver="tsit5")
    state = sj.EnvState(
        q=tr.q[-1], qd=tr.qd[-1], t=jnp.asarray(1.5), u=jnp.zeros(0),
        result=jnp.asarray(0), steps=jnp.asarray(0),
    )  # fmt: skip
    np.testing.assert_allclose(
        env.contact_forces(state)[0], cs.total_force(), rtol=1e-12
    )
    assert env.observation(state).shape == (2 * lk.n_dof + 6 + 3,)
    weight = 1000.0 * np.pi * 0.01**2 * 0.3 * G
    # at rest the floor carries the weight (residual motion after 1.5 s: < 1e-3)
    np.testing.assert_allclose(float(cs.total_force()[2]), weight, rtol=1e-3)
    assert float(jnp.max(jnp.abs(tr.qd[-1]))) < 1e-2


# -------------------------------------------------------------------- crossing rods
def crossing_rods(P, x=0.3):
    """Rod 1 a cantilever along x; rod 2 along y, free to slide vertically (P joint),
    pressed onto rod 1 by a downward force P at its middle."""
    r = 0.01
    basis = sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2)
    mat = sj.Material(E=1e7, poisson=0.5, rho=1000.0)
    rod1 = sj.SoftLink([sj.Division(0.4, sj.CircularSection(r), basis)], mat)
    rod2 = sj.SoftLink(
        [sj.Division(0.2, sj.CircularSection(r), basis)],
        mat,
        joint=sj.Joint("P", axis=(0, 0, 1)),
    )
    g2 = np.eye(4)
    g2[:3, :3] = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])  # x along world y
    g2[:3, 3] = [x, -0.1, 2 * r]
    law = sj.ContactLaw(stiffness=1e5, smoothing=1e-6)
    contact = sj.Contact((), law, rod_pairs=[(1, 2)], spacing=0.02)
    return sj.Linkage(
        [rod1, rod2], parents=(0, 0), placements=np.stack([np.eye(4), g2]),
        point_wrenches=[sj.PointWrench(2, jnp.stack([0.0, 0, 0, 0, 0, -P]), division=1, X1=0.5)],
        contact=contact,
    )  # fmt: skip


@pytest.mark.parametrize("x", [0.3, 0.31])  # at a vertex of rod 1, between two
def test_crossing_rods_press_without_passing_through(x):
    P = 0.5
    lk = crossing_rods(P, x)
    sol = sj.solve_statics(lk)
    cs = sj.contact_state(lk, sol.q)
    # rod 2's joint carries no vertical force: the contact takes the whole load
    # (rows are the forces on rod 1, pressed down)
    np.testing.assert_allclose(float(jnp.sum(cs.force[:, 2])), -P, rtol=1e-6)
    g = sj.forward_kinematics(lk, sol.q)
    lay = lk.layout.links
    z1 = float(g[lay[0].tip_point, 2, 3])
    z2_mid = float(jnp.min(g[lay[1].divisions[0].first_point : lay[1].tip_point, 2, 3]))
    assert z1 < -1e-3, "rod 1 should bend down under the load"
    # centre lines stay two radii apart up to the penalty's penetration (P/k = 5e-6)
    assert float(jnp.max(cs.penetration)) < 1e-4
    assert z2_mid > z1 - 1e-3


def test_rod_pair_stiffness_in_w_matches_the_force_derivative():
    """ROS34PW2's W carries the rod pair's contact stiffness: the Gauss-Newton K_c
    equals the derivative of the generalised contact force, -dQ/dq, up to the
    geometric terms it leaves out (force / radius = 50 N/m against k = 1e5 N/m: 1e-2
    relative in the Frobenius norm allows for them and for gravity's and the
    point load's own, smaller, derivatives). Positive semi-definite by
    construction; the contact's gradient is not zero (a W without the pair is)."""
    from sorojax.dynamics._contact import contact_tangent
    from sorojax.dynamics._generalized import kinematics_from_data
    from sorojax.model._precompute import precompute

    lk = crossing_rods(0.5)
    q = sj.solve_statics(lk).q

    @jax.jit  # one program, not the kernels' operations one by one
    def tangents(q):
        kin = kinematics_from_data(
            precompute(lk), q, jnp.zeros_like(q), need_jdot=False
        )
        Kc, _ = contact_tangent(lk, 0.0, kin.g, kin.J, kin.eta)
        return Kc, -jax.jacfwd(lambda q_: sj.generalized_external_force(lk, q_))(q)

    Kc, K_num = tangents(q)
    scale = float(jnp.linalg.norm(K_num))
    assert scale > 1.0, "the pair's contact stiffness should show in -dQ/dq"
    assert float(jnp.linalg.norm(Kc - K_num)) < 1e-2 * scale
    np.testing.assert_allclose(Kc, Kc.T, atol=1e-9 * scale)
    assert float(jnp.min(jnp.linalg.eigvalsh(Kc))) > -1e-9 * scale


# --------------------------------------------------------------- kernels and input
def test_segment_closest_points_match_brute_force():
    rng = np.random.default_rng(0)
    grid = np.linspace(0, 1, 401)
    for _ in range(20):
        p0, p1, q0, q1 = rng.normal(size=(4, 3))
        s, u = segment_closest(*map(jnp.asarray, (p0, p1, q0, q1)))
        A = p0 + np.outer(grid, p1 - p0)
        B = q0 + np.outer(grid, q1 - q0)
        D = np.linalg.norm(A[:, None] - B[None], axis=-1)
        best = D.min()
        got = np.linalg.norm((p0 + float(s) * (p1 - p0)) - (q0 + float(u) * (q1 - q0)))
        # the grid's minimum is within its spacing's second-order error of the exact
        assert best - 1e-3 <= got <= best + 1e-12


@pytest.mark.parametrize(
    "build, field",
    [
        (lambda: sj.ContactLaw(stiffness=-1.0), "ContactLaw.stiffness"),
        (lambda: sj.ContactLaw(stiffness=1.0, smoothing=0.0), "ContactLaw.smoothing"),
        (
            lambda: sj.ContactLaw(stiffness=1.0, static_friction=-0.1),
            "ContactLaw.static_friction",
        ),
        (lambda: sj.ContactLaw(stiffness=1.0, damping=-1.0), "ContactLaw.damping"),
        (
            lambda: sj.ContactLaw(stiffness=1.0, stick_velocity=0.0),
            "ContactLaw.stick_velocity",
        ),
        (lambda: sj.ContactLaw(1.0, stick_load=0.0), "ContactLaw.stick_load"),
        (lambda: sj.ContactLaw(stiffness=1.0, kind="ipc"), "ContactLaw.kind"),
        (lambda: sj.Sphere(0.0), "Sphere.radius"),
        (lambda: sj.Capsule(-0.1), "Capsule.radius"),
        (lambda: sj.Box((0.1, 0.0, 0.1)), "Box.half_extents"),
        (lambda: sj.Plane(normal=(0, 0, 0)), "Plane.normal"),
        (lambda: sj.ContactSphere(-1.0), "ContactSphere.radius"),
        (lambda: sj.Contact(sj.Plane()), "Contact.law"),
        (lambda: sj.Contact("floor", sj.ContactLaw(1.0)), "Contact.obstacles"),
        (
            lambda: sj.Contact(sj.Plane(), sj.ContactLaw(1.0), spacing=0.0),
            "Contact.spacing",
        ),
        (
            lambda: sj.Linkage(
                [floor_rod().links[0]],
                contact=sj.Contact(sj.Plane(), sj.ContactLaw(1.0), links=[3]),
            ),
            "Contact.links",
        ),
        (
            lambda: sj.Linkage(
                [floor_rod().links[0]],
                contact=sj.Contact((), sj.ContactLaw(1.0), rod_pairs=[(1, 1)]),
            ),
            "Contact.rod_pairs",
        ),
        (
            lambda: sj.Linkage(
                [floor_rod().links[0]],
                contact=sj.Contact(
                    (), sj.ContactLaw(1.0), shapes={1: sj.ContactSphere(0.1)}
                ),
            ),
            "Contact.shapes",
        ),
    ],
)
def test_bad_contact_input_names_the_field(build, field):
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        build()


# ----------------------------------------- heavy cantilever resting on a floor
def test_heavy_cantilever_on_floor_matches_the_elastica():
    """Shape and clamp reaction against the elastica with an unknown touchdown point
    (tests/contact_reference.py, a shooting solution of its own)."""
    from contact_reference import equivalent_touchdown, heavy_cantilever_on_floor

    L, EI, w, d, r = 1.0, 0.05, 1.0, 0.05, 0.01
    ref = heavy_cantilever_on_floor(L, EI, w, d)
    nd = 4
    divs = [
        sj.Division(
            L / nd, sj.CircularSection(r), sj.LegendreBasis((0, 1, 0, 0, 0, 0), 3)
        )
        for _ in range(nd)
    ]
    rod = sj.SoftLink(
        divs,
        sj.Material(E=EI / (np.pi * r**4 / 4), poisson=0.5, rho=w / (np.pi * r**2 * G)),
    )
    law = sj.ContactLaw(stiffness=1e6, smoothing=1e-7)
    lk = sj.Linkage(
        [rod], placements=_pose(d + r)[None], gravity=(0, 0, -G),
        contact=sj.Contact(sj.Plane(), law, spacing=0.01),
    )  # fmt: skip
    sol = sj.solve_statics(lk)
    g = np.asarray(sj.forward_kinematics(lk, sol.q))
    lay = lk.layout
    # the division ends at arc lengths 0, L/4, ..., L: 5 exact positions, plus the
    # rod's points in between
    pts = np.where(lay.point_kind == 2)[0]
    s = (lay.point_division[pts] - 1 + lay.point_X1[pts]) * L / nd
    # the swept sphere rests its centre line one radius above the floor
    xr = np.interp(s, ref["s"], ref["x"])
    zr = np.interp(s, ref["s"], ref["z"]) + r
    err = np.max(np.hypot(g[pts, 0, 3] - xr, g[pts, 2, 3] - zr))
    # penalty compliance (w / k = 1e-6 m) and the rounded touchdown zone
    # ((EI / k)^(1/4) = 1.5 cm long): measured 2.9e-5 L
    assert err < 2e-3 * L, f"centre line {err / L:.2e} L from the elastica"
    cs = sj.contact_state(lk, sol.q)
    clamp_fz = w * L - float(cs.total_force()[2])
    # the clamp carries the hanging part's weight less R: measured 5e-4 relative
    np.testing.assert_allclose(clamp_fz, ref["clamp_force"][1], rtol=2e-3)
    # The touchdown point: the penalty spreads the rigid floor's point reaction over
    # a zone that starts about (EI / k)^(1/4) early (x = 0.637 against 0.650); the
    # rigid floor with the same resultant force and moment touches down at
    # a_eq within 2e-3 L of the elastica's a (measured 3.8e-4 L; 2.9e-4 to 6.1e-4 L
    # for k = 1e4 .. 1e7 in benchmarks/contact.py: the discretisation's error).
    a_eq = equivalent_touchdown(
        np.asarray(cs.force)[:, 2], np.asarray(cs.point)[:, 0], w, L, g[-1, 0, 3]
    )
    assert abs(a_eq - ref["a"]) < 2e-3 * L, f"touchdown {a_eq:.4f} vs {ref['a']:.4f}"


# ------------------------------------------------------------- inside a soft tube
def test_sphere_pushed_through_a_curved_tube_stays_inside():
    """A ball pushed along x into a soft tube pre-curved by 3 rad/m follows the bore."""
    Ro, Ri, rho = 0.014, 0.01, 0.008
    tube = sj.SoftLink(
        [sj.Division(0.3, sj.AnnularSection(Ro, Ri), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1),
                     xi_ref=(0, 0, 3.0, 1, 0, 0))],
        sj.Material(E=1e6, poisson=0.5, rho=1000.0, eta=1e3),
    )  # fmt: skip
    ball = sj.RigidLink(sj.Joint("F"), length=0.01, mass=0.005,
                        inertia=np.diag([1e-7] * 3), g_i=np.eye(4), g_f=np.eye(4))  # fmt: skip
    place = np.stack([np.eye(4), _pose()])
    place[1, 0, 3] = 0.02
    law = sj.ContactLaw(stiffness=2e3, smoothing=1e-5, damping=2.0)
    lk = sj.Linkage(
        [tube, ball], parents=(0, 0), placements=place,
        point_wrenches=[sj.PointWrench(2, jnp.stack([0.0, 0, 0, 0.05, 0, 0]))],
        contact=sj.Contact((), law, shapes={2: sj.ContactSphere(rho)}, inside=[(1, 2)],
                           spacing=0.01),
    )  # fmt: skip
    tr = sj.simulate(lk, 0.2, solver="tsit5", n_save=21, rtol=1e-5, atol=1e-8)
    rod = np.where(lk.layout.point_kind == 2)[0]
    cm = lk.layout.links[1].cm_point
    g = np.asarray(jax.vmap(lambda q: sj.forward_kinematics(lk, q))(tr.q))
    for k in range(g.shape[0]):
        A, x = g[k, rod, :3, 3], g[k, cm, :3, 3]
        ab = A[1:] - A[:-1]
        s = np.clip(np.sum((x - A[:-1]) * ab, 1) / np.sum(ab * ab, 1), 0, 1)
        dist = np.min(np.linalg.norm(x - (A[:-1] + s[:, None] * ab), axis=1))
        # inside the bore up to the penalty's penetration (load / k ~ 1e-5 m)
        assert dist <= Ri - rho + 1e-4, (
            f"ball {dist * 1e3:.2f} mm off the axis at t={tr.t[k]}"
        )
    # it went round the bend (the tube turns 0.5 rad over the first 0.17 m)
    assert g[-1, cm, 1, 3] > 0.04 and g[-1, cm, 0, 3] > 0.15
    # the wall did guide it
    assert float(jnp.max(tr.contact.penetration)) > 0


def test_ball_resting_on_a_cantilever_carries_its_weight():
    """A rigid ball (its contact sphere) against a soft rod's segments: the rod
    carries the ball's weight through the contact (statics, frictionless)."""
    r, rho_b, m = 0.01, 0.02, 0.01
    rod = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection(r), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2)
            )
        ],
        sj.Material(E=1e7, poisson=0.5, rho=1000.0),
    )
    ball = sj.RigidLink(sj.Joint("P", axis=(0, 0, 1)), length=0.01, mass=m,
                        inertia=np.diag([1e-7] * 3), g_i=np.eye(4), g_f=np.eye(4))  # fmt: skip
    place = np.stack([np.eye(4), _pose(r + rho_b)])
    place[1, 0, 3] = 0.2
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-7)
    lk = sj.Linkage(
        [rod, ball], parents=(0, 0), placements=place, gravity=(0, 0, -G),
        contact=sj.Contact((), law, shapes={2: sj.ContactSphere(rho_b)},
                           rod_pairs=[(1, 2)], spacing=0.02),
    )  # fmt: skip
    sol = sj.solve_statics(lk)
    cs = sol.contact
    # the ball's joint carries nothing vertical: the contact holds its weight
    np.testing.assert_allclose(float(jnp.sum(cs.force[:, 2])), m * G, rtol=1e-6)
    # penetration of the per-point law: weight / k = 1e-5 m
    np.testing.assert_allclose(float(jnp.max(cs.penetration)), m * G / 1e4, rtol=0.1)
    # the rod bends down under it
    assert float(sj.tip_pose(lk, sol.q, 1)[2, 3]) < -1e-2


def test_an_obstacle_with_its_own_law_sets_the_friction():
    """A rod sliding at 1 m/s on a floor whose own law has mu = 0.2 (the contact's
    default 0.5): every sample's friction is -0.2 f_n along the slip."""
    rod = floor_rod().links[0]
    rod = sj.SoftLink(rod.divisions, rod.material, joint=sj.Joint("P", axis=(1, 0, 0)))
    rough = sj.ContactLaw(stiffness=1e5, smoothing=1e-6, static_friction=0.5)
    slippery = sj.ContactLaw(stiffness=1e5, smoothing=1e-6, static_friction=0.2)
    lk = sj.Linkage(
        [rod], placements=_pose(R_ROD - 1e-4)[None], gravity=(0, 0, -G),
        contact=sj.Contact(sj.Plane(), rough, spacing=0.03, obstacle_laws={0: slippery}),
    )  # fmt: skip
    qd = jnp.zeros(lk.n_dof).at[0].set(1.0)
    cs = sj.contact_state(lk, jnp.zeros(lk.n_dof), qd)
    f = np.asarray(cs.force)
    # mu(1 m/s) = mu_k to 1e-4 (Stribeck 1 cm/s), regularisation (1 mm/s) 5e-7
    np.testing.assert_allclose(f[:, 0], -0.2 * f[:, 2], rtol=1e-3)
    assert np.all(f[:, 2] > 0)
    with pytest.raises(ValueError, match="Contact.obstacle_laws"):
        sj.Contact(sj.Plane(), rough, obstacle_laws={1: slippery})


def test_box_distance_is_exact_and_its_derivative_finite_at_every_level():
    """The box's signed distance at points outside (to an edge, a face) and inside
    (minus the depth under the nearest face) equals the closed form, and the
    penetration's forward-mode derivative for spheres against a turned box equals
    central differences (1e-7: truncation at step 1e-6), compiled at XLA's -O0 as at
    its default level. The spheres are those of tests/test_contact_viz.py's rod
    where, at -O0, ``jnp.max``'s derivative (an average over the entries equal to
    the maximum) gave 0/0: XLA computed the entries in two kernels with different
    rounding, and none equalled the maximum."""
    from sorojax.dynamics._contact import _against_obstacle

    box = sj.Box((0.02, 0.02, 0.02))
    pts = jnp.asarray([[0.07330127, 0.06160254, -0.0105],  # outside, beside an edge
                       [0.05, 0.01, 0.0],  # outside a face
                       [0.005, -0.012, 0.003]])  # inside, nearest face -y  # fmt: skip
    want = [np.hypot(0.05330127, 0.04160254), 0.03, -(0.02 - 0.012)]
    np.testing.assert_allclose(jax.vmap(box.distance)(pts), want, rtol=1e-12)
    c, s_ = np.cos(np.pi / 6), np.sin(np.pi / 6)
    pose = np.array([[c, -s_, 0, 0.2], [s_, c, 0, -0.1], [0, 0, 1, 0.02], [0, 0, 0, 1]])
    turned = sj.Box((0.02, 0.02, 0.02), pose=pose)
    x = jnp.asarray([[0.19999999998231238, 0.0, 0.00943338404625861],
                     [0.24999999996135924, 0.0, 0.00943474895272092],
                     [0.2999999998445533, 0.0, 0.00943810188796205]])  # fmt: skip
    radius = jnp.full(3, 0.01)

    def depth(x):
        z = jnp.zeros_like(x)
        return _against_obstacle(turned, 0.0, x, z, z, radius)[1]

    h, e = 1e-6, jnp.broadcast_to(jnp.asarray([1.0, -0.5, 0.25]), x.shape)
    fd = (depth(x + h * e) - depth(x - h * e)) / (2 * h)
    for level in (0, 2):
        opts = {**sj.compiler_options(), "xla_backend_optimization_level": level}
        tangent = jax.jit(
            lambda x: jax.jvp(depth, (x,), (e,))[1], compiler_options=opts
        )(x)
        np.testing.assert_allclose(tangent, fd, atol=1e-7, err_msg=f"level {level}")
