"""Stability of static equilibria: the reduced tangent stiffness's spectrum.

References: a rigid pendulum's potential m g l_c (1 - cos theta) has second derivative
+m g l_c hanging and -m g l_c upright; the same pendulum as a free body closed to the
ground by a revolute loop (the manifold's curvature enters through the multipliers)
has the same signs and equal and opposite eigenvalues; a rod clamped at both ends
with its far end pushed to 0.8 L has a buckled (stable) and a straight (unstable)
equilibrium, the buckled one at a far lower elastic energy.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
import sorojax.scenes

M_P, L_P, G = 0.3, 0.2, 9.81  # pendulum mass [kg], length [m], gravity [m/s^2]


def _pendulum_link(joint):
    return sj.RigidLink(joint, length=L_P, mass=M_P, inertia=np.eye(3) * 1e-4)


def test_pendulum_stability_and_eigenvalue_are_analytic():
    """Open chain, revolute about z, gravity -y. Without joint stiffness the scale is 1,
    so the eigenvalue is d2V/dtheta2 = +-m g l_c (l_c = L/2), to 1e-9 relative (Newton
    tolerance); the upright solve warns that it is unstable."""
    lk = sj.Linkage(
        _pendulum_link(sj.Joint("R", axis=(0.0, 0.0, 1.0))), gravity=(0.0, -G, 0.0)
    )
    mgl = M_P * G * L_P / 2
    down = sj.solve_statics(lk, [-math.pi / 2 + 0.3])
    assert abs(float(down.q[0]) + math.pi / 2) < 1e-9
    assert bool(down.stable) and int(down.n_negative) == 0
    assert abs(float(down.min_eigenvalue) - mgl) < 1e-9 * mgl, down.min_eigenvalue
    with pytest.warns(sj.UnstableEquilibriumWarning, match="1 negative"):
        up = sj.solve_statics(lk, [math.pi / 2 - 0.05])
    assert abs(float(up.q[0]) - math.pi / 2) < 1e-9
    assert not bool(up.stable) and int(up.n_negative) == 1
    assert abs(float(up.min_eigenvalue) + mgl) < 1e-9 * mgl, up.min_eigenvalue
    # the flag is data: no warning under throw=False with warn_unstable=False
    quiet = sj.solve_statics(lk, [math.pi / 2 - 0.05], throw=False, warn_unstable=False)
    assert not bool(quiet.stable)


def test_closed_loop_pendulum_needs_the_constraint_curvature():
    """A free body (joint F) pinned to the ground at its base by a revolute closure:
    6 coordinates, 5 constraint rows. Its manifold is the pendulum's circle, curved
    in these coordinates, so only the multipliers' curvature term gives the right
    signs: hanging stable (0 negative), upright unstable (1 negative), eigenvalues
    equal and opposite (1e-8: the two are mirror images)."""
    link = _pendulum_link(sj.Joint("F"))
    lk = sj.Linkage(
        link,
        gravity=(0.0, -G, 0.0),
        closed_loops=[
            sj.ClosedLoopJoint(
                sj.Joint("R", axis=(0.0, 0.0, 1.0)), 1, 0, g_A=sj.translation(-L_P)
            )
        ],
    )
    sols = []
    for theta in (-math.pi / 2, math.pi / 2):
        q0 = jnp.zeros(6).at[2].set(theta + 0.02)
        sols.append(sj.solve_statics(lk, q0, warn_unstable=False))
    down, up = sols
    for s, th in zip(sols, (-math.pi / 2, math.pi / 2), strict=True):
        assert float(s.constraint_error) < 1e-10
        assert abs(float(s.q[2]) - th) < 1e-8, s.q
    assert bool(down.stable) and int(down.n_negative) == 0
    assert not bool(up.stable) and int(up.n_negative) == 1
    lam_d, lam_u = float(down.min_eigenvalue), float(up.min_eigenvalue)
    assert lam_d > 0 and abs(lam_d + lam_u) < 1e-8 * lam_d, (lam_d, lam_u)


E_C, R_C, L_C = 1e6, 0.005, 0.4


@pytest.fixture(scope="module")
def clamped_clamped():
    rod = sj.SoftLink(
        [
            sj.Division(
                L_C, sj.CircularSection(R_C), sj.LegendreBasis((1, 1, 1, 1, 1, 1), 8)
            )
        ],
        sj.Material(E_C),
    )
    return sj.Linkage(
        rod,
        closed_loops=[
            sj.ClosedLoopJoint(sj.Joint("N"), 1, 0, g_B=sj.translation(0.8 * L_C))
        ],
    )


def _buckled_guess(lk, scale):
    # first clamped-clamped mode w = a/2 (1 - cos(2 pi s / L)); linear theory's
    # amplitude for an end shortening of 0.2 L is a = sqrt(0.8) L / pi
    a = scale * math.sqrt(0.8) * L_C / math.pi
    k = 2 * math.pi / L_C

    def strain(s):
        return jnp.stack([0.0, 0.0, a / 2 * k**2 * jnp.cos(k * s), 1.0, 0.0, 0.0])

    return sj.strain_coordinates(lk, strain, total=True)


@pytest.mark.parametrize("scale", [0.1, 1.0, 3.0])
def test_clamped_clamped_rod_returns_the_buckled_shape_from_a_buckled_guess(
    clamped_clamped, scale
):
    """All six modes, order 8 (54 DoF). From buckled guesses of 0.1x to 3x linear
    theory's amplitude the solve returns the buckled shape (energy < 1/50 of the
    straight rod's), flagged stable (its only zero eigenvalue is the turn about the
    line through the ends, a symmetry of the circular section)."""
    lk = clamped_clamped
    sol = sj.solve_statics(lk, _buckled_guess(lk, scale))
    energy = float(sj.elastic_energy(lk, sol.q))
    straight = 0.5 * E_C * math.pi * R_C**2 * 0.2**2 * L_C  # E A eps^2 L / 2
    assert float(sol.constraint_error) < 1e-10
    assert energy < straight / 50, (energy, straight)
    assert bool(sol.stable) and int(sol.n_negative) == 0
    assert abs(float(sol.min_eigenvalue)) < 1e-8  # the symmetry


def test_clamped_clamped_rod_straight_guess_is_flagged_unstable(clamped_clamped):
    """From the straight guess Newton stays on the straight, 20 % compressed rod (the
    energy E A eps^2 L / 2 to 1e-6); it is unstable (many buckling modes: at least
    one negative eigenvalue per bending plane) and the solve warns."""
    lk = clamped_clamped
    with pytest.warns(sj.UnstableEquilibriumWarning):
        sol = sj.solve_statics(lk)
    straight = 0.5 * E_C * math.pi * R_C**2 * 0.2**2 * L_C
    energy = float(sj.elastic_energy(lk, sol.q))
    assert abs(energy - straight) < 1e-6 * straight, (energy, straight)
    assert not bool(sol.stable)
    assert int(sol.n_negative) >= 2 and int(sol.n_negative) % 2 == 0
    assert float(sol.min_eigenvalue) < 0


@pytest.mark.parametrize("follower", [False, True])
def test_end_moment_circle_in_3d_is_not_flagged_unstable(follower):
    """A rod rolled into a full circle by an end moment, with both bending planes:
    the load is not conservative in 3D, so its tangent is not symmetric and the
    symmetric part has negative eigenvalues (-0.33) although no eigenvalue of the
    tangent has a negative real part (smallest 0.58: no divergence). The report
    uses the tangent's own eigenvalues: stable, and no warning (filterwarnings)."""
    E, r, L = 1e7, 0.01, 1.0
    EI = E * math.pi * r**4 / 4
    rod = sj.SoftLink(
        sj.Division(L, sj.CircularSection(r), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2)),
        sj.Material(E),
    )
    lk = sj.Linkage(
        rod,
        point_wrenches=[
            sj.PointWrench(1, [0.0, 0.0, 2 * math.pi * EI, 0, 0, 0], follower=follower)
        ],
    )
    sol = sj.solve_statics(lk, load_steps=4)
    assert float(jnp.abs(sj.tip_pose(lk, sol.q)[:3, 3]).max()) < 1e-12  # closed
    assert bool(sol.stable) and int(sol.n_negative) == 0
    assert float(sol.min_eigenvalue) > 0.1


def test_gradient_through_a_post_buckled_stable_solution():
    """Clamped-free column at 1.5 P_cr, solved from a buckled guess: the stable
    buckled equilibrium; d(tip deflection)/dP by the implicit function theorem
    equals central differences (1e-6 relative: h = 1e-4 P, error ~ h^2)."""
    base = sj.scenes.euler_column(3)  # order 3: the cheaper 4th-order Magnus step
    rod = base.links[0]
    P_cr = float(-base.point_wrenches[0].wrench[3])
    q0 = jnp.zeros(rod.n_dof).at[0].set(1.0)  # tip turned by ~1 rad

    def column(P):
        return sj.Linkage(
            rod, point_wrenches=[sj.PointWrench(1, jnp.stack([0.0, 0, 0, -P, 0, 0]))]
        )

    def deflection(P):
        lk = column(P)
        sol = sj.solve_statics(lk, q0, throw=False)
        return sj.tip_pose(lk, sol.q)[1, 3], (sol.stable, sol.result)

    # One compiled program: the derivative and, at P +- h, the differences.
    f = jax.jit(jax.value_and_grad(deflection, has_aux=True))
    P = 1.5 * P_cr
    (y, (stable, result)), grad = f(P)
    assert result == sj.RESULTS.successful
    assert bool(stable) and abs(float(y)) > 0.1
    h = 1e-4 * P
    fd = float((f(P + h)[0][0] - f(P - h)[0][0]) / (2 * h))
    assert abs(float(grad) - fd) < 1e-6 * abs(fd), (float(grad), fd)
