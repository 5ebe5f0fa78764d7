"""Kinematics: joints against hand-composed transforms, Jacobians against autodiff,
Magnus convergence order, strains and twists, branch independence, jit / vmap.
"""

import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.scipy.linalg import expm

import sorojax as sj
from sorojax.lie import hat, inverse_se3, vee


def _rot(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.asarray(
        expm(hat(jnp.concatenate([jnp.asarray(a * angle), jnp.zeros(3)])))
    )


def _rot_z(angle):
    return _rot((0, 0, 1), angle)


AX = tuple(np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0))
E_ = np.eye(3)
# Joint bases written out by hand (angular rows first), independent of Joint.basis.
HAND_BASIS = {
    "N": np.zeros((6, 0)),
    "R": np.concatenate([AX, np.zeros(3)])[:, None],
    "P": np.concatenate([np.zeros(3), AX])[:, None],
    "H": np.concatenate([AX, 0.05 * np.asarray(AX)])[:, None],
    "U": np.stack([np.r_[E_[1], 0, 0, 0], np.r_[E_[2], 0, 0, 0]], 1),  # default axis x
    "C": np.stack([np.r_[AX, 0, 0, 0], np.r_[0, 0, 0, AX]], 1),
    "A": np.stack(
        [np.r_[E_[2], 0, 0, 0], np.r_[0, 0, 0, E_[0]], np.r_[0, 0, 0, E_[1]]], 1
    ),
    "S": np.concatenate([np.eye(3), np.zeros((3, 3))]),
    "F": np.eye(6),
}


def _joint(kind):
    if kind in ("U", "A", "S", "F", "N"):
        return sj.Joint(kind)
    return sj.Joint(kind, axis=AX, pitch=0.05)


@pytest.mark.parametrize("kind", list(HAND_BASIS))
def test_rigid_chain_fk_equals_hand_composed_transforms(kind, key):
    L1, L2 = 0.3, 0.2
    link1 = sj.RigidLink(_joint(kind), length=L1)
    link2 = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1)), length=L2)
    place = np.stack([np.eye(4), _rot((0, 1, 0), 0.4)])
    lk = sj.Linkage([link1, link2], placements=jnp.asarray(place))
    n1 = HAND_BASIS[kind].shape[1]
    assert lk.n_dof == n1 + 1, f"{kind}: n_dof {lk.n_dof}"
    q = jax.random.uniform(key, (lk.n_dof,), minval=-1.0, maxval=1.0)
    tr = lambda x: np.asarray(sj.translation(x))  # noqa: E731
    g = (
        place[0]
        @ np.asarray(expm(hat(jnp.asarray(HAND_BASIS[kind]) @ q[:n1])))
        @ tr(L1 / 2)
        @ tr(L1 / 2)
        @ place[1]
        @ _rot_z(float(q[n1]))
        @ tr(L2 / 2)
        @ tr(L2 / 2)
    )
    got = np.asarray(sj.tip_pose(lk, q))
    # exp of a constant twist is exact in closed form; expm agrees to roundoff.
    np.testing.assert_allclose(got, g, atol=1e-12, err_msg=f"{kind}: tip pose")


@pytest.mark.parametrize("kind", list(HAND_BASIS))
def test_joint_kind_and_axis_are_read_back_from_its_directions(kind):
    """A joint is stored as its free directions (arrays); kind and axis read back."""
    j = _joint(kind)
    assert j.kind == kind
    assert j.n_dof == HAND_BASIS[kind].shape[1]
    np.testing.assert_allclose(np.asarray(j.basis()), HAND_BASIS[kind], atol=1e-15)
    x, z = (1, 0, 0), (0, 0, 1)
    axis = {"N": x, "U": x, "A": z, "S": x, "F": x}  # defaults; the others take AX
    np.testing.assert_allclose(j.axis, axis.get(kind, AX))


def test_joints_with_as_many_freedoms_are_one_structure():
    """Type and axis are array values: R/P/H, U/C and A/S are one pytree structure
    each (so they share compiled programs), a different count of freedoms is not."""

    def structure(j):
        return jax.tree.structure(j), [x.shape for x in jax.tree.leaves(j)]

    for group in (("R", "P", "H"), ("U", "C"), ("A", "S")):
        first = structure(_joint(group[0]))
        assert all(structure(_joint(k)) == first for k in group[1:]), group
    assert structure(sj.Joint("R")) != structure(sj.Joint("U"))


def test_joint_kind_inside_traced_code_says_where_to_read_it():
    @eqx.filter_jit
    def f(joint):
        return joint.kind

    with pytest.raises(ValueError, match="Joint.kind .* traced"):
        f(sj.Joint("R"))


def test_joint_types_and_axes_share_one_compiled_program():
    """Only the number of a joint's freedoms is structure: a revolute about z, one
    about AX, a prismatic and a helical joint (pitch 0.05 m/rad) under one bar are
    one program (traced once), and each gives its own tip pose (exp of its twist
    times the bar, composed by hand: exact to roundoff)."""
    L, q = 0.3, 0.7
    z, x = np.r_[0.0, 0, 1, 0, 0, 0], np.r_[0.0, 0, 0, 1, 0, 0]
    cases = [
        (sj.Joint("R", axis=(0, 0, 1)), z),
        (sj.Joint("R", axis=AX), HAND_BASIS["R"][:, 0]),
        (sj.Joint("P", axis=(1, 0, 0)), x),
        (sj.Joint("H", axis=AX, pitch=0.05), HAND_BASIS["H"][:, 0]),
    ]

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def tip(lk, q_):
        return sj.tip_pose(lk, q_)

    for j, twist in cases:
        lk = sj.Linkage([sj.RigidLink(j, length=L)])
        g = np.asarray(expm(hat(jnp.asarray(twist * q)))) @ np.asarray(
            sj.translation(L)
        )
        got = np.asarray(tip(lk, jnp.array([q])))
        np.testing.assert_allclose(got, g, atol=1e-12, err_msg=f"{j.kind} {j.axis}")


def test_gradient_reaches_the_joint_axis():
    """d(tip)/d(joint direction) by autodiff equals central differences (1e-8)."""
    L, q = 0.3, 0.7
    lk = sj.Linkage([sj.RigidLink(sj.Joint("R", axis=AX), length=L)])

    def tip_xy(d):
        lk_d = eqx.tree_at(lambda m: m.links[0].joint.directions, lk, d)
        p = sj.tip_pose(lk_d, jnp.array([q]))[:3, 3]
        return p[0] + 2.0 * p[1]

    d0 = lk.links[0].joint.directions
    grad = np.asarray(jax.grad(tip_xy)(d0))
    h = 1e-6
    fd = np.zeros_like(grad)
    for i in range(3):  # the angular rows
        e = jnp.zeros_like(d0).at[i, 0].set(h)
        fd[i, 0] = (float(tip_xy(d0 + e)) - float(tip_xy(d0 - e))) / (2 * h)
    assert np.abs(grad[:3]).max() > 0.1  # the axis matters
    np.testing.assert_allclose(grad[:3], fd[:3], atol=1e-8)


# ------------------------------------------------------------------- hybrid tree
def _hybrid_tree():
    mat = sj.Material(1e6, rho=1000.0)
    soft = sj.SoftLink(
        [
            sj.Division(
                0.4,
                sj.CircularSection((0.02, 0.01)),
                sj.LegendreBasis((1, 1, 1, 1, 1, 1), 1),
            ),
            sj.Division(
                0.3,
                sj.EllipticalSection(0.02, 0.01),
                sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2),
            ),
        ],
        mat,
        joint=sj.Joint("U"),
        g_i=sj.translation(0.01),
        g_f=sj.translation(0, 0.02),
    )
    branch = sj.SoftLink(
        [
            sj.Division(
                0.2,
                sj.RectangularSection(0.02, 0.01),
                sj.MonomialBasis((1, 1, 1, 0, 0, 0), 1),
                xi_ref=lambda X1: jnp.stack([0.0, 0.0, 2.0 * X1, 1.0, 0.0, 0.0]),
            )
        ],
        mat,
        joint=sj.Joint("P", axis=(0, 1, 0)),
    )
    return sj.Linkage(
        [
            sj.RigidLink(sj.Joint("R", axis=(0, 0, 1)), 0.3),
            soft,
            sj.RigidLink(sj.Joint("S"), 0.2),
            branch,
        ],
        parents=(0, 1, 1, 3),
        placements=jnp.stack(
            [jnp.eye(4), jnp.eye(4), sj.translation(0, 0.1), sj.translation(0, 0, 0.05)]
        ),
    )


@pytest.fixture(scope="module")
def tree():
    return _hybrid_tree()


def test_jacobian_recursion_equals_autodiff_of_poses(tree, key):
    q = 0.5 * jax.random.normal(key, (tree.n_dof,))
    g = sj.forward_kinematics(tree, q)
    J = sj.jacobians(tree, q)
    dg = jax.jacfwd(lambda q_: sj.forward_kinematics(tree, q_))(q)  # (n, 4, 4, n_dof)
    # Body Jacobian column k = vee(g^-1 dg/dq_k).
    J_ad = jax.vmap(
        lambda gp, dgp: jax.vmap(
            lambda d: vee(inverse_se3(gp) @ d), in_axes=2, out_axes=1
        )(dgp)
    )(g, dg)
    err = float(jnp.max(jnp.abs(J - J_ad)))
    # Both are exact derivatives of the same discrete map: roundoff only.
    assert err < 1e-10, f"Jacobian recursion vs autodiff of FK: max error {err:.2e}"


def test_jacobian_time_derivative_matches_finite_differences(tree, key):
    k1, k2 = jax.random.split(key)
    q = 0.5 * jax.random.normal(k1, (tree.n_dof,))
    qd = jax.random.normal(k2, (tree.n_dof,))
    Jd = sj.jacobians_time_derivative(tree, q, qd)
    h = 1e-5
    fd = (sj.jacobians(tree, q + h * qd) - sj.jacobians(tree, q - h * qd)) / (2 * h)
    err = float(jnp.max(jnp.abs(Jd - fd)))
    # Central differences: truncation ~ h^2 * |d3J| ~ 1e-9.
    assert err < 1e-7, f"Jdot vs central differences: max error {err:.2e}"


def test_twist_rates_from_the_recursion_equal_jdot_qd(tree, key):
    """kinematics_and_rates: eta = J qd and Jdot qd from the recursion in time.

    Reference: the public Jacobians and their forward-mode time derivative (the
    hybrid tree: R, U, S, P joints, two divisions, all six strains, a curved
    reference strain, a branch). Both are exact: tolerance 1e-12 of the largest
    entry (roundoff of different evaluation orders).
    """
    from sorojax.kinematics._recursion import kinematics_and_rates

    k1, k2 = jax.random.split(key)
    q = 0.5 * jax.random.normal(k1, (tree.n_dof,))
    qd = jax.random.normal(k2, (tree.n_dof,))
    g, J, eta, etadot = jax.jit(kinematics_and_rates)(sj.precompute(tree), q, qd)
    J_ref = sj.jacobians(tree, q)
    rate_ref = jnp.einsum("paj,j->pa", sj.jacobians_time_derivative(tree, q, qd), qd)
    np.testing.assert_allclose(g, sj.forward_kinematics(tree, q), atol=1e-14)
    np.testing.assert_allclose(J, J_ref, atol=1e-14)
    scale = float(jnp.abs(rate_ref).max())
    err_eta = float(jnp.abs(eta - J_ref @ qd).max())
    err_rate = float(jnp.abs(etadot - rate_ref).max()) / scale
    assert err_eta < 1e-12, f"eta vs J qd: {err_eta:.1e}"
    assert err_rate < 1e-12, (
        f"Jdot qd from the recursion vs forward mode: {err_rate:.1e}"
    )


def test_strains_and_twists(tree, key):
    k1, k2 = jax.random.split(key)
    q = 0.3 * jax.random.normal(k1, (tree.n_dof,))
    qd = jax.random.normal(k2, (tree.n_dof,))
    kin = sj.kinematics(tree, q, qd)
    np.testing.assert_allclose(kin.eta, jnp.einsum("pij,j->pi", kin.J, qd), atol=1e-13)
    np.testing.assert_allclose(sj.screw_velocities(tree, q, qd), kin.eta, atol=1e-13)
    lay = tree.layout
    # Branch (link 4): monomial basis 1, X1 per mode over (torsion, bend y, bend z),
    # angular rows divided by the length 0.2; reference strain (0, 0, 2 X1, 1, 0, 0).
    sl = tree.dof_slice(4)
    qb = np.asarray(q[sl])[1:]  # skip the prismatic joint coordinate
    dl = lay.links[3].divisions[0]
    for k, X1 in enumerate(dl.X1):
        expect = np.zeros(6)
        for m in range(3):
            expect[m] = (qb[2 * m] + qb[2 * m + 1] * X1) / 0.2
        expect[2] += 2.0 * X1
        expect[3] = 1.0
        np.testing.assert_allclose(
            kin.xi[dl.first_point + k], expect, atol=1e-12, err_msg=f"strain at X1={X1}"
        )


def test_branches_do_not_depend_on_each_other(tree, key):
    q = 0.5 * jax.random.normal(key, (tree.n_dof,))
    J = np.asarray(sj.jacobians(tree, q))
    lay = tree.layout
    soft_pts = lay.point_link == 2
    branch_pts = np.isin(lay.point_link, [3, 4])
    # Link 2 and links 3-4 hang from the tip of link 1 on separate branches.
    assert np.all(J[soft_pts][:, :, tree.dof_slice(3)] == 0)
    assert np.all(J[soft_pts][:, :, tree.dof_slice(4)] == 0)
    assert np.all(J[branch_pts][:, :, tree.dof_slice(2)] == 0)
    q2 = q.at[tree.dof_slice(4)].add(0.3)
    g1, g2 = sj.forward_kinematics(tree, q), sj.forward_kinematics(tree, q2)
    np.testing.assert_array_equal(g1[soft_pts], g2[soft_pts])


def test_jit_equals_eager_and_vmap_equals_loop(tree, key):
    q = 0.5 * jax.random.normal(key, (tree.n_dof,))
    with jax.disable_jit():
        g_eager = sj.forward_kinematics(tree, q)
        J_eager = sj.jacobians(tree, q)
    np.testing.assert_allclose(sj.forward_kinematics(tree, q), g_eager, atol=1e-13)
    np.testing.assert_allclose(sj.jacobians(tree, q), J_eager, atol=1e-13)
    qs = 0.5 * jax.random.normal(key, (64, tree.n_dof))
    batched = jax.vmap(lambda q_: sj.forward_kinematics(tree, q_))(qs)
    looped = jnp.stack([sj.forward_kinematics(tree, q_) for q_ in qs])
    np.testing.assert_allclose(batched, looped, atol=1e-13)


def test_same_structure_compiles_once(tree, key):
    other = eqx.tree_at(
        lambda lk: lk.links[1].material.E, tree, jnp.asarray(3e6, dtype=float)
    )
    q = jnp.zeros(tree.n_dof)

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def f(lk, q_):
        return sj.jacobians(lk, q_)

    f(tree, q)
    f(other, q)  # new parameter values, same structure: no retrace


# ----------------------------------------------------------- Magnus convergence
def test_magnus_is_fourth_order():
    # Curvature varying as a quadratic in X plus twist: not integrable in closed form.
    def rod(n_gauss):
        div = sj.Division(
            1.0,
            sj.CircularSection(0.01),
            sj.LegendreBasis((1, 1, 1, 0, 0, 0), 2),
            n_gauss=n_gauss,
        )
        return sj.Linkage([sj.SoftLink([div], sj.Material(1e6))])

    q = jnp.array([1.0, 0.5, -0.3, 2.0, -1.0, 0.8, 1.5, 0.7, -0.6])
    ref = np.asarray(sj.tip_pose(rod(64), q))
    ns = (4, 8, 16)
    errs = [np.abs(np.asarray(sj.tip_pose(rod(n), q)) - ref).max() for n in ns]
    slope = np.polyfit(np.log(ns), np.log(errs), 1)[0]
    # 4th-order Magnus / Zanna collocation: error ~ n^-4 (fit over 4..16 points).
    assert -5.0 < slope < -3.5, f"convergence slope {slope:.2f}, errors {errs}"


def test_constant_curvature_is_exact():
    L, kappa, tau = 0.7, 2.0, 1.3
    div = sj.Division(
        L, sj.CircularSection(0.01), sj.LegendreBasis((1, 1, 0, 0, 0, 0), 0), n_gauss=3
    )
    lk = sj.Linkage([sj.SoftLink([div], sj.Material(1e6))])
    q = jnp.array([tau * L, kappa * L])  # q = strain * L (dimensionless)
    xi = jnp.array([tau, kappa, 0.0, 1.0, 0.0, 0.0])
    expected = np.asarray(expm(hat(xi * L)))
    # Constant strain: Magnus is exact; only roundoff remains.
    np.testing.assert_allclose(sj.tip_pose(lk, q), expected, atol=1e-13)


def test_tip_pose_is_the_tip_point(tree, key):
    q = 0.5 * jax.random.normal(key, (tree.n_dof,))
    g = sj.forward_kinematics(tree, q)
    for link in range(1, tree.n_links + 1):
        # Same arithmetic, separately compiled programs: XLA may fuse differently.
        np.testing.assert_allclose(
            sj.tip_pose(tree, q, link), g[tree.tip_point(link)], rtol=0, atol=1e-14
        )


def test_backward_wrench_recursion_equals_jacobian_transpose(tree, key):
    """force_from_wrenches: sum_p J_p^T W_p without forming J (branched hybrid tree).

    The recursion carries wrenches from the tips to the base and maps each Magnus
    step by dOmega^T (formed from the strain bases and ad^T, never as a matrix); the
    reference contracts the recursion's Jacobians with the same random wrenches.
    Both are the same sums in another order: roundoff only (1e-10 relative).
    """
    from sorojax.dynamics._wrench_recursion import (
        force_from_wrenches,
        poses_with_records,
    )

    k1, k2 = jax.random.split(key)
    q = 0.5 * jax.random.normal(k1, (tree.n_dof,))
    W = jax.random.normal(k2, (tree.layout.n_points, 6))

    @jax.jit  # one compile instead of op-by-op dispatch
    def both(q, W):
        data = sj.precompute(tree)
        g, records = poses_with_records(data, q)
        F_ref = jnp.einsum("pai,pa->i", sj.jacobians(tree, q), W)
        return g, force_from_wrenches(data, records, W), F_ref

    g, F, F_ref = both(q, W)
    np.testing.assert_allclose(g, sj.forward_kinematics(tree, q), atol=1e-14)
    err = float(jnp.max(jnp.abs(F - F_ref)) / jnp.max(jnp.abs(F_ref)))
    assert err < 1e-10, f"backward recursion vs J^T W: relative error {err:.2e}"


def test_tangent_apply_is_the_tangent_times_a_twist_with_its_derivative(key):
    """``tangent_apply(Omega, x)`` (cross products, T never formed) is ``T(Omega)
    x`` and its forward derivative along ``dOmega`` is ``(dT dOmega) x`` (the rate
    term ``(dT/dt) Od`` of the dynamics), from zero twist (the series) to
    rotations past pi (the closed forms): roundoff, 1e-12 of unit-scale values."""
    from sorojax.kinematics._step import exp_and_tangent, tangent_apply

    k1, k2, k3 = jax.random.split(key, 3)
    scale = jnp.array([0.0, 1e-3, 0.3, 1.0, 2.0, 4.0, 1.0])[:, None]
    Omega = jax.random.normal(k1, (7, 6)) * scale
    dO, x = jax.random.normal(k2, (7, 6)), jax.random.normal(k3, (7, 6))

    def by_tangent(O, d, x):
        T, dT = jax.jvp(lambda O: exp_and_tangent(O)[2], (O,), (d,))
        return T @ x, dT @ x

    def by_apply(O, d, x):
        return jax.jvp(lambda O: tangent_apply(O, x), (O,), (d,))

    got = jax.jit(jax.vmap(by_apply))(Omega, dO, x)
    want = jax.jit(jax.vmap(by_tangent))(Omega, dO, x)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_many_tangent_rules_equal_autodiff_of_the_kernels(key):
    """The hand-written derivatives used under ``jacfwd`` (statics' Newton tangent)
    equal autodiff of the kernels they replace, to first and second order.

    ``exp_and_tangent_many`` contracts the kernel's derivative along the twist's 6
    coordinates with the tangents; ``_prefix_poses`` differentiates the chains'
    pose products as one prefix sum. Both are exact rewrites of the same
    derivatives (twists from zero, where the Taylor branch is taken, to rotations
    past pi): roundoff only, 1e-11 of the values' scale.
    """
    from sorojax.kinematics import _recursion as rec
    from sorojax.kinematics._step import exp_and_tangent, exp_and_tangent_many

    k1, k2 = jax.random.split(key)
    Omega = (
        jax.random.normal(k1, (7, 6))
        * jnp.array([0.0, 1e-3, 0.3, 1.0, 2.0, 4.0, 1.0])[:, None]
    )
    dO = jax.random.normal(k2, (7, 6))

    def plain(O):
        return jax.vmap(exp_and_tangent)(O)

    # each side as one program (jit), not the kernels' operations one by one
    got = jax.jit(lambda O, d: jax.jvp(exp_and_tangent_many, (O,), (d,))[1])(Omega, dO)
    want = jax.jit(lambda O, d: jax.jvp(plain, (O,), (d,))[1])(Omega, dO)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-11)
    got2 = jax.jit(jax.jacfwd(jax.jacfwd(lambda O: exp_and_tangent_many(O)[2])))(
        Omega[2:4]
    )
    want2 = jax.jit(jax.jacfwd(jax.jacfwd(lambda O: plain(O)[2])))(Omega[2:4])
    np.testing.assert_allclose(got2, want2, rtol=0, atol=1e-11)

    R, p, _ = jax.jit(plain)(Omega)
    R, p = R.reshape(1, 7, 3, 3), p.reshape(1, 7, 3)
    dR = jax.random.normal(k1, R.shape)  # any tangents: the rule is exact for all
    dp = jax.random.normal(k2, p.shape)

    def by_hand(R, p):  # the same products, differentiated by autodiff
        G = [(jnp.eye(3), jnp.zeros(3))]
        for i in range(R.shape[1]):
            Rg, pg = G[-1]
            G.append((Rg @ R[0, i], pg + Rg @ p[0, i]))
        return jnp.stack([g[0] for g in G])[None], jnp.stack([g[1] for g in G])[None]

    for sequential in (False, True):
        prefix = functools.partial(rec._prefix_poses, sequential=sequential)
        got = jax.jit(lambda *a, f=prefix: jax.jvp(f, a[:2], a[2:]))(R, p, dR, dp)
        want = jax.jit(lambda *a: jax.jvp(by_hand, a[:2], a[2:]))(R, p, dR, dp)
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-11)
    hess = jax.jit(jax.hessian(lambda p: jnp.sum(rec._prefix_poses(R, p)[0] ** 3)))(p)
    hess_ref = jax.jit(jax.hessian(lambda p: jnp.sum(by_hand(R, p)[0] ** 3)))(p)
    np.testing.assert_allclose(hess, hess_ref, rtol=0, atol=1e-11)
