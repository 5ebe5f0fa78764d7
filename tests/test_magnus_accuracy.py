"""Accuracy of the Magnus steps for high-order strain bases.

References: the exact full circle under an end moment (constant curvature, which
every basis represents); the convergence order of the 6th-order step against a
fine solution of g' = g xi^; autodiff of the same discrete maps (node matrices, body
Jacobians, twist rates, the backward wrench recursion) on a hybrid tree whose
high-order division switches the linkage to 6th-order steps.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

import sorojax as sj
from sorojax.kinematics._step import magnus6, magnus6_apply, magnus6_apply_transpose
from sorojax.lie import hat, inverse_se3, vee
from sorojax.model._precompute import HIGH_ORDER, magnus_order, precompute

ALL_MODES = (1, 1, 1, 1, 1, 1)


def _circle_rod(order):
    E, r, L = 1e7, 0.01, 1.0
    EI = E * math.pi * r**4 / 4
    M = 2.0 * math.pi * EI / L  # curvature M / EI = 2 pi / L: one full turn
    div = sj.Division(L, sj.CircularSection(r), sj.LegendreBasis(ALL_MODES, order))
    rod = sj.SoftLink([div], sj.Material(E, poisson=0.5))
    pw = sj.PointWrench(1, [0.0, 0.0, M, 0.0, 0.0, 0.0], follower=True)
    return sj.Linkage([rod], point_wrenches=[pw]), L


def test_full_circle_at_order_8_with_default_points():
    """All six strains at Legendre order 8 (54 DoF), default n_gauss: tip at the base.

    The exact equilibrium (constant curvature 2 pi / L) lies in the basis and its
    poses are exact at any step order, but J^T W is not: the 4th-order step
    integrates the Jacobian columns of the order-8 modes with an O(h^4 |Phi''''|)
    error that q picked up (3e-6 L). The 6th-order step (chosen for orders >= 4)
    leaves 1.5e-9 L here; tolerance 1e-8 L (the statics' floor it must reach).
    """
    lk, L = _circle_rod(8)
    assert magnus_order(lk) == 6, "order-8 bases must use 6th-order steps"
    sol = sj.solve_statics(lk, warn_unstable=False)  # the full circle is unstable in 3D
    tip = np.asarray(sj.tip_pose(lk, sol.q))[:3, 3]
    err = float(np.linalg.norm(tip)) / L
    assert err < 1e-8, f"full-circle tip off the base by {err:.2e} L (order 8)"


@pytest.mark.parametrize("order, expected", [(3, 4), (HIGH_ORDER, 6)])
def test_step_order_follows_the_basis_order(order, expected):
    """Low orders keep the cheap 4th-order step (exact for them), high ones get 6th."""
    lk, _ = _circle_rod(order)
    got = magnus_order(lk)
    assert got == expected, f"Magnus order {got} for basis order {order}"


def _strain(s):
    """A smooth, non-commuting strain field along the rod (angular first)."""
    return jnp.asarray(
        [
            1.0 + s,
            math.sin(3.0 * s),
            2.0 * s * s,
            1.0 + 0.3 * s,
            0.2 * math.cos(2 * s),
            s**3,
        ]
    )


_NODES6 = np.array([0.5 - math.sqrt(15.0) / 10.0, 0.5, 0.5 + math.sqrt(15.0) / 10.0])


def _end_pose(n):
    """End pose of g' = g xi^ on [0, 1] by n 6th-order steps."""
    h = 1.0 / n
    s = (np.arange(n, dtype=float)[:, None] + _NODES6[None, :]) * h  # node positions
    xi = jnp.stack([jnp.stack([_strain(si) for si in row]) for row in s])
    Omega = np.asarray(magnus6(xi, jnp.full(n, h)))
    g = np.eye(4)
    for O in Omega:
        g = g @ scipy.linalg.expm(np.asarray(hat(jnp.asarray(O))))
    return g


def test_sixth_order_step_converges_at_order_six():
    """log-error vs log-step slope of the 6th-order step is 6 (diffrax-style test).

    Reference: 128 steps (error ~1e-14 there, far below the coarse ones'). The
    slope over 4 -> 8 -> 16 steps measures the local O(h^7) error; 5.5 allows for
    the pre-asymptotic first halving (5.83 measured, then 5.96).
    """
    ref = _end_pose(128)
    ns = (4, 8, 16)
    errs = [float(np.abs(_end_pose(n) - ref).max()) for n in ns]
    slopes = np.diff(np.log(errs)) / np.diff(np.log(1.0 / np.asarray(ns)))
    assert np.all(slopes > 5.5), f"convergence slopes {slopes} (errors {errs})"


def test_step_derivative_and_its_transpose_equal_autodiff():
    """dOmega applied to columns and transposed onto wrenches (cross products only)
    equal forward-mode autodiff of Omega and its transpose (roundoff)."""
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(3), 3)
    xi = jax.random.normal(k1, (2, 3, 6))  # two steps
    h = jnp.array([0.3, 0.7])
    dxi = jax.random.normal(k2, (2, 3, 4, 6))  # four columns
    z = jax.random.normal(k3, (2, 6))

    @jax.jit
    def both(xi, dxi, z):
        J = jax.vmap(jax.jacfwd(magnus6))(xi, h)  # (2, 6, 3, 6)
        return (
            magnus6_apply(xi, h, dxi),
            jnp.einsum("sazb,szkb->ska", J, dxi),
            magnus6_apply_transpose(xi, h, z),
            jnp.einsum("sazb,sa->szb", J, z),
        )

    fwd, fwd_ref, rev, rev_ref = both(xi, dxi, z)
    err = float(jnp.abs(fwd - fwd_ref).max())
    assert err < 1e-13, f"dOmega columns vs jacfwd: max error {err:.2e}"
    err = float(jnp.abs(rev - rev_ref).max())
    assert err < 1e-13, f"dOmega^T z vs jacfwd: max error {err:.2e}"


def _high_order_tree():
    """Hybrid tree (R, U, P joints, two divisions, curved branch) with an order-4
    division, so that every step of the linkage is 6th order (26 DoF)."""
    mat = sj.Material(1e6, rho=1000.0)
    soft = sj.SoftLink(
        [
            sj.Division(
                0.4, sj.CircularSection((0.02, 0.01)), sj.LegendreBasis(ALL_MODES, 0)
            ),
            sj.Division(
                0.3,
                sj.EllipticalSection(0.02, 0.01),
                sj.LegendreBasis((0, 1, 1, 0, 0, 0), 4),
                n_gauss=5,
            ),
        ],
        mat,
        joint=sj.Joint("U"),
        g_i=sj.translation(0.01),
    )
    branch = sj.SoftLink(
        [
            sj.Division(
                0.2,
                sj.RectangularSection(0.02, 0.01),
                sj.MonomialBasis((1, 1, 1, 0, 0, 0), 1),
                xi_ref=lambda X1: jnp.stack([0.0, 0.0, 2.0 * X1, 1.0, 0.0, 0.0]),
                n_gauss=3,
            )
        ],
        mat,
        joint=sj.Joint("P", axis=(0, 1, 0)),
    )
    return sj.Linkage(
        [sj.RigidLink(sj.Joint("R", axis=(0, 0, 1)), 0.3), soft, branch],
        parents=(0, 1, 2),
    )


def test_sixth_order_recursions_are_consistent():
    """6th-order steps: J = autodiff of the poses, eta = J qd, Jdot qd from the
    recursion = forward mode, backward wrench recursion = J^T W.

    Each pair computes the same derivative of the same discrete map in another
    order: roundoff only (1e-10 relative).
    """
    from sorojax.dynamics._wrench_recursion import (
        force_from_wrenches,
        poses_with_records,
    )
    from sorojax.kinematics._recursion import (
        jacobians_dot,
        kinematics_and_rates,
        poses,
    )

    tree = _high_order_tree()
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(0), 3)
    q = 0.5 * jax.random.normal(k1, (tree.n_dof,))
    qd = jax.random.normal(k2, (tree.n_dof,))
    W = jax.random.normal(k3, (tree.layout.n_points, 6))

    @jax.jit  # one compile for all the quantities
    def everything(q, qd, W):
        data = precompute(tree)
        g, J, eta, etadot = kinematics_and_rates(data, q, qd)
        dg = jax.jacfwd(lambda q_: poses(data, q_))(q)  # (n, 4, 4, n_dof)
        J_ad = jax.vmap(
            lambda gp, dgp: jax.vmap(
                lambda d: vee(inverse_se3(gp) @ d), in_axes=2, out_axes=1
            )(dgp)
        )(g, dg)
        rate_ref = jnp.einsum("paj,j->pa", jacobians_dot(data, q, qd), qd)
        _, records = poses_with_records(data, q)
        F = force_from_wrenches(data, records, W)
        return J, J_ad, eta, etadot, rate_ref, F

    order = magnus_order(tree)
    assert order == 6, "the order-4 division must switch the tree to 6th order"
    J, J_ad, eta, etadot, rate_ref, F = everything(q, qd, W)

    def rel(a, b):
        return float(jnp.abs(a - b).max() / jnp.abs(b).max())

    assert rel(J, J_ad) < 1e-10, f"J vs autodiff of FK: {rel(J, J_ad):.1e}"
    assert rel(eta, J @ qd) < 1e-10, f"eta vs J qd: {rel(eta, J @ qd):.1e}"
    err = rel(etadot, rate_ref)
    assert err < 1e-10, f"Jdot qd, recursion vs forward mode: {err:.1e}"
    F_ref = jnp.einsum("pai,pa->i", J, W)
    assert rel(F, F_ref) < 1e-10, f"wrench recursion vs J^T W: {rel(F, F_ref):.1e}"
