"""Size classes: models of other orders and modes share compiled programs.

References: Legendre and monomial families are nested (the first o + 1 polynomials of
order P are those of order o), so a model padded to a class, with its padding
columns zero, has the same strains, equilibria and motions as the unpadded model on
the same points and Magnus steps (round-off); the padding is decoupled and stays
exactly zero; the class's structure does not depend on the model's own orders or
modes, so one compiled program serves them all (counted at the compile call).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax._mechanisms import cable_manipulator
from sorojax.scenes import cantilever, free_fall_q0, free_fall_rod

CLASS = 3  # below the 6th-order Magnus threshold (order 4), like orders 1-3
POINTS = 10  # the class's default points: max(8, 2 * 3 + 4)
GRAVITY = (0.0, 0.0, -9.81)
WRENCH = [0.0, 0.0, 0.0, 0.0, 0.2, 0.05]  # tip force along y and z [N]


def _rod(order, modes=(1, 1, 1, 0, 0, 0), n_gauss=None):
    return cantilever(
        length=0.5,
        radius=0.01,
        E=1e6,
        modes=modes,
        order=order,
        gravity=GRAVITY,
        tip_wrench=WRENCH,
        n_gauss=n_gauss,
    )


def _padding(padded, q):
    q = np.asarray(q)
    return np.delete(q, sj.active_coordinates(padded), axis=-1)


def _solve_padded(models, pad, compiles, what):
    """``[(padded, q)]``: each model padded by ``pad`` and solved; asserts that no
    solve after the first compiled and that every padding coordinate is 0."""
    out, n_after_first = [], None
    for lk in models:
        padded = pad(lk)
        sol = sj.solve_statics(padded)
        assert sol.result == sj.RESULTS.successful
        if n_after_first is None:
            n_after_first = len(compiles)
        assert np.all(_padding(padded, sol.q) == 0.0)
        out.append((padded, np.asarray(sol.q)))
    assert len(compiles) == n_after_first, f"another {what} compiled again"
    return out


def test_statics_of_every_order_in_a_class_is_the_models_and_compiles_once(compiles):
    """Orders 1, 2, 3 (torsion and both bendings) padded to class 3: one statics
    program for the three (no compile after the first padded solve); the padded
    orders 1 and 2 are the unpadded models on the class's 10 points to 1e-12 (same
    arithmetic up to zero columns), its padding exactly 0. The padded models come
    from models with their default points (8, 8, 10): the class fixes them. Being
    one structure, they stack into one pytree: a vmapped solve gives the same
    equilibria (1e-12)."""
    padded = _solve_padded(
        [_rod(order) for order in (1, 2, 3)],
        lambda lk: sj.size_class(lk, CLASS),
        compiles,
        "order",
    )
    for pad, _ in padded:
        assert pad.n_dof == 3 * (CLASS + 1)
        assert pad.links[0].divisions[0].n_gauss == POINTS
    # one class, one pytree structure: the models stack, and one vmapped solve
    # gives every order's equilibrium (a convergence study in one program)
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *(pad for pad, _ in padded))
    qs = jax.vmap(lambda lk: sj.solve_statics(lk, throw=False).q)(stacked)
    for (_, q_pad), q_batch in zip(padded, np.asarray(qs), strict=True):
        np.testing.assert_allclose(q_batch, q_pad, rtol=0.0, atol=1e-12)
    # orders below the class against their unpadded models (order 3 fills it)
    for order, (_, q_pad) in zip((1, 2), padded[:2], strict=True):
        ref_model = _rod(order, n_gauss=POINTS)
        ref = np.asarray(sj.solve_statics(ref_model).q)
        idx = sj.active_coordinates(sj.size_class(ref_model, CLASS))
        assert np.abs(q_pad[idx] - ref).max() <= 1e-12 * np.abs(ref).max()
        assert np.abs(ref).max() > 0.1  # a large deflection, not a trivial one


def test_a_modes_class_shares_one_program_across_modes(compiles):
    """With the class's modes given (all six), a bending-only model of order 2 and a
    model of every mode at order 1 share one program; each equals its unpadded model
    on the same points (1e-12), its padding exactly 0."""
    cases = [(2, (0, 1, 1, 0, 0, 0)), (1, (1, 1, 1, 1, 1, 1))]
    padded = _solve_padded(
        [_rod(order, modes) for order, modes in cases],
        lambda lk: sj.size_class(lk, 2, modes=(1,) * 6),
        compiles,
        "set of modes",
    )
    assert all(pad.n_dof == 6 * 3 for pad, _ in padded)
    for (order, modes), (pad, q) in zip(cases, padded, strict=True):
        ref = np.asarray(sj.solve_statics(_rod(order, modes, n_gauss=8)).q)
        err = np.abs(q[sj.active_coordinates(pad)] - ref).max()
        assert err <= 1e-12 * np.abs(ref).max()


def test_dynamics_of_a_padded_model_is_the_models_motion(compiles):
    """0.3 s of the damped free-fall rod at orders 1 and 2 padded to class 3: one
    integration program for both; the initial shape fitted on the padded model
    (strain_coordinates) and every saved state equal the unpadded model's on the
    same points to 1e-10 (the error norm counts only the model's own states, so the
    adaptive steps are the same: equal step counts), the padding exactly 0."""
    runs, n_after_first = [], None
    for order in (1, 2):
        pad = sj.size_class(free_fall_rod(order, eta=1e4), CLASS)
        tr = sj.simulate(pad, 0.3, free_fall_q0(pad), solver="tsit5", n_save=7)
        assert tr.result == sj.RESULTS.successful
        if n_after_first is None:
            n_after_first = len(compiles)
        assert np.all(_padding(pad, tr.q) == 0.0)
        assert np.all(_padding(pad, tr.qd) == 0.0)
        runs.append((pad, tr))
    assert len(compiles) == n_after_first, "a padded order compiled again"
    for order, (pad, tr) in zip((1, 2), runs, strict=True):
        lk = free_fall_rod(order, eta=1e4, n_gauss=POINTS)
        ref = sj.simulate(lk, 0.3, free_fall_q0(lk), solver="tsit5", n_save=7)
        idx = sj.active_coordinates(pad)
        scale = np.abs(np.asarray(ref.q)).max()
        err = np.abs(np.asarray(tr.q)[:, idx] - np.asarray(ref.q)).max()
        assert err <= 1e-10 * scale
        assert int(tr.num_steps) == int(ref.num_steps)
        assert scale > 0.1


def test_a_divisions_class_shares_one_program_across_division_counts(compiles):
    """One and two divisions padded to three (empty divisions of length 0 at the
    tip, every coefficient off): one statics program for both; equilibria and tip
    poses equal the unpadded models' (1e-12), padding exactly 0; 0.05 s of
    constant-step Rosenbrock dynamics of the one-division rod with two empty
    divisions equal too (1e-12: the same equations; with
    adaptive steps, round-off of the longer sums moves the steps, so trajectories
    agree to the tolerance only)."""
    models = [
        cantilever(0.5, 0.01, 1e6, (1, 1, 1, 0, 0, 0), 2, n, 1000.0, GRAVITY, WRENCH)
        for n in (1, 2)
    ]
    padded = _solve_padded(
        models, lambda lk: sj.size_class(lk, 2, divisions=3), compiles, "division count"
    )
    for pad, _ in padded:
        assert len(pad.links[0].divisions) == 3 and pad.n_dof == 27
    steps = dict(solver="ros34pw2", adaptive=False, dt0=1e-3, n_save=5)
    for lk, (pad, q) in zip(models, padded, strict=True):
        ref = np.asarray(sj.solve_statics(lk).q)
        idx = sj.active_coordinates(pad)
        assert np.abs(q[idx] - ref).max() <= 1e-12 * np.abs(ref).max()
        np.testing.assert_allclose(
            sj.tip_pose(pad, q), sj.tip_pose(lk, ref), rtol=0.0, atol=1e-12
        )
    # dynamics of the one-division rod with two empty divisions (the padded
    # program is shared; each unpadded reference would be a compile of its own)
    (lk, (pad, _)) = models[0], padded[0]
    idx = sj.active_coordinates(pad)
    tr, tr_ref = sj.simulate(pad, 0.05, **steps), sj.simulate(lk, 0.05, **steps)
    scale = np.abs(np.asarray(tr_ref.q)).max()
    err = np.abs(np.asarray(tr.q)[:, idx] - np.asarray(tr_ref.q)).max()
    assert err <= 1e-12 * scale and scale > 0.1


def test_empty_divisions_carry_no_cable_load():
    """The four-cable arm (cables spanning every division, oblique paths) padded
    from 2 to 3 divisions and from order 1 to 2: the empty division adds no cable
    length, force or weight, so the equilibrium's tip pose under tensions equals
    the unpadded arm's on the same points (1e-12)."""
    arm = cable_manipulator(order=1, n_gauss=8)
    tensions = jnp.array([2.0, 0.5, 1.0, 0.0])
    ref = sj.solve_statics(arm, u=tensions)
    pad = sj.size_class(arm, 2, n_gauss=8, divisions=3)
    sol = sj.solve_statics(pad, u=tensions)
    assert np.all(_padding(pad, sol.q) == 0.0)
    g, g_ref = sj.tip_pose(pad, sol.q), sj.tip_pose(arm, ref.q)
    np.testing.assert_allclose(g, g_ref, rtol=0.0, atol=1e-12)
    assert np.abs(np.asarray(g_ref)[:2, 3]).max() > 0.01  # the cables bend it


def test_padded_mass_and_stiffness():
    """The padded model's M and K restricted to its own coordinates are the unpadded
    model's (1e-12); the padding is decoupled (zero off-diagonal blocks) with the
    mean diagonal of the others, so M stays symmetric positive definite."""
    lk = free_fall_rod(1, n_gauss=POINTS)
    pad = sj.size_class(lk, CLASS)
    q = free_fall_q0(pad)
    idx = sj.active_coordinates(pad)
    rest = np.setdiff1d(np.arange(pad.n_dof), idx)
    for fn, args, ref_args in (
        (sj.mass_matrix, (pad, q), (lk, free_fall_q0(lk))),
        (sj.stiffness_matrix, (pad,), (lk,)),
    ):
        A, A_ref = np.asarray(fn(*args)), np.asarray(fn(*ref_args))
        assert np.abs(A[np.ix_(idx, idx)] - A_ref).max() <= 1e-12 * np.abs(A_ref).max()
        assert np.all(A[np.ix_(idx, rest)] == 0.0)
        np.testing.assert_allclose(
            np.diag(A)[rest], np.mean(np.diag(A_ref)), rtol=1e-12
        )
    assert np.linalg.eigvalsh(np.asarray(sj.mass_matrix(pad, q))).min() > 0.0


def test_active_coordinates_and_bad_classes():
    """An unpadded linkage's coordinates are all its own; orders above the class, a
    mode outside the class's modes, a custom basis and a bad order are refused with
    the division, the value and the fix named."""
    lk = _rod(2)
    np.testing.assert_array_equal(sj.active_coordinates(lk), np.arange(lk.n_dof))
    with pytest.raises(
        ValueError, match="torsion at order 2 > the class order 1: give order >= 2"
    ):
        sj.size_class(lk, 1)
    with pytest.raises(ValueError, match="mode torsion on.*give modes with torsion"):
        sj.size_class(lk, 3, modes=(0, 1, 1, 0, 0, 0))
    with pytest.raises(ValueError, match="order = -1"):
        sj.size_class(lk, -1)
    two = cantilever(order=1, n_divisions=2)
    with pytest.raises(ValueError, match="link 1 has 2 divisions > divisions = 1"):
        sj.size_class(two, 1, divisions=1)
    custom = sj.Linkage(
        sj.SoftLink(
            [sj.Division(0.5, basis=sj.CustomBasis(lambda x: jnp.eye(6)[:, :1], 1))],
            sj.Material(E=1e6),
        )
    )
    with pytest.raises(ValueError, match="link 1 division 1 has a CustomBasis"):
        sj.size_class(custom, 3)
