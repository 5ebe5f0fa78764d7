"""The mass matrix from composite inertias and the bases on their groups' columns.

With two coordinate groups or more (joints with coordinates, divisions) and enough
coordinates (``MIN_GROUP_DOF``, lowered here so that small models take it) the chain's
steps keep their bases on their own group's columns (``GroupBasis``) and the
dynamics forms ``M`` from composite inertias (:mod:`sorojax.dynamics._composite`)
and maps every wrench, the inertial ones included, by the backward sweep, where
the single-group path forms every point's Jacobian and ``sum w J^T M J``. Both are
the same sums regrouped, so ``M`` and the forces must agree to rounding (1e-12
relative; their forward derivatives 1e-10, on the chain and the tree; the
accelerations, which divide by an ill-conditioned M, by their backward error): on a
free rod of three divisions with different bases (one a
``CustomBasis`` mixing strain rows) on a floor, the manual's branched hybrid with
rigid links and a closed loop, a padded size class, a rod of 6th-order steps, and
with added mass.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax import scenes
from sorojax.dynamics._composite import _take_runs
from sorojax.dynamics._eom import mass_and_force, spd_solve
from sorojax.dynamics._mass import _mass_from_J
from sorojax.kinematics._recursion import chain_layout, point_rates, rows_of
from sorojax.model import _precompute
from sorojax.model._precompute import precompute


def _mixed(X):
    """Two columns: bending both ways in one (cos, sin), torsion in the other."""
    z = jnp.zeros_like(X)
    bend = jnp.stack([z, jnp.cos(jnp.pi * X), jnp.sin(jnp.pi * X), z, z, z])
    twist = jnp.stack([1.0 + X, z, z, z, z, z])
    return jnp.stack([bend, twist], axis=1)


def _free_rod():
    """A free rod of three unlike divisions on a floor (8 contact samples)."""
    sec = sj.CircularSection(0.01)
    rod = sj.SoftLink(
        [sj.Division(0.1, sec, sj.LegendreBasis((1, 1, 1, 0, 0, 0), 2)),
         sj.Division(0.1, sec, sj.CustomBasis(_mixed, 2, order=2)),
         sj.Division(0.1, sec, sj.LegendreBasis((0, 1, 1, 1, 1, 1), (0, 1, 1, 0, 0, 0)))],
        sj.Material(E=1e6, rho=1000.0, eta=1e3),
        joint=sj.Joint("F"),
    )  # fmt: skip
    law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, static_friction=0.5)
    contact = sj.Contact(sj.Plane(point=(0, 0, -0.05)), law, spacing=0.3 / 7)
    return sj.Linkage([rod], gravity=(0, 0, -9.81), contact=contact)


def _sixth():
    """A pinned rod of two quartic divisions: 6th-order steps."""
    sec = sj.CircularSection(0.01)
    div = sj.Division(0.15, sec, sj.LegendreBasis((0, 1, 1, 0, 0, 0), 4))
    rod = sj.SoftLink(
        [div, div], sj.Material(E=1e6, rho=1000.0), joint=sj.Joint("R", axis=(0, 1, 0))
    )
    return sj.Linkage([rod], gravity=(0, 0, -9.81))


def _added(linkage):
    """The free rod with an added inertia at every point (a fluid's, say)."""
    n_points = precompute(linkage).point_weight.shape[0]
    A = np.diag([1e-7, 2e-7, 2e-7, 0.3, 0.2, 0.2])
    return eqx.tree_at(
        lambda lk: lk.added_mass,
        linkage,
        jnp.asarray(np.broadcast_to(A, (n_points, 6, 6))),
        is_leaf=lambda x: x is None,
    )


MODELS = {
    "free rod": _free_rod,
    "manual hybrid": scenes.manual_hybrid,
    "padded": lambda: sj.size_class(scenes.free_fall_rod(3, eta=1e4), 6, divisions=3),
    "6th order": _sixth,
    "added mass": lambda: _added(_free_rod()),
}


@pytest.fixture(scope="module", params=list(MODELS))
def case(request):
    linkage = MODELS[request.param]()
    least = _precompute.MIN_GROUP_DOF
    _precompute.MIN_GROUP_DOF = 0
    try:  # not the cached precompute: its trace of a structure is kept (per process)
        data = _precompute._precompute(linkage)
    finally:
        _precompute.MIN_GROUP_DOF = least
    assert data.steps.group is not None  # several groups: the composite path
    rng = np.random.default_rng(3)
    q = jnp.asarray(rng.normal(size=linkage.n_dof) * 3.0)
    qd = jnp.asarray(rng.normal(size=linkage.n_dof))
    return linkage, data, q, qd, request.param


def _without_groups(data):
    """The same data on the single-group path (full-width bases, Jacobians)."""
    return eqx.tree_at(lambda d: d.steps.group, data, None)


def _rel(a, b):
    return float(jnp.max(jnp.abs(a - b)) / jnp.max(jnp.abs(b)))


def test_group_bases_equal_full_width(case):
    """Strains and transposed products equal the full-width bases' (1e-14)."""
    _, data, q, _, _ = case
    st = data.steps
    rng = np.random.default_rng(4)
    Z = jnp.asarray(rng.normal(size=st.xi_ref_z.shape))
    full = jnp.einsum("szan,n->sza", st.Phi_z, q)
    assert _rel(st.group.strains(q), full) < 1e-14
    full_t = jnp.einsum("szan,sza->n", st.Phi_z, Z)
    assert _rel(st.group.transpose(Z), full_t) < 1e-14


def test_composite_mass_equals_jacobian_product(case):
    """``M`` from composite inertias equals ``sum w J^T M J`` (1e-12), and is SPD."""
    linkage, data, q, qd, _ = case

    @jax.jit
    def both(q, qd):
        rates = point_rates(data, q, qd)
        M_new, _ = mass_and_force(linkage, data, 0.0, q, qd, rates=rates)
        row = rows_of(data, rates)
        M_J = _mass_from_J(data, rates.J, row)
        if linkage.added_mass is not None:
            idx = np.asarray(data.mass_points)
            Ma = data.point_weight[idx, None, None] * linkage.added_mass[idx]
            J_m = rates.J[row[idx]]
            M_J = M_J + jnp.einsum("pai,pab,pbj->ij", J_m, Ma, J_m)
        return M_new, M_J

    M_new, M_J = both(q, qd)
    assert _rel(M_new, M_J) < 1e-12
    assert float(jnp.max(jnp.abs(M_new - M_new.T))) == 0.0
    assert float(jnp.min(jnp.linalg.eigvalsh(M_new))) > 0.0


def test_forces_and_derivatives_equal_single_group_path(case):
    """``(M, f)`` and, on the free rod and the manual's tree, their forward derivatives
    equal the single-group path's (1e-12 / 1e-10); the accelerations solve the other path's ``M qdd = f`` with a
    normwise backward error below 1e-13 (the solutions themselves differ by up to
    cond(M) x eps: cond(M) is 4e7 on the free rod at these strains)."""
    linkage, data, q, qd, name = case
    old = _without_groups(data)
    assert chain_layout(old).m == chain_layout(data).m

    def terms(d, q, qd):
        return mass_and_force(linkage, d, 0.0, q, qd)

    (M, f), (M_o, f_o) = (jax.jit(terms)(d, q, qd) for d in (data, old))
    assert _rel(M, M_o) < 1e-12 and _rel(f, f_o) < 1e-12
    qdd = spd_solve(M, f)
    r = jnp.max(jnp.abs(M_o @ qdd - f_o))
    scale = jnp.max(jnp.sum(jnp.abs(M_o), 1)) * jnp.max(jnp.abs(qdd))
    assert float(r / (scale + jnp.max(jnp.abs(f_o)))) < 1e-13
    if name not in ("free rod", "manual hybrid"):  # derivatives: a chain and a tree
        return
    dq = jnp.asarray(np.random.default_rng(6).normal(size=q.shape))

    def tangent(d):
        return jax.jit(lambda q, qd: jax.jvp(lambda x: terms(d, x, qd), (q,), (dq,)))(
            q, qd
        )[1]

    for a, b in zip(tangent(data), tangent(old), strict=True):
        assert _rel(a, b) < 1e-10


@pytest.mark.parametrize(
    "idx",
    [
        np.arange(5, 17),  # one run
        np.r_[0, 11:21],  # a joint's column, then a division's (two runs)
        np.r_[0:3, 8:10, 15, 20:24],  # runs of several lengths
        np.arange(0, 24, 2),  # twelve runs of one: the gather
    ],
)
def test_take_by_runs_equals_a_gather(idx):
    """``_take_runs`` (copies of the runs of consecutive indices, a gather past eight
    runs) picks what ``jnp.take`` picks, along either axis: exact."""
    x = jnp.asarray(np.random.default_rng(5).normal(size=(25, 25)))
    for axis in (0, 1):
        np.testing.assert_array_equal(
            _take_runs(x, idx, axis), jnp.take(x, idx, axis=axis)
        )
