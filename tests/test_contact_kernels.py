"""Contact samples as leaves of the kinematic chain, and the rod pairs' broad phase.

A contact sample that is not a chain point (an end, a Gauss or a load point) is a
leaf: one Magnus step from the chain point before it. Its pose, twist, Jacobian and
twist rate must be those of that step (checked against autodiff of the poses), the
chain's points must not move when samples are added, and the dynamics, which forms
Jacobians at the chain's points only, must map the leaves' wrenches exactly as J^T.
The broad phase must give the narrow phase every pair that can touch (the same
forces as examining every pair), and say so when it cannot.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.dynamics._eom import lazy_kinematics
from sorojax.dynamics._wrench_recursion import (
    force_from_point_rates,
    force_from_wrenches,
    poses_with_records,
)
from sorojax.kinematics._recursion import (
    kinematics_and_rates,
    point_jacobians,
    point_rates,
    rest_rates,
)
from sorojax.model._precompute import precompute


def _rod(n_samples):
    """A rod on a planar joint, bending both ways (quadratic), over a floor."""
    rod = sj.SoftLink(
        [sj.Division(0.3, sj.CircularSection(0.01),
                     sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2))],
        sj.Material(E=1e6, rho=1000.0, eta=1e3),
        joint=sj.Joint("A", axis=(0, 1, 0)),
    )  # fmt: skip
    contact = None
    if n_samples:
        law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, damping=10.0,
                            static_friction=0.5)  # fmt: skip
        contact = sj.Contact(sj.Plane(), law, spacing=0.3 / (n_samples - 1))
    return sj.Linkage([rod], gravity=(0, 0, -9.81), contact=contact)


@pytest.fixture(scope="module")
def rods():
    return _rod(None), _rod(13)


@pytest.fixture(scope="module")
def state(rods):
    rng = np.random.default_rng(3)
    n = rods[1].n_dof
    return jnp.asarray(rng.normal(size=n)), jnp.asarray(rng.normal(size=n))


def test_samples_are_leaves_and_leave_the_chain_unchanged(rods, state):
    bare, sampled = rods
    lay = sampled.layout
    assert lay.point_leaf.sum() == 12 - 1  # 13 samples, the end's on the chain...
    # ...less those at the ends and Gauss points (none here but the two ends)
    q, _ = state
    g0, g1 = sj.forward_kinematics(bare, q), sj.forward_kinematics(sampled, q)
    chain = np.flatnonzero(~lay.point_leaf)
    # same chain, same poses: bit for bit (the same steps, in the same order)
    np.testing.assert_array_equal(np.asarray(g1[chain]), np.asarray(g0))


def test_leaf_twists_jacobians_and_rates_are_the_derivatives_of_the_poses(rods, state):
    _, lk = rods
    q, qd = state
    data = precompute(lk)

    @jax.jit  # one program, not the kernels' operations one by one
    def terms(q, qd):
        g, J, eta, etadot = kinematics_and_rates(data, q, qd)
        gdot = jax.jvp(lambda q_: sj.forward_kinematics(lk, q_), (q,), (qd,))[1]
        rate = jax.jvp(lambda q_: kinematics_and_rates(data, q_, qd)[2], (q,), (qd,))[1]
        pr = point_rates(data, q, qd)
        return g, J, eta, etadot, gdot, rate, pr.g, pr.eta, point_jacobians(data, pr)

    g, J, eta, etadot, gdot, rate, pr_g, pr_eta, pr_J = terms(q, qd)
    Rt = jnp.swapaxes(g[:, :3, :3], 1, 2)
    W = Rt @ gdot[:, :3, :3]
    twist = jnp.concatenate(
        [jnp.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], 1),
         jnp.einsum("pij,pj->pi", Rt, gdot[:, :3, 3])], axis=1,
    )  # fmt: skip
    # round-off of O(10) products of unit-size numbers
    np.testing.assert_allclose(eta, twist, atol=1e-12, err_msg="eta = (g^-1 gdot)^v")
    np.testing.assert_allclose(eta, J @ qd, atol=1e-12, err_msg="eta = J qd")
    np.testing.assert_allclose(etadot, rate, atol=1e-11, err_msg="Jdot qd")
    np.testing.assert_allclose(pr_g, g, atol=0.0, err_msg="point_rates poses")
    np.testing.assert_allclose(pr_eta, eta, atol=1e-13, err_msg="point_rates twists")
    # every point's Jacobian from the chain points' (the contacts' tangent in W)
    np.testing.assert_allclose(pr_J, J, atol=1e-13, err_msg="point_jacobians")


def test_hooks_read_the_same_kinematics_from_the_dynamics_rates(rods, state):
    # Inside the dynamics the hooks' Kinematics reuses point_rates' poses and twists
    # and carries the Jacobians from them; it must equal the full pass's, leaves
    # (contact samples) included. A hook is given only the fields it reads (the
    # others zeros, so that they are neither traced nor compiled).
    _, lk = rods
    q, qd = state
    data = precompute(lk)

    @jax.jit  # one program, not the kernels' operations one by one
    def terms(q, qd):
        kin_fn = lazy_kinematics(data, q, qd, point_rates(data, q, qd))
        damping = kin_fn(lambda k: -2.0 * k.eta)  # reads the twists only
        mapped = kin_fn(lambda k: jnp.einsum("pai,pa->i", k.J, k.eta))
        return kinematics_and_rates(data, q, qd), kin_fn(), damping, mapped

    (g, J, eta, _), kin, damping, mapped = terms(q, qd)
    for name, ref in (("g", g), ("J", J), ("eta", eta)):
        # round-off of O(10) products of unit-size numbers, as above
        np.testing.assert_allclose(getattr(kin, name), ref, atol=1e-12, err_msg=name)
    np.testing.assert_array_equal(damping.eta, kin.eta)
    for name in ("g", "J", "xi", "Jdot"):
        assert not np.any(getattr(damping, name)), (
            f"{name} given to a hook not reading it"
        )
    np.testing.assert_array_equal(mapped.J, kin.J)
    assert not np.any(mapped.Jdot)


def test_rest_rates_are_the_point_rates_at_rest(rods, state):
    # A start's velocity projection takes the poses and Jacobians at rest without
    # the rates' columns: the same poses and chain Jacobians as point_rates at
    # qd = 0 (the same kernels, up to XLA's fusion: round-off), zero twists.
    _, lk = rods
    q, _ = state
    data = precompute(lk)
    full, rest = point_rates(data, q, jnp.zeros_like(q)), rest_rates(data, q)
    np.testing.assert_allclose(rest.g, full.g, atol=1e-14, err_msg="poses")
    np.testing.assert_allclose(rest.J, full.J, atol=1e-13, err_msg="Jacobians")
    assert not np.any(rest.eta) and not np.any(rest.etadot)


def test_leaves_wrenches_map_as_their_jacobians_transpose(rods, state):
    _, lk = rods
    q, qd = state
    data = precompute(lk)
    W = jnp.asarray(np.random.default_rng(4).normal(size=(lk.n_points, 6)))
    J = kinematics_and_rates(data, q, qd)[1]
    want = jnp.einsum("pai,pa->i", J, W)
    tol = 1e-12 * float(jnp.max(jnp.abs(want)))  # round-off of sums of O(100) terms
    got = force_from_point_rates(data, point_rates(data, q, qd), W)
    np.testing.assert_allclose(got, want, atol=tol, err_msg="dynamics' mapping")
    got = force_from_wrenches(data, poses_with_records(data, q)[1], W)
    np.testing.assert_allclose(got, want, atol=tol, err_msg="backward recursion")


def test_leaf_on_a_constant_strain_rod_lies_on_the_exact_arc():
    """Constant curvature: every Magnus step is exact, so is every leaf's pose."""
    L, kappa = 0.5, 3.0
    rod = sj.SoftLink(
        [sj.Division(L, sj.CircularSection(0.01), sj.LegendreBasis((0, 0, 1, 0, 0, 0), 0))],
        sj.Material(E=1e6, rho=1000.0),
    )  # fmt: skip
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4)
    lk = sj.Linkage(
        [rod], contact=sj.Contact(sj.Plane(point=(0.0, 0.0, -1.0)), law, spacing=L / 7)
    )
    q = sj.strain_coordinates(lk, [0.0, 0.0, kappa, 0.0, 0.0, 0.0])
    g = sj.forward_kinematics(lk, q)
    lay = lk.layout
    leaves = np.flatnonzero(lay.point_leaf)
    assert len(leaves) >= 5
    s = lay.point_X1[leaves] * L
    exact = np.stack([np.sin(kappa * s) / kappa, (1 - np.cos(kappa * s)) / kappa], 1)
    np.testing.assert_allclose(g[leaves, :2, 3], exact, atol=1e-13)


def _crossing(capacity):
    """Two rods crossing at right angles, the upper one 5 mm into the lower."""
    rods = [
        sj.SoftLink(
            [
                sj.Division(
                    1.0,
                    sj.CircularSection(0.01),
                    sj.LegendreBasis((0, 1, 1, 0, 0, 0), 3),
                )
            ],
            sj.Material(E=1e6, rho=1000.0, eta=100.0),
        )  # fmt: skip
        for _ in range(2)
    ]
    pl = np.stack([np.eye(4)] * 2)
    pl[0, :3, 3] = [-0.5, 0.0, 0.0]
    pl[1, :3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    pl[1, :3, 3] = [0.0, -0.5, 0.0185]
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, damping=1.0,
                        static_friction=0.3)  # fmt: skip
    c = sj.Contact((), law, rod_pairs=[(1, 2)], spacing=0.02, pair_capacity=capacity)
    return sj.Linkage(rods, parents=(0, 0), placements=pl, gravity=(0, 0, -9.81),
                      contact=c)  # fmt: skip


@pytest.fixture(scope="module")
def crossings():
    # default capacity: 4 per segment (400 of the 2500 segment pairs); every pair
    return _crossing(None), _crossing(10**6)


def test_broad_phase_gives_the_forces_of_every_pair(crossings):
    broad, every = crossings
    rng = np.random.default_rng(0)
    q = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.002
    qd = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.1
    a, b = sj.contact_state(broad, q, qd), sj.contact_state(every, q, qd)
    assert (len(a.link), len(b.link)) == (400, 2500)
    assert not bool(a.overflow)
    assert int(jnp.sum(b.active)) >= 2, "the rods must touch for this test"
    assert int(jnp.sum(a.active)) == int(jnp.sum(b.active))
    np.testing.assert_allclose(
        jnp.sum(a.force, 0), jnp.sum(b.force, 0), rtol=1e-12, err_msg="total force"
    )
    fa, fb = sj.forward_dynamics(broad, q, qd), sj.forward_dynamics(every, q, qd)
    # the same contacts summed in another order: round-off
    np.testing.assert_allclose(fa, fb, atol=1e-12 * float(jnp.max(jnp.abs(fb))))


def test_small_pass_gives_the_full_pass_forces_and_report(crossings):
    """Candidates fewer than a quarter of the capacity take a narrow phase on a
    quarter of its rows, padded with empty rows: the same sums at the samples and
    the same report rows as the full pass (the same pairs' arithmetic: exact), and
    under vmap (the conditional becomes a select) the same as plain calls."""
    from sorojax.dynamics import _contact as kc

    broad, _ = crossings
    rng = np.random.default_rng(1)
    q = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.002
    qd = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.1
    kin = sj.kinematics(broad, q, qd)
    g, eta = kin.g, kin.eta
    entry = kc._pair_list(broad)[0]
    table, c = kc._broad_phase(broad.contact, g, entry)
    K, small = (
        kc._capacity(broad.contact, entry),
        kc._small_capacity(broad.contact, entry),
    )
    assert (K, small) == (400, 100)
    assert 2 <= int(c[-1]) < small, "the candidates must fit the small pass"
    args = (broad.contact, entry, table, c, g, eta, True, K)
    (sa, ra), (sb, rb) = kc._pair_pass(*args, small), kc._pair_pass(*args, K)
    for x, y in zip((*sa, *ra), (*sb, *rb), strict=True):
        np.testing.assert_array_equal(x, y)
    Q = q[None] + 1e-3 * jnp.asarray(rng.normal(size=(3, broad.n_dof)))
    batched = jax.vmap(lambda q: sj.forward_dynamics(broad, q, qd))(Q)
    for i in range(3):
        np.testing.assert_allclose(
            batched[i], sj.forward_dynamics(broad, Q[i], qd), rtol=1e-12, atol=1e-12
        )


@pytest.mark.slow
def test_broad_phase_gradients_equal_those_of_every_pair(crossings):
    broad, every = crossings
    rng = np.random.default_rng(0)
    q = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.002
    qd = jnp.asarray(rng.normal(size=broad.n_dof)) * 0.1

    def loss(lk, q):
        return jnp.sum(sj.forward_dynamics(lk, q, qd) ** 2)

    ga, gb = (
        jax.grad(lambda q: loss(broad, q))(q),
        jax.grad(lambda q: loss(every, q))(q),
    )
    np.testing.assert_allclose(ga, gb, atol=1e-10 * float(jnp.max(jnp.abs(gb))))


def test_broad_phase_overflow_is_a_result_code_not_a_missed_contact():
    lk = _crossing(2)  # fewer than the overlapping pairs
    q = jnp.zeros(lk.n_dof)
    assert bool(sj.contact_state(lk, q).overflow)
    assert not np.any(np.isfinite(np.asarray(sj.forward_dynamics(lk, q, q))))
    # NaN forces: every step is rejected (until max_steps), and the report says why
    tr = sj.simulate(lk, 0.01, q, n_save=2, max_steps=8, throw=False)
    assert tr.result == sj.RESULTS.contact_overflow
    with pytest.raises(ValueError, match="pair_capacity"):
        sj.Contact((), sj.ContactLaw(stiffness=1.0), pair_capacity=0)


@pytest.mark.parametrize("n_true", [0, 3, 8, 40])
def test_broad_phase_compaction_equals_nonzero(n_true):
    """The candidates' compaction is ``jnp.nonzero(mask, size=k, fill_value=0)``
    (exact integers): fewer, as many and more True entries than ``k = 8``."""
    from sorojax.dynamics._contact import _first_true

    rng = np.random.default_rng(n_true)
    mask = np.zeros(97, bool)
    mask[rng.choice(97, n_true, replace=False)] = True
    mask = jnp.asarray(mask)
    idx = jax.jit(_first_true, static_argnums=1)(jnp.cumsum(mask.astype(int)), 8)
    np.testing.assert_array_equal(idx, jnp.nonzero(mask, size=8, fill_value=0)[0])
