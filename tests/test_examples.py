"""The scripts in examples/ run, write their figures and compute the right physics.

Each example's ``main(argv)`` is run in this process (the test configuration's
persistent compile cache then serves it) with a small problem and a temporary output
folder; the returned values are checked against references.
"""

import importlib.util
import pathlib

import equinox as eqx
import jax
import matplotlib
import numpy as np
import pytest
from references import elastica_cantilever_tip_load

import sorojax as sj

matplotlib.use("Agg")

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_hybrid_statics_gradient_matches_central_differences(tmp_path):
    """examples/hybrid_statics.py: equilibrium and d(tip y)/d(joint stiffness).

    Reference: central differences of the tip height with a 1e-4 relative step in the
    joint stiffness, same compiled solve (the step changes no structure). Newton at
    rtol 1e-10 leaves ~1e-10 / 1e-4 = 1e-6 relative noise in the difference and the
    truncation is ~(1e-4)^2: tolerance 1e-5 relative.
    """
    ex = _load("hybrid_statics")
    sol, (dk, _) = ex.main(["--out", str(tmp_path)])
    assert sol.result == sj.RESULTS.successful
    assert (tmp_path / "hybrid_statics.png").stat().st_size > 10_000
    linkage = ex.demo_linkage()
    k0 = float(linkage.links[0].joint.stiffness.squeeze())

    def tip_y(k):
        lk = eqx.tree_at(lambda l: l.links[0].joint.stiffness, linkage, np.array([[k]]))
        return float(sj.tip_pose(lk, sj.solve_statics(lk).q)[1, 3])

    h = 1e-4 * k0
    fd = (tip_y(k0 + h) - tip_y(k0 - h)) / (2 * h)
    err = abs(float(dk.squeeze()) - fd) / abs(fd)
    assert err < 1e-5, f"d(tip y)/dk = {float(dk.squeeze()):.8e} vs central {fd:.8e}"


def test_free_fall_dynamics_dissipates_and_keeps_outputs(tmp_path):
    """examples/free_fall_dynamics.py over 0.5 s: the damped rod never gains energy.

    Reference: dE/dt = -qd^T D qd <= 0; between save times E may rise by at most 1e-7
    of |E(0)| (integration error at the default tolerances: ROS34PW2, rtol 1e-3; each
    step dissipates, measured: E falls at every save). A second run
    must refuse to overwrite the PNG without --overwrite.
    """
    ex = _load("free_fall_dynamics")
    traj = ex.main(["--t1", "0.5", "--out", str(tmp_path)])
    assert traj.result == sj.RESULTS.successful
    rod = ex.free_fall_rod(order=3, eta=1e4)
    E = np.asarray(jax.vmap(lambda q, qd: sj.total_energy(rod, q, qd))(traj.q, traj.qd))
    assert np.diff(E).max() < 1e-7 * abs(E[0]), "energy rose between save times"
    assert E[-1] < E[0], "the damped rod must lose energy"
    png = tmp_path / "free_fall_dynamics.png"
    size = png.stat().st_size
    assert size > 10_000
    with pytest.raises(SystemExit, match="overwrite"):
        ex.main(["--t1", "0.5", "--out", str(tmp_path)])
    assert png.stat().st_size == size


def test_cantilever_sweep_matches_elliptic_integrals(tmp_path):
    """examples/cantilever_sweep.py with 4 loads (P L^2/EI = 0.5 .. 10) under vmap.

    Reference: Bisshopp-Drucker elliptic-integral tip position (tests/references.py).
    Tolerance 1e-4 relative on both tip coordinates (the statics' accuracy bar;
    order 6 with the default Gauss points gives ~3e-6). The gradient d(tip y)/dP must be positive and
    fall as the rod stiffens geometrically, and at the smallest load match
    the linear value L^3/(3 E I) within 10 % (at alpha = 0.5 the large-deflection
    response is measured 8 % softer than linear).
    """
    ex = _load("cantilever_sweep")
    alpha, xy, dy = ex.main(["--n", "4", "--out", str(tmp_path)])
    for a, (x, y) in zip(alpha, xy, strict=True):
        ref = elastica_cantilever_tip_load(a)
        err = abs(y - ref[1]) / ref[1]
        assert err < 1e-4, f"alpha {a}: tip y {y:.6f} vs elliptic {ref[1]:.6f}"
        err = abs(x - ref[0]) / ref[0]
        assert err < 1e-4, f"alpha {a}: tip x {x:.6f} vs elliptic {ref[0]:.6f}"
    assert np.all(dy > 0) and np.all(np.diff(dy) < 0), f"d(tip y)/dP = {dy}"
    linear = ex.L**3 / (3 * ex.EI)
    assert abs(dy[0] / linear - 1) < 0.1, f"dy/dP {dy[0]:.4f} vs linear {linear:.4f}"
    assert (tmp_path / "cantilever_sweep.png").stat().st_size > 10_000


def test_l_beam_matches_linear_frame_theory_and_symmetry(tmp_path):
    """examples/l_beam.py at order 1: closure, clamp reaction and the linear limit.

    References: (1) at 1e-4 of the load the corner deflection equals the linear
    Euler-Bernoulli frame solution (two frame elements, exact for a corner load): the
    bending moment is linear and the twist constant along each arm, so order 1
    represents them exactly; the geometric nonlinearity there is ~(w/L)^2 ~ 1e-10 and
    Newton stops at ~1e-10: tolerance 1e-6 relative. (2) The L is symmetric about the
    vertical plane through the corner at 45 degrees, so each clamp carries half the
    load: the far clamp's vertical force (the multiplier of the z position row, in a
    frame turned about z) is P / 2 within 1e-8 relative. (3) The fixed closure holds
    to 1e-10 m / rad (Newton tolerance).
    """
    ex = _load("l_beam")
    results, ratio = ex.main(["--orders", "1", "--out", str(tmp_path)])
    assert abs(ratio - 1) < 1e-6, f"small-load deflection / linear = {ratio:.10f}"
    sol = results[1]["sol"]
    assert sol.result == sj.RESULTS.successful
    assert float(sol.constraint_error) < 1e-10, f"closure {sol.constraint_error}"
    assert int(sol.constraint_rank) == 6
    fz = float(sol.lam[5])
    assert abs(fz / 1000.0 - 1) < 1e-8, f"far clamp force z {fz} N, expected 1000"
    # Large deflection: geometric stiffening (the inextensible arms pull), so the
    # response is below the linear one, by a few per cent at w/L ~ 0.14.
    w_lin = abs(ex.linear_corner_response(2000.0)[0])
    dmax = results[1]["max_deflection"]
    assert 0.9 * w_lin < dmax < w_lin, f"max deflection {dmax} vs linear {w_lin}"
    assert (tmp_path / "l_beam.png").stat().st_size > 10_000


@pytest.mark.slow
def test_l_beam_deflection_converges_with_order(tmp_path):
    """examples/l_beam.py at orders 1-3 (2 kN, w/L ~ 0.14): the maximum deflection.

    Reference: Cauchy convergence. Order 1 is already within 1e-3 of order 3 (the
    curvature is nearly linear); the change from order 2 to 3 must be smaller than
    from 1 to 2 and below 1e-5 relative (measured: 13.896, 13.9037, 13.9038 cm).
    """
    ex = _load("l_beam")
    results, _ = ex.main(["--orders", "1", "2", "3", "--out", str(tmp_path)])
    d = [results[k]["max_deflection"] for k in (1, 2, 3)]
    assert abs(d[0] / d[2] - 1) < 1e-3, f"max deflections {d}"
    assert abs(d[2] - d[1]) < abs(d[1] - d[0]), f"max deflections {d}"
    assert abs(d[2] / d[1] - 1) < 1e-5, f"max deflections {d}"


@pytest.mark.slow  # ~40 s; external cables: tests/test_actuation.py (default run)
def test_gripper_finger_curls_monotonically_and_balances(tmp_path):
    """examples/gripper_finger.py over 5 tensions 0..8 N.

    References: (1) the curl increases strictly with the tension. (2) Equilibrium by
    virtual work, independent of the solver's autodiff: K q = F(q) - T dl/dq with
    dl/dq by central differences of the tendon length (step 1e-6: truncation ~1e-12,
    rounding ~1e-10 relative to T dl/dq ~ 0.06 N m); tolerance 1e-6 of |K q|.
    """
    ex = _load("gripper_finger")
    tensions, qs, curls = ex.main(["--n", "5", "--out", str(tmp_path)])
    assert np.all(np.diff(curls) > 0), f"curl [deg] {np.degrees(curls)}"
    assert np.degrees(curls[-1]) > 90, "8 N should curl the finger past 90 deg"
    finger = ex.gripper_finger()
    K = np.asarray(sj.stiffness_matrix(finger))
    for T, q in zip(tensions, qs, strict=True):
        h = 1e-6
        dl = np.array(
            [
                (
                    float(sj.cable_lengths(finger, q + h * e)[0])
                    - float(sj.cable_lengths(finger, q - h * e)[0])
                )
                / (2 * h)
                for e in np.eye(len(q))
            ]
        )
        F = np.asarray(sj.generalized_external_force(finger, q))
        r = K @ q - F + T * dl
        scale = np.abs(K @ q).max()
        assert np.abs(r).max() < 1e-6 * scale, f"T = {T}: residual {r}"
    # The drawn tendon (sorojax.viz.cable_polylines) is the modelled one: for a chain
    # of anchors its polyline length is the cable length (to rounding).
    from sorojax.viz import cable_polylines

    ((name, pts),) = cable_polylines(finger, qs[-1])
    drawn = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    length = float(sj.cable_lengths(finger, qs[-1])[0])
    assert name == "tendon" and abs(drawn - length) < 1e-12, f"{drawn} vs {length}"
    assert (tmp_path / "gripper_finger.png").stat().st_size > 10_000


@pytest.mark.slow
def test_manual_hybrid_statics_and_dynamics(tmp_path):
    """examples/manual_hybrid.py: closed-loop statics (-pi/4, 50 N) and 0.2 s of motion.

    References: (1) the fixed loop closes to 1e-10 with full rank 6. (2) Moment
    balance about the revolute axis: the cable and the loop are internal to the
    links beyond the joint, so the solved torque equals dV_g/dtheta (central
    differences of the gravitational energy, step 1e-5: error ~1e-10) minus the
    moment (p x f)_z of the 5 N follower force about the z axis through the
    origin; tolerance 1e-7 N m. (3) In dynamics the revolute follows pi t / 2
    exactly and the Baumgarte-stabilised loop stays closed within 1e-6.
    """
    ex = _load("manual_hybrid")
    sol, traj = ex.main(["--t1", "0.2", "--out", str(tmp_path)])
    lk = ex.manual_hybrid()
    assert sol.result == sj.RESULTS.successful
    assert float(sol.constraint_error) < 1e-10
    assert int(sol.constraint_rank) == 6
    q = np.asarray(sol.q)
    assert abs(q[0] - ex.ANGLE) < 1e-12
    h = 1e-5
    e0 = np.eye(len(q))[0]
    dV = (
        float(sj.gravitational_energy(lk, q + h * e0))
        - float(sj.gravitational_energy(lk, q - h * e0))
    ) / (2 * h)
    pw = lk.point_wrenches[0]
    g = np.asarray(sj.forward_kinematics(lk, q))[lk.point_index(pw)]
    f = g[:3, :3] @ np.asarray(pw.wrench)[3:]
    expected = dV - np.cross(g[:3, 3], f)[2]
    torque = float(sol.efforts[0])
    assert abs(torque - expected) < 1e-7, f"torque {torque} vs balance {expected}"
    assert traj.result == sj.RESULTS.successful
    t = np.asarray(traj.t)
    assert np.allclose(np.asarray(traj.q)[:, 0], np.pi * t / 2, atol=1e-10)
    err = np.asarray(jax.vmap(lambda qq: sj.closure_errors(lk, qq))(traj.q))
    assert np.abs(err).max() < 1e-6, f"closure error {np.abs(err).max()}"
    assert (tmp_path / "manual_hybrid.png").stat().st_size > 10_000


def test_snap_through_finds_folds_bifurcation_and_the_sweep_jump(tmp_path):
    """examples/snap_through.py at its defaults (16 sweep loads, elastica order 8).

    References: (1) the truss folds at F / F_max = +1 and -1, the closed form's limit
    loads, at apex heights +-y* (scenes.von_mises_truss: the bars are exact linear
    springs, so only the secant location limits it; 1e-6 is slack, measured 1e-14).
    (2) The plain warm-started sweep follows the stable branch up to the fold (apex
    above y*, flagged stable) and past it has no nearby equilibrium: every point
    beyond F_max lies at least 2 cm below the fold's apex, and the example's point
    that it lands on *unstable* equilibria, flagged (measured: 1.1-1.5 F_max, the
    apex past the far pin), holds. (3) The elastica bifurcates at P_cr within 1e-3
    and its buckled branch lies on the elliptic-integral curve within 1e-4 relative
    (measured 1.5e-5 at order 8, as in tests/test_continuation.py). A second run
    must refuse to overwrite the PNG without --overwrite.
    """
    ex = _load("snap_through")
    res = ex.main(["--out", str(tmp_path)])
    p_fold, m_fold = res["folds"]
    assert abs(p_fold - 1) < 1e-6 and abs(m_fold + 1) < 1e-6, res["folds"]
    y_star = res["fold_apex_height_analytic"]
    y0, y1 = res["fold_apex_heights"]
    assert abs(y0 - y_star) < 1e-6 and abs(y1 + y_star) < 1e-6, (y0, y1, y_star)
    loads, y = res["sweep_loads"], res["sweep_apex_heights"]
    conv, stable = res["sweep_converged"], res["sweep_stable"]
    below, beyond = loads < 1 - 1e-9, loads > 1 + 1e-9
    assert conv[below].all() and stable[below].all(), "sweep below the fold"
    assert np.all(y[below] > y_star), f"apex below the fold {y[below]}"
    assert np.all(y[beyond] < y_star - 0.02), f"apex beyond the fold {y[beyond]}"
    assert (conv & ~stable)[beyond].any(), "the sweep's unstable landing is flagged"
    assert abs(res["bifurcation"] - 1) < 1e-3, res["bifurcation"]
    err = res["elastica_max_relative_error"]
    assert err < 1e-4, f"elastica P/P_cr vs elliptic integrals: {err:.2e}"
    png = tmp_path / "snap_through.png"
    size = png.stat().st_size
    assert size > 10_000
    with pytest.raises(SystemExit, match="overwrite"):
        ex.main(["--out", str(tmp_path)])
    assert png.stat().st_size == size
