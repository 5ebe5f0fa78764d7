"""Model adequacy (issue 16): re-ordered models, discretisation error, model choice.

References: Legendre bases are nested (a strain field of one order is reproduced
exactly at a higher order); an over-resolved model (order 14, 70 points) stands in
for the exact solution of a planar cantilever under a tip force; the pure end moment
gives constant curvature, exact at order 0.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.scenes import cantilever
from sorojax.statics._adequacy import (
    _tip_poses,
    pose_distance,
    reference_length,
    transfer_coordinates,
)

MODES = (0, 0, 1, 1, 1, 0)  # planar (x-y): bending about z, elongation, shear y
WRENCH = [0.0, 0.0, 0.0, 0.0, 0.3, 0.0]  # 0.3 N along y at the tip


def _rod(order, n_gauss=None):
    return cantilever(
        length=1.0,
        radius=0.01,
        E=1e7,
        modes=MODES,
        order=order,
        n_gauss=n_gauss,
        tip_wrench=WRENCH,
    )


@pytest.fixture(scope="module")
def reference():
    lk = _rod(14, 70)
    sol = sj.solve_statics(lk)
    return lk, np.asarray(_tip_poses(lk, sol.q[None]))[0]


def _true_error(lk, q, reference):
    g = np.asarray(_tip_poses(lk, jnp.asarray(q)[None]))[0]
    return float(pose_distance(g, reference[1], 1.0).max())


def test_with_orders_and_transfer_keep_the_strain_field():
    """Raising orders (same points) reproduces the same strain at every point and the
    same tip pose (1e-14: Legendre bases are nested), and transferring back recovers
    q exactly; switching modes off removes their coordinates; bad keys and orders
    get clear errors."""
    lk = _rod(4)  # orders >= 4 on both sides: the same (6th-order) Magnus step
    q = jnp.asarray(np.random.default_rng(0).normal(size=lk.n_dof) * 0.1)
    n_gauss = lk.links[0].divisions[0].n_gauss
    hi = sj.with_orders(lk, {(1, 0): (-1, -1, 6, 5, 4, -1)}, n_gauss)
    assert hi.n_dof == 7 + 6 + 5
    q_hi = transfer_coordinates(lk, q, hi)
    s_lo = np.asarray(sj.screw_strains(lk, q))
    s_hi = np.asarray(sj.screw_strains(hi, jnp.asarray(q_hi)))
    assert np.abs(s_lo - s_hi).max() < 1e-14
    g_lo, g_hi = sj.tip_pose(lk, q), sj.tip_pose(hi, jnp.asarray(q_hi))
    assert float(jnp.abs(g_lo - g_hi).max()) < 1e-14
    assert np.array_equal(transfer_coordinates(hi, q_hi, lk), np.asarray(q))
    planar = sj.with_orders(lk, {(1, 0): (-1, -1, 5, -1, -1, -1)})
    assert planar.n_dof == 6
    with pytest.raises(ValueError, match="orders key"):
        sj.with_orders(lk, {(2, 0): (0,) * 6})
    with pytest.raises(ValueError, match="six orders"):
        sj.with_orders(lk, {(1, 0): (0, 0, 1)})


def test_end_moment_half_circle_estimate_tracks_the_true_error():
    """Constant curvature pi / L (exact tip (0, 2 L / pi, 0)) at order 4: the only
    error is the one the kinematics' integration puts into the higher coefficients;
    the estimate is within 10x of the true tip error (or both below 1e-9)."""
    lk = cantilever(
        length=1.0,
        radius=0.01,
        E=1e7,
        modes=(0, 1, 1, 0, 0, 0),
        order=4,
        tip_wrench=[0.0, 0.0, 1e7 * np.pi * 0.01**4 / 4 * np.pi, 0.0, 0.0, 0.0],
    )
    sol = sj.solve_statics(lk, load_steps=4)
    tip = np.asarray(sj.tip_pose(lk, sol.q))
    true = max(np.linalg.norm(tip[:3, 3] - [0.0, 2.0 / np.pi, 0.0]), 0.0)
    est = sj.discretization_error(lk, sol.q).error
    assert (true < 1e-9 and est < 1e-9) or 0.1 * true < est < 10 * true, (true, est)


@pytest.mark.parametrize("order", [2, 4])
def test_discretization_error_is_within_10x_of_the_true_error(reference, order):
    """Coefficient-decay extrapolation plus the points' term: within a factor 10 of
    the error against the over-resolved model (measured 0.97x and 0.42x at orders 2, 4)."""
    lk = _rod(order)
    sol = sj.solve_statics(lk)
    true = _true_error(lk, sol.q, reference)
    est = sj.discretization_error(lk, sol.q).error
    assert 0.1 * true < est < 10 * true, (order, true, est)


def test_choose_model_meets_the_tolerance_with_few_coordinates(reference):
    """tol 1e-5 L: the chosen model's error against the over-resolved model is below
    tol, its estimate within 10x of that error, it has fewer coordinates than the
    uniform order-3 model of the same modes (12 DoF, whose error 8.4e-6 L also meets
    it: measured 9 DoF, error 2.9e-6), in two solves (reference + verification)."""
    ch = sj.choose_model(_rod(3), tol=1e-5, modes=MODES, reference_order=10)
    true = _true_error(ch.linkage, ch.q, reference)
    assert ch.error_estimate <= 1e-5 and true <= 1e-5, (ch.error_estimate, true)
    assert 0.1 * true < ch.error_estimate < 10 * true, (true, ch.error_estimate)
    assert ch.n_dof < 12, ch.orders
    assert ch.num_solves == 2
    uniform = _rod(3)
    assert _true_error(uniform, sj.solve_statics(uniform).q, reference) <= 1e-5


@pytest.mark.slow
def test_choose_model_dynamics_meets_the_tolerance_over_the_window():
    """SoRoSim's damped free-fall rod over 0.2 s, tol 1e-2 L: the chosen model's tip
    poses stay within tol of the reference simulation's at every save (verified by
    the function's own simulation, re-checked here from its trajectories), with
    fewer coordinates than the reference (~1-2 min: dynamics compiles)."""
    from sorojax.scenes import free_fall_q0, free_fall_rod

    rod = free_fall_rod(order=3, eta=1e4)
    ch = sj.choose_model_dynamics(rod, 0.2, free_fall_q0(rod), tol=1e-2, n_save=6)
    assert ch.error_estimate <= 1e-2
    g_c = np.asarray(_tip_poses(ch.linkage, jnp.asarray(ch.q)))
    g_r = np.asarray(_tip_poses(ch.reference, jnp.asarray(ch.q_reference)))
    assert pose_distance(g_c, g_r, reference_length(rod)).max() <= 1e-2
    assert ch.n_dof < ch.reference.n_dof
