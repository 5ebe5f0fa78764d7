"""Many contact samples: the leaves' steps computed component by component.

With at least ``MIN_LEAVES`` leaves (4th-order steps) the dynamics poses the leaves,
takes their twists and maps their wrenches with the kernels of
:mod:`sorojax.kinematics._leaves` (rows over the leaves) instead of the stacked ones
of :mod:`sorojax.kinematics._recursion`. Both evaluate the same formulas, so poses,
twists, Jacobians, generalised forces and their derivatives must agree to rounding
(1e-12 relative; their derivatives 1e-11), on strains large
enough that the exp's coefficients take both their Taylor series (theta < 1) and
their closed forms. The strains at the steps' nodes and the force of their
covectors read the bases by their nonzero entries (``LeafBasis``): the same products
as the full-width bases, also on a rod of two divisions whose second basis mixes
strain rows. Contact wrenches at distinct sample points are summed by a gather
instead of a scatter: the same sums. The obstacles' contact on the leaves is formed
on their rows too (world positions and velocities in, wrenches at the chain points
out): the dynamics' forces and their derivatives agree with the stacked path's
(contact wrenches at every point, mapped by the stacked kernels) to rounding.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_contact_kernels import _rod  # the same rod and floor

import sorojax as sj
from sorojax import lie
from sorojax.dynamics._contact import _add_rows
from sorojax.dynamics._eom import mass_and_force
from sorojax.dynamics._wrench_recursion import force_from_point_rates
from sorojax.kinematics import _leaves
from sorojax.kinematics._recursion import (
    chain_layout,
    leaf_sums,
    point_jacobians,
    point_rates,
    poses_and_jacobians,
)
from sorojax.model._precompute import precompute


@pytest.fixture(scope="module")
def rod():
    return _rod(40)


def _mixed(X):
    """Two columns: bending both ways in one (cos, sin), torsion in the other."""
    z = jnp.zeros_like(X)
    bend = jnp.stack([z, jnp.cos(jnp.pi * X), jnp.sin(jnp.pi * X), z, z, z])
    twist = jnp.stack([1.0 + X, z, z, z, z, z])
    return jnp.stack([bend, twist], axis=1)


@pytest.fixture(scope="module")
def two_divisions():
    """60 samples on a rod whose divisions have different bases and columns."""
    sec, law = sj.CircularSection(0.01), sj.ContactLaw(stiffness=1e4, smoothing=1e-4)
    rod = sj.SoftLink(
        [sj.Division(0.15, sec, sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1)),
         sj.Division(0.15, sec, sj.CustomBasis(_mixed, 2, order=2))],
        sj.Material(E=1e6, rho=1000.0, eta=1e3),
        joint=sj.Joint("A", axis=(0, 1, 0)),
    )  # fmt: skip
    contact = sj.Contact(sj.Plane(), law, spacing=0.3 / 59)
    return sj.Linkage([rod], gravity=(0, 0, -9.81), contact=contact)


@pytest.fixture(scope="module")
def state(rod):
    """Large strains (tens of 1/m): some leaves' steps turn by more than a radian."""
    rng = np.random.default_rng(5)
    q = jnp.asarray(rng.normal(size=rod.n_dof) * 12.0)
    qd = jnp.asarray(rng.normal(size=rod.n_dof))
    return q, qd


def _both(fn, *args):
    """``fn(*args)`` compiled with the leaves' kernels and with the stacked ones."""
    new = jax.jit(lambda *a: fn(*a))(*args)
    old_min = _leaves.MIN_LEAVES
    _leaves.MIN_LEAVES = 10**9
    try:
        old = jax.jit(lambda *a: fn(*a))(*args)
    finally:
        _leaves.MIN_LEAVES = old_min
    return new, old


def _close(a, b, rtol):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        scale = max(float(jnp.max(jnp.abs(y))), 1e-300)
        assert float(jnp.max(jnp.abs(x - y))) <= rtol * scale


def test_the_leaves_kernels_apply_from_their_threshold(rod):
    data = precompute(rod)
    assert len(data.leaf_points) >= _leaves.MIN_LEAVES
    assert _leaves.applies(data)
    assert not _leaves.applies(precompute(_rod(12)))  # 10 leaves: the stacked ones


def test_poses_twists_jacobians_and_forces_agree_with_the_stacked_kernels(rod, state):
    data = precompute(rod)
    q, qd = state
    W = jnp.asarray(np.random.default_rng(6).normal(size=(rod.n_points, 6)))

    def kin(q, qd, W):
        pr = point_rates(data, q, qd)
        return (
            pr.g,
            pr.eta,
            point_jacobians(data, pr),
            force_from_point_rates(data, pr, W),
        )

    new, old = _both(kin, q, qd, W)
    # the leaves' own steps turn by less and by more than a radian (theta^2 = 1 is
    # where the coefficients switch from their series to their closed forms)
    th2 = jax.jit(lambda q: point_rates(data, q, qd).leaves.theta2)(q)
    assert float(jnp.min(th2)) < 1.0 < float(jnp.max(th2))
    _close(new, old, 1e-12)


def test_derivatives_agree_with_the_stacked_kernels(rod, state):
    """Forward and reverse mode through poses, twists and the mapped forces."""
    data = precompute(rod)
    q, qd = state
    rng = np.random.default_rng(7)
    dq, dqd = (jnp.asarray(rng.normal(size=rod.n_dof)) for _ in range(2))
    W = jnp.asarray(rng.normal(size=(rod.n_points, 6)))

    def f(q, qd):
        pr = point_rates(data, q, qd)
        return pr.g, pr.eta, force_from_point_rates(data, pr, W * pr.eta)

    def tangents(q, qd):
        jvp = jax.jvp(f, (q, qd), (dq, dqd))[1]
        grad = jax.grad(lambda q, qd: sum(jnp.sum(jnp.sin(x)) for x in f(q, qd)),
                        (0, 1))(q, qd)  # fmt: skip
        return jvp, grad

    new, old = _both(tangents, q, qd)
    _close(new, old, 1e-11)


def test_steps_all_under_a_radian_agree_with_the_stacked_kernels(rod):
    """Small strains: every leaf's step turns by less than a radian, so the exp's
    closed forms are skipped (their sine and cosine are not evaluated); values and
    forward-mode derivatives as the stacked kernels' (which always form them)."""
    data = precompute(rod)
    rng = np.random.default_rng(8)
    q, qd, dq = (jnp.asarray(rng.normal(size=rod.n_dof)) for _ in range(3))
    W = jnp.asarray(rng.normal(size=(rod.n_points, 6)))

    def f(q):
        pr = point_rates(data, q, qd)
        return pr.g, pr.eta, force_from_point_rates(data, pr, W * pr.eta)

    def values_and_tangents(q):
        return jax.jvp(f, (q,), (dq,))

    th2 = jax.jit(lambda q: point_rates(data, q, qd).leaves.theta2)(q)
    assert float(jnp.sqrt(jnp.max(th2))) < 1.0
    new, old = _both(values_and_tangents, q)
    _close(new, old, 1e-11)


def test_leaf_sums_equal_a_scatter_add(rod):
    """Each chain point's sum of its leaves' rows (differences of prefix sums): the
    sums of a scatter-add, to rounding (1e-13 of the largest sum)."""
    lay = chain_layout(precompute(rod))
    y = np.random.default_rng(9).normal(size=(len(lay.leaf_row), 6))
    ref = np.zeros((len(lay.core), 6))
    np.add.at(ref, lay.leaf_row, y)
    assert np.count_nonzero(lay.leaf_stop > lay.leaf_first) > 1
    sums = np.asarray(leaf_sums(lay, jnp.asarray(y)))
    assert np.max(np.abs(sums - ref)) <= 1e-13 * np.max(np.abs(ref))


@pytest.mark.parametrize("n", [12, 40])
def test_twists_as_one_jacobian_column_equal_the_dynamics_twists(n, state):
    """The contact report's twists, ``J qd`` formed as one column (no Jacobian),
    equal the dynamics' recursion of twists (the leaves' twists by the stacked
    kernels with 12 samples, by their own with 40) to rounding: ``eta = J qd``."""
    data = precompute(_rod(n))
    assert _leaves.applies(data) == (n == 40)
    q, qd = state
    g, Jv = jax.jit(lambda q, qd: poses_and_jacobians(data, q, qd[:, None]))(q, qd)
    pr = jax.jit(lambda q, qd: point_rates(data, q, qd))(q, qd)
    _close((g, Jv[..., 0]), (pr.g, pr.eta), 1e-12)


def test_vmap_equals_plain_calls(rod, state):
    data = precompute(rod)
    q, qd = state
    qs = q[None] + jnp.linspace(-0.5, 0.5, 3)[:, None]
    f = jax.jit(lambda q: point_rates(data, q, qd).eta)
    batched = jax.jit(jax.vmap(lambda q: point_rates(data, q, qd).eta))(qs)
    _close(batched, jnp.stack([f(x) for x in qs]), 1e-13)


def test_contact_wrenches_gathered_at_distinct_points_equal_a_scatter_add():
    """Distinct static points (one gather) give the scatter-add's sums exactly."""
    rng = np.random.default_rng(8)
    points = np.array([4, 0, 2, 7, 1])  # unsorted, some rows receive nothing
    values = jnp.asarray(rng.normal(size=(len(points), 6)))
    W = jnp.asarray(rng.normal(size=(9, 6)))
    gathered = jax.jit(lambda W, v: _add_rows(W, points, v))(W, values)
    jaxpr = jax.make_jaxpr(lambda W, v: _add_rows(W, points, v))(W, values)
    assert "scatter" not in str(jaxpr)
    assert bool(jnp.all(gathered == W.at[points].add(values)))


def test_leaf_bases_by_their_nonzero_entries_equal_the_full_width_products(
    rod, two_divisions
):
    """Strains, columns and transposed products of LeafBasis against ``Phi_t``."""
    rng = np.random.default_rng(9)
    for lk in (rod, two_divisions):
        st = precompute(lk).leaf_steps
        lb = st.compact
        assert lb is not None
        x = jnp.asarray(rng.normal(size=lk.n_dof))
        Z = jnp.asarray(rng.normal(size=st.xi_ref_t.shape))
        last = (1, 2, 0)  # StepData's (n_steps, n_nodes, 6) -> (n_nodes, 6, n_steps)
        _close(lb.strains(x, st.xi_ref_t), jnp.transpose(st.strains(x), last), 1e-14)
        rates = jnp.transpose(st.strains(x, ref=False), last)
        _close(lb.strains(x), rates, 1e-14)
        full = st.basis_transpose(jnp.transpose(Z, (2, 0, 1)))
        _close(lb.transpose(tuple(Z), lk.n_dof), full, 1e-13)
        _close(lb.columns(lk.n_dof), jnp.transpose(st.basis(), (1, 2, 3, 0)), 0.0)
    # a Legendre column is read on its mode's row; a custom basis's on every row
    assert precompute(rod).leaf_steps.compact.row == (1, 1, 1, 2, 2, 2)
    lb = precompute(two_divisions).leaf_steps.compact
    assert len(lb.segments) == 2
    assert lb.row == (0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5)


def test_two_divisions_agree_with_the_stacked_kernels(two_divisions):
    """Poses, twists, Jacobians, forces and their forward derivatives, two divisions."""
    lk = two_divisions
    data = precompute(lk)
    rng = np.random.default_rng(10)
    q, qd, dq = (jnp.asarray(rng.normal(size=lk.n_dof) * 6.0) for _ in range(3))
    W = jnp.asarray(rng.normal(size=(lk.n_points, 6)))

    def f(q):
        pr = point_rates(data, q, qd)
        J = point_jacobians(data, pr)
        return pr.g, pr.eta, J, force_from_point_rates(data, pr, W)

    new, old = _both(lambda q: jax.jvp(f, (q,), (dq,)), q)
    _close(new, old, 1e-11)


def _obstacles_rod(self_contact: bool, moving: bool = True):
    """40 samples against a tilted plane (forward friction) and a sphere.

    The sphere has its own law; with ``self_contact`` the rod's segment pairs load
    the leaves as well (their wrenches then reach the leaves' rows both ways). The
    plane moves, or (``moving`` False) stands still, offset and in a frame of its
    own (the rows path then meets it in the chain points' frames).
    """
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, damping=10.0,
                        static_friction=0.5, forward_friction=0.2)  # fmt: skip
    other = sj.ContactLaw(stiffness=3e3, smoothing=2e-4, damping=5.0,
                          static_friction=0.3)  # fmt: skip

    def lift(t):
        return jnp.eye(4).at[2, 3].set(0.002 * jnp.sin(3.0 * t)).at[0, 3].set(0.01 * t)

    if moving:
        plane = sj.Plane(normal=(0.005, 0.002, 1.0), motion=lift)
    else:
        pose = np.array(lift(0.4))
        axis = np.array([0.3, -0.4, 70.0]) / np.linalg.norm([0.3, -0.4, 70.0])
        pose[:3, :3] = np.asarray(lie.exp_so3(jnp.asarray(0.7 * axis)))
        plane = sj.Plane(point=(0.01, 0.02, 0.001), normal=(0.005, 0.002, 1.0),
                         pose=pose)  # fmt: skip
    ball = sj.Sphere(0.02, centre=(0.2, 0.0, 0.03))
    rod = _rod(None).links[0]  # test_contact_kernels' rod
    contact = sj.Contact((plane, ball), law, spacing=0.3 / 39,
                         obstacle_laws={1: other},
                         self_contact=(1,) if self_contact else ())  # fmt: skip
    place = np.eye(4)
    place[2, 3] = 0.008  # pressed into the plane
    return sj.Linkage(
        [rod], placements=place[None], gravity=(0, 0, -9.81), contact=contact
    )


@pytest.mark.parametrize(
    "self_contact, moving", [(False, True), (True, True), (False, False)]
)
def test_obstacles_on_the_leaves_rows_agree_with_the_stacked_path(self_contact, moving):
    """``(M, f)`` and their forward derivatives, both obstacles touching."""
    lk = _obstacles_rod(self_contact, moving)
    data = precompute(lk)
    assert _leaves.applies(data)
    rng = np.random.default_rng(11)
    q = jnp.asarray(np.r_[0.0, 0.0, 0.0, rng.normal(size=lk.n_dof - 3) * 0.03])
    qd, dq, dqd = (jnp.asarray(rng.normal(size=lk.n_dof) * 0.2) for _ in range(3))
    t = jnp.asarray(0.3)
    st = sj.contact_state(lk, q, qd, t)
    for k in (0, 1):  # the plane and the sphere both push
        assert int(jnp.sum((st.obstacle == k) & (st.normal_force > 0))) >= 3

    def f(q, qd):
        return mass_and_force(lk, data, t, q, qd)

    new, old = _both(lambda q, qd: jax.jvp(f, (q, qd), (dq, dqd)), q, qd)
    _close(new, old, 1e-11)
