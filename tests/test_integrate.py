"""simulate: result codes, errors, jit/vmap consistency, strain_coordinates.

A 2-DoF rod (bending about y, linear strain) under gravity keeps compiles small; the
physics references (energy, frequencies, pendulums) are in test_dynamics.py.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.scenes import cantilever


@pytest.fixture(scope="module")
def rod():
    """Soft, light rod: 0.3 m, r 5 mm, E 1 MPa, bending about y (order 1), g along -z."""
    return cantilever(
        length=0.3,
        radius=0.005,
        E=1e6,
        modes=(0, 1, 0, 0, 0, 0),
        order=1,
        gravity=(0.0, 0.0, -9.81),
        n_gauss=6,
    )


def test_strain_coordinates_reproduce_a_circle(rod):
    """Uniform curvature k about y is in the basis: tip on the circle of radius 1/k.

    Reference: the tip of a rod of length L bent uniformly by k about y sits at
    (sin(kL)/k, 0, -(1 - cos(kL))/k) (x along the rod, bending about +y turns x to -z).
    Tolerance 1e-12: exact representation, Magnus steps exact for constant strain.
    """
    k, L = 2.0, 0.3
    q = sj.strain_coordinates(rod, [0.0, k, 0.0, 0.0, 0.0, 0.0])
    tip = sj.tip_pose(rod, q)[:3, 3]
    expected = np.array([math.sin(k * L) / k, 0.0, -(1 - math.cos(k * L)) / k])
    np.testing.assert_allclose(tip, expected, rtol=0, atol=1e-12)


def test_strain_coordinates_errors(rod):
    """A link that is not a soft link is refused, naming the link; a strain that is
    not a 6-vector is refused, naming its shape."""
    with pytest.raises(ValueError, match="link = 2"):
        sj.strain_coordinates(rod, jnp.zeros(6), link=2)
    with pytest.raises(ValueError, match=r"strain gives shape \(2,\); expected \(6,\)"):
        sj.strain_coordinates(rod, [0.0, 1.0])


@pytest.fixture(scope="module")
def stretchy():
    """The rod of :func:`rod` with an elongation mode too (bend y + stretch, order 1)."""
    return cantilever(
        length=0.3,
        radius=0.005,
        E=1e6,
        modes=(0, 1, 0, 1, 0, 0),
        order=1,
        gravity=(0.0, 0.0, -9.81),
        n_gauss=6,
    )


def test_strain_coordinates_bend_an_extensible_rod_without_collapsing_it(stretchy):
    """A deviation [0, k, 0, 0, 0, 0] bends the rod and keeps its reference stretch.

    Reference: the tip of the unstretched circle of curvature k (as above), 1e-12;
    the same q from the total strain [0, k, 0, 1, 0, 0] with ``total=True`` (1e-12:
    the same least-squares fit).
    """
    k, L = 2.0, 0.3
    q = sj.strain_coordinates(stretchy, [0.0, k, 0.0, 0.0, 0.0, 0.0])
    tip = sj.tip_pose(stretchy, q)[:3, 3]
    expected = np.array([math.sin(k * L) / k, 0.0, -(1 - math.cos(k * L)) / k])
    np.testing.assert_allclose(tip, expected, rtol=0, atol=1e-12)
    q_total = sj.strain_coordinates(stretchy, [0.0, k, 0.0, 1.0, 0.0, 0.0], total=True)
    np.testing.assert_allclose(q_total, q, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("strain", "total", "gx"),
    [
        ([0.0, 1.0, 0.0, 0.0, 0.0, 0.0], True, "0"),  # a deviation passed as total
        ([0.0, 0.0, 0.0, -1.0, 0.0, 0.0], False, "0"),  # stretch 1 - 1
        ([0.0, 0.0, 0.0, -2.5, 0.0, 0.0], False, "-1.5"),  # inverted
    ],
)
def test_strain_coordinates_refuse_a_collapsed_rod(stretchy, strain, total, gx):
    """A strain whose fitted axial stretch is <= 0 is refused, naming gx and the fix;
    under vmap (traced strain) the same check runs inside the program."""
    with pytest.raises(ValueError, match=rf"axial stretch gx = {gx} .*total=True"):
        sj.strain_coordinates(stretchy, strain, total=total)
    with pytest.raises(eqx.EquinoxRuntimeError, match="axial stretch gx <= 0"):
        jax.vmap(lambda x: sj.strain_coordinates(stretchy, x, total=total))(
            jnp.asarray([strain])
        )


def test_max_steps_gives_result_code_and_clear_error(rod):
    """Too few steps: throw=False returns max_steps_reached; throw=True raises it."""
    traj = sj.simulate(rod, 0.5, solver="tsit5", max_steps=3, throw=False, n_save=3)
    assert traj.result == sj.RESULTS.max_steps_reached
    with pytest.raises(RuntimeError, match="maximum number of steps"):
        sj.simulate(rod, 0.5, solver="tsit5", max_steps=3, n_save=3)


def test_explicit_divergence_is_reported(rod):
    """A constant step far beyond the explicit stability limit is reported, not NaN.

    The stiffest mode of this rod has w_max = 30.5 rad/s (generalised eigenproblem,
    checked here); Tsit5's stability region reaches about h w = 3.5 on the imaginary
    axis, so h = 0.2 s (h w = 6.1) amplifies that mode by roughly (h w)^5 / 5! ~ 70
    per step: 500 steps overflow to non-finite values, and the result code says
    so instead of handing back silent NaNs.
    """
    w = np.sqrt(
        np.linalg.eigvals(
            np.linalg.solve(sj.mass_matrix(rod, jnp.zeros(2)), sj.stiffness_matrix(rod))
        ).real.max()
    )
    assert 0.2 * w > 3.5
    q0 = sj.strain_coordinates(rod, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    traj = sj.simulate(
        rod, 100.0, q0, solver="tsit5", adaptive=False, dt0=0.2, throw=False, n_save=3
    )
    assert traj.result == sj.RESULTS.unstable_step


def test_vmap_over_initial_conditions_equals_loop(rod):
    """vmap of simulate over 4 initial bends equals calling it 4 times (1e-12)."""
    ks = jnp.array([0.5, 1.0, 1.5, 2.0])
    q0s = jax.vmap(
        lambda k: sj.strain_coordinates(rod, jnp.array([0, k, 0, 0, 0, 0.0]))
    )(ks)

    def final(q0):
        return sj.simulate(rod, 0.05, q0, solver="tsit5", throw=False, n_save=2).q[-1]

    batched = jax.vmap(final)(q0s)
    looped = jnp.stack([final(q0) for q0 in q0s])
    np.testing.assert_allclose(batched, looped, rtol=1e-12, atol=1e-12)


def test_bad_arguments(rod):
    """Unknown solver, wrong q0 shape, constant step without dt0, ts outside [t0, t1]."""
    with pytest.raises(ValueError, match="solver"):
        sj.simulate(rod, 0.1, solver="rk4")
    with pytest.raises(ValueError, match="q0"):
        sj.simulate(rod, 0.1, jnp.zeros(5))
    with pytest.raises(ValueError, match="dt0"):
        sj.simulate(rod, 0.1, adaptive=False)
    with pytest.raises(ValueError, match="ts"):
        sj.simulate(rod, 0.1, ts=jnp.array([0.0, 0.2]))
    for gains in ((0.3,), (0.3, 0.0), (0.3, float("nan"))):
        with pytest.raises(ValueError, match="controller_gains"):
            sj.simulate(rod, 0.1, solver="bosh3", controller_gains=gains)


def test_controller_gains_steer_the_explicit_steps_to_the_same_solution(rod):
    """``controller_gains=(0.3, 0.3)`` (PI control) with Bogacki-Shampine from a
    pre-bend at rest over 0.1 s: another step sequence than integral control (the
    gains reach the controller), the same end state to the tolerance's scale (both
    within 1e-5 of each other at rtol 1e-6, atol 1e-9; the coordinates are O(1))."""
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    steps = dict(ts=[0.1], solver="bosh3", rtol=1e-6, atol=1e-9)
    runs = [
        sj.simulate(rod, 0.1, q0, controller_gains=gains, **steps)
        for gains in (None, (0.3, 0.3))
    ]
    assert all(tr.result == sj.RESULTS.successful for tr in runs)
    assert int(runs[0].num_steps) != int(runs[1].num_steps)
    np.testing.assert_allclose(runs[1].q[-1], runs[0].q[-1], atol=1e-5)


@pytest.mark.slow  # three programs with Newton root finders (~16 s); sorojax's own
# constant-step solvers' orders are checked by tests/test_fixed_step.py
def test_constant_step_implicit_solvers_converge_at_their_order(rod):
    """Constant steps with implicit solvers (root-finder tolerances from rtol/atol).

    Reference: Dopri8 at rtol 1e-12 over 0.05 s from a pre-bend at rest. Implicit
    Euler is first order: halving h halves the error. Measured ratios 1.68, 1.85,
    1.92 for h = 2e-3 / 1e-3 / 5e-4 / 2.5e-4 (|lambda_max| h from 0.06 down to
    0.007 on this 2-DoF rod), so h = 5e-4 and 2.5e-4 must give 2 within 10 %
    (an order-2 or order-0/1.5 method fails that). Kvaerno3 (3rd order) at
    h = 5e-4 must be at least 100x closer than implicit Euler.
    """
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    t1 = 0.05
    ref = sj.simulate(rod, t1, q0, ts=[t1], solver="dopri8", rtol=1e-12, atol=1e-14)

    def err(solver, h):
        tr = sj.simulate(
            rod,
            t1,
            q0,
            ts=[t1],
            solver=solver,
            adaptive=False,
            dt0=h,
            rtol=1e-10,
            atol=1e-12,
        )
        assert tr.result == sj.RESULTS.successful
        return float(jnp.abs(tr.q[-1] - ref.q[-1]).max())

    e2, e1 = err("implicit_euler", 5e-4), err("implicit_euler", 2.5e-4)
    assert abs(e2 / e1 / 2.0 - 1.0) < 0.1, f"implicit Euler error ratio {e2 / e1:.3f}"
    e_kv3 = err("kvaerno3", 5e-4)
    assert e_kv3 < 1e-2 * e1, f"Kvaerno3 {e_kv3:.2e} vs implicit Euler {e1:.2e}"


def test_bosh3_by_name_converges_at_third_order(rod):
    """``solver="bosh3"`` is Bogacki-Shampine's third-order method.

    Constant steps h, h/2, h/4 (h = 1e-3 s, |lambda_max| h <= 0.03 on this 2-DoF
    rod) from a pre-bend at rest over 0.05 s: the differences of successive
    solutions shrink by 2^3 = 8 (measured 8.8); within 20 % (Heun's second-order
    method gives 4.0, Tsit5 48). One program serves the three step sizes.
    """
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    t1 = 0.05

    def end(h):
        tr = sj.simulate(rod, t1, q0, ts=[t1], solver="bosh3", adaptive=False, dt0=h)
        assert tr.result == sj.RESULTS.successful
        return tr.q[-1]

    q1, q2, q3 = end(1e-3), end(5e-4), end(2.5e-4)
    ratio = float(jnp.abs(q1 - q2).max() / jnp.abs(q2 - q3).max())
    assert abs(ratio / 8.0 - 1.0) < 0.2, f"Bosh3 difference ratio {ratio:.2f}"


def test_compiled_simulate_has_no_host_callback(rod):
    """The compiled program holds no host callback, so the persistent cache keeps it.

    JAX refuses to write programs with host callbacks to its persistent compilation
    cache; diffrax's own save-time checks are one (``equinox.error_if``), which
    sorojax replaces by host-side checks. Saved times outside [t0, t1] under an outer
    jit (no host check possible) give non-finite states and a failure code.
    """
    q0 = sj.strain_coordinates(rod, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])

    def run(ts):
        return sj.simulate(rod, 0.1, q0, ts=ts, solver="tsit5", throw=False)

    jaxpr = str(jax.make_jaxpr(lambda ts: run(ts).q)(jnp.array([0.0, 0.05, 0.1])))
    assert "callback" not in jaxpr
    bad = jax.jit(run)(jnp.array([0.0, 0.05, 0.2]))
    assert bad.result != sj.RESULTS.successful
    good = jax.jit(run)(jnp.array([0.0, 0.05, 0.1]))
    assert good.result == sj.RESULTS.successful
    assert np.isfinite(np.asarray(good.q)).all()


def test_trajectory_energies_and_tips_match_pointwise_queries(rod):
    """``Trajectory.energies`` / ``tip_positions`` (one batched program each) equal
    the single-state queries at every save time: kinetic + gravitational + elastic
    = total_energy to 1e-12 relative, tips = tip_pose to 1e-14 m."""
    q0 = sj.strain_coordinates(rod, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    traj = sj.simulate(rod, 0.05, q0, n_save=4, solver="tsit5")
    E = np.asarray(traj.energies(rod))
    tips = np.asarray(traj.tip_positions(rod))
    assert E.shape == (4, 4) and tips.shape == (4, 3)
    for k in range(4):
        q, qd = traj.q[k], traj.qd[k]
        parts = [
            sj.kinetic_energy(rod, q, qd),
            sj.gravitational_energy(rod, q),
            sj.elastic_energy(rod, q),
            sj.total_energy(rod, q, qd),
        ]
        np.testing.assert_allclose(E[k], np.asarray(parts), rtol=1e-12, atol=1e-15)
        tip = np.asarray(sj.tip_pose(rod, q))[:3, 3]
        np.testing.assert_allclose(tips[k], tip, rtol=0, atol=1e-14)
    np.testing.assert_allclose(E[:, :3].sum(axis=1), E[:, 3], rtol=1e-13)


def test_backsolve_adjoint_with_the_rosenbrock_solver_is_refused(rod):
    """The Rosenbrock-W solver cannot integrate ``BacksolveAdjoint``'s backward
    pytree state: a ValueError names the adjoint and the fix, before any compile
    of the integration."""
    import diffrax

    with pytest.raises(ValueError, match="BacksolveAdjoint\\(solver=diffrax.Tsit5"):
        sj.simulate(rod, 0.05, solver="ros34pw2", adjoint=diffrax.BacksolveAdjoint())


@pytest.mark.slow  # two gradient programs: ~30 s of compiles on 2 cores
def test_backsolve_adjoint_matches_the_exact_gradient(rod):
    """``diffrax.BacksolveAdjoint`` works through ``simulate`` (its vector field
    closes over no array) and its gradient converges to the exact one.

    d(tip x after 0.05 s)/d(initial curvature) of the 2-DoF rod, Tsit5 forward and
    backward at rtol = atol = 1e-10: the continuous adjoint's gradient differs from
    the exact gradient of the computed trajectory (default adjoint) by the backward
    solve's error (2e-13 relative measured); tolerance 1e-7.
    """
    import diffrax

    q0 = sj.strain_coordinates(rod, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    tol = dict(rtol=1e-10, atol=1e-10)

    def tip_x(s, adjoint):
        traj = sj.simulate(
            rod, 0.05, s * q0, n_save=2, solver="tsit5", adjoint=adjoint, **tol
        )
        return sj.tip_pose(rod, traj.q[-1])[0, 3]

    backsolve = diffrax.BacksolveAdjoint(
        solver=diffrax.Tsit5(), stepsize_controller=diffrax.PIDController(**tol)
    )
    exact = jax.jit(jax.grad(lambda s: tip_x(s, None)))(1.0)
    continuous = jax.jit(jax.grad(lambda s: tip_x(s, backsolve)))(1.0)
    assert abs(float(exact)) > 1e-3  # the tip moves with the curvature
    np.testing.assert_allclose(float(continuous), float(exact), rtol=1e-7)
