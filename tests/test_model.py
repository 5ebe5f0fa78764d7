"""Model building: bad input errors, derived quantities never stale, K and D values."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj


def _rod(**kw):
    args = dict(
        length=0.5,
        section=sj.CircularSection(0.01),
        basis=sj.LegendreBasis((1, 1, 1, 1, 1, 1), 0),
    )
    args.update(kw)
    return sj.SoftLink([sj.Division(**args)], sj.Material(1e6, poisson=0.3, eta=10.0))


@pytest.mark.parametrize(
    "build, field, value",
    [
        (lambda: sj.Division(-0.5), "Division.length", "-0.5"),
        (lambda: sj.Division(0.0), "Division.length", "0.0"),
        (lambda: sj.CircularSection(-0.01), "CircularSection.radius", "-0.01"),
        (lambda: sj.CircularSection((0.02, 0.0)), "CircularSection.radius[1]", "0.0"),
        (lambda: sj.RectangularSection(0.01, -1.0), "RectangularSection.width", "-1.0"),
        (lambda: sj.Material(0.0), "Material.E", "0.0"),
        (lambda: sj.Material(-1e6), "Material.E", "-1000000.0"),
        (lambda: sj.Material(1e6, poisson=0.7), "Material.poisson", "0.7"),
        (lambda: sj.Joint("X"), "Joint.kind", "'X'"),
        (lambda: sj.Joint("R", axis=(0, 0, 0)), "Joint.axis", "(0, 0, 0)"),
        (lambda: sj.Joint("U", stiffness=np.ones(3)), "Joint.stiffness", "(3,)"),
        (
            lambda: sj.LegendreBasis((1, 1, 0, 0, 0, 0), -1),
            "LegendreBasis.orders",
            "-1",
        ),
        (lambda: sj.LegendreBasis((1, 1, 0), 1), "LegendreBasis.modes", "3 entries"),
        (lambda: sj.RigidLink(length=-0.2), "RigidLink.length", "-0.2"),
        (lambda: sj.RigidLink(inertia=np.eye(2)), "RigidLink.inertia", "(2, 2)"),
        (lambda: sj.Division(0.5, xi_ref=np.zeros(5)), "Division.xi_ref", "(5,)"),
        (lambda: sj.Linkage([_rod()], parents=(1,)), "Linkage.parents[0]", "1"),
        (
            lambda: sj.Linkage([_rod(), _rod()], parents=(0, 5)),
            "Linkage.parents[1]",
            "5",
        ),
        (
            lambda: sj.Linkage([_rod(), _rod()], parents=(2, 1)),
            "Linkage.parents[0]",
            "2",
        ),
        (lambda: sj.Linkage([_rod()], parents=(0, 0)), "Linkage.parents", "2 entries"),
        (
            lambda: sj.Linkage([_rod()], placements=np.zeros((2, 4, 4))),
            "Linkage.placements",
            "(2, 4, 4)",
        ),
        (
            lambda: sj.Linkage([_rod()], placements=2 * np.eye(4)[None]),
            "Linkage.placements[0]",
            "SE(3)",
        ),
        (lambda: sj.Linkage([_rod()], gravity=(0, -9.81)), "Linkage.gravity", "(2,)"),
        (lambda: sj.PointWrench(1, np.zeros(3)), "PointWrench.wrench", "(3,)"),
        (
            lambda: sj.Linkage(
                [_rod()], point_wrenches=[sj.PointWrench(2, np.zeros(6))]
            ),
            "link",
            "2",
        ),
        (
            lambda: sj.Linkage(
                [_rod()], point_wrenches=[sj.PointWrench(1, np.zeros(6), 3)]
            ),
            "division",
            "3",
        ),
    ],
)
def test_bad_input_raises_naming_field_and_value(build, field, value):
    with pytest.raises(ValueError) as info:
        build()
    msg = str(info.value)
    assert field in msg and value in msg, f"message lacks {field!r} / {value!r}: {msg}"


def test_wrong_q_shape_is_reported():
    lk = sj.Linkage([_rod()])
    with pytest.raises(ValueError, match=r"n_dof = 6"):
        sj.forward_kinematics(lk, jnp.zeros(5))


def test_stiffness_and_damping_of_a_uniform_rod():
    E, nu, r, L, eta = 1e6, 0.3, 0.01, 0.5, 10.0
    lk = sj.Linkage([_rod()])
    G = E / (2 * (1 + nu))
    A, I = math.pi * r**2, math.pi * r**4 / 4
    k = 6 * (1 + nu) / (7 + 6 * nu)  # Cowper's shear coefficient of a circle
    # Order-0 basis, q dimensionless (angular rows / L): K = L * S Sigma S.
    k_expected = np.array(
        [G * 2 * I / L, E * I / L, E * I / L, E * A * L, k * G * A * L, k * G * A * L]
    )
    d_expected = eta * np.array(
        [2 * I / L, 3 * I / L, 3 * I / L, 3 * A * L, k * A * L, k * A * L]
    )
    np.testing.assert_allclose(np.diag(sj.stiffness_matrix(lk)), k_expected, rtol=1e-12)
    np.testing.assert_allclose(np.diag(sj.damping_matrix(lk)), d_expected, rtol=1e-12)


def test_changed_parameter_is_never_stale():
    lk = sj.Linkage([_rod()])
    K1 = sj.stiffness_matrix(lk)
    lk2 = eqx.tree_at(
        lambda m: m.links[0].material.E, lk, jnp.asarray(2e6, dtype=float)
    )
    K2 = sj.stiffness_matrix(lk2)
    # Every entry scales with E when nu is fixed (E A, E I, G A, G J).
    np.testing.assert_allclose(K2, 2 * K1, rtol=1e-12)
    lk3 = eqx.tree_at(
        lambda m: m.links[0].divisions[0].section.radius.value,
        lk,
        jnp.asarray(0.02, dtype=float),
    )
    K3 = sj.stiffness_matrix(lk3)
    assert float(K3[1, 1]) == pytest.approx(16 * float(K1[1, 1]), rel=1e-12), "EI ~ r^4"


def test_stiffness_is_differentiable_in_radius():
    def k_bend(r):
        lk = sj.Linkage([_rod(section=sj.CircularSection(r))])
        return sj.stiffness_matrix(lk)[1, 1]

    r = 0.01
    # d(E pi r^4 / (4 L)) / dr = E pi r^3 / L.
    assert float(jax.grad(k_bend)(r)) == pytest.approx(
        1e6 * math.pi * r**3 / 0.5, rel=1e-12
    )


def test_tapered_section_and_rigid_inertia():
    sec = sj.CircularSection((0.02, 0.01))
    A0, _, _, _ = sec.properties(0.0)
    A1, _, _, _ = sec.properties(1.0)
    assert float(A0) == pytest.approx(math.pi * 4e-4) and float(A1) == pytest.approx(
        math.pi * 1e-4
    )
    body = sj.RigidLink(
        length=0.4, section=sj.RectangularSection(0.02, 0.04), rho=500.0
    )
    M = np.asarray(body.spatial_inertia())
    m = 500.0 * 0.02 * 0.04 * 0.4
    # Solid box, width 0.04 along y and height 0.02 along z.
    assert M[3, 3] == pytest.approx(m)
    assert M[0, 0] == pytest.approx(m * (0.04**2 + 0.02**2) / 12)
    assert M[1, 1] == pytest.approx(m * (0.4**2 + 0.02**2) / 12)
    assert M[2, 2] == pytest.approx(m * (0.4**2 + 0.04**2) / 12)


def test_only_requested_modes_get_coordinates():
    planar = sj.LegendreBasis((0, 0, 1, 0, 0, 0), 3)
    full = sj.LegendreBasis((1, 1, 1, 1, 1, 1), (2, 3, 3, 1, 0, 0))
    assert planar.n_dof == 4 and full.n_dof == 3 + 4 + 4 + 2 + 1 + 1
    lk = sj.Linkage([sj.RigidLink(sj.Joint("R")), _rod(basis=planar)], parents=(0, 1))
    assert lk.n_dof == 1 + 4
