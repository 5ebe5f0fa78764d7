"""Equilibrium paths: buckling, post-buckling and snap-through.

References: Euler's buckling loads pi^2 EI / (4 L^2) (clamped-free) and pi^2 EI / L^2
(pinned-pinned); the pinned-pinned elastica's end rotation alpha at
P / P_cr = (2 K(k) / pi)^2, k = sin(alpha / 2) (complete elliptic integral of the
first kind; 1.1517 at 60 degrees in Timoshenko & Gere 1961, table 2-7); the von
Mises truss's closed-form apex force F(y) and its limit load (scenes.von_mises_truss).
"""

import math

import numpy as np
import pytest
from scipy.special import ellipk

import sorojax as sj
from sorojax.scenes import euler_column, pinned_elastica, von_mises_truss


def test_clamped_free_column_buckles_at_euler_load():
    """Straight column: stable below the bifurcation, which is detected at
    P / P_cr = 1 within 1e-4 (measured 1.6e-11 at order 6); switching onto the
    buckled branch, the post-buckling path is stable (supercritical) and rises."""
    path = sj.continuation(euler_column(6), 0.0, 1.5, switch_branch=True)
    assert path.status == "reached p1"
    (bif,) = path.bifurcations
    assert abs(bif.p - 1.0) < 1e-4, bif.p
    assert bif.multiplicity == 1 and bif.n_negative == (0, 1)
    before = path.p < bif.p - 1e-3
    assert before.any() and path.stable[before].all()
    buckled = path.branch == 1
    assert buckled.sum() >= 3 and path.stable[buckled].all()
    assert np.all(np.diff(path.p[buckled]) > 0)
    # the mode is the first buckling mode: the tip rotation is its largest
    assert np.abs(path.q[buckled][-1]).max() > 0.5


@pytest.fixture(scope="module")
def elastica():
    return pinned_elastica(8)


def test_pinned_elastica_post_buckling_path_matches_elliptic_integrals(elastica):
    """Every traced point of the buckled branch (end rotations up to ~80 degrees)
    lies on the exact elastica P / P_cr = (2 K(sin(alpha/2)) / pi)^2 within 1e-4
    relative (measured 1.6e-7 at order 8); the bifurcation is within 1e-3 of
    P_cr; the published 60-degree point (1.1517) is the closed form's."""
    assert (
        abs((2 * ellipk(math.sin(math.radians(30)) ** 2) / math.pi) ** 2 - 1.1517)
        < 5e-5
    )
    path = sj.continuation(elastica, 0.0, 1.3, switch_branch=True)
    assert path.status == "reached p1"
    (bif,) = path.bifurcations
    assert abs(bif.p - 1.0) < 1e-3, bif.p
    buckled = (path.branch == 1) & (np.abs(path.q[:, 0]) > math.radians(2))
    alpha = np.abs(path.q[buckled, 0])
    assert alpha.max() > math.radians(60) and alpha.size >= 8
    exact = (2 * ellipk(np.sin(alpha / 2) ** 2) / math.pi) ** 2
    err = np.abs(path.p[buckled] - exact) / exact
    assert err.max() < 1e-4, err.max()
    assert path.stable[path.branch == 1].all()


def test_pinned_elastica_straight_branch_above_p_cr_is_unstable(elastica):
    """Without switching, the path stays straight: flagged unstable (one negative
    eigenvalue, the first buckling mode) above P_cr, stable below; the same
    compiled corrector serves this second run (same structure)."""
    path = sj.continuation(elastica, 0.0, 1.3)
    assert path.status == "reached p1"
    assert np.abs(path.q[:, 0]).max() < 1e-12  # straight
    above, below = path.p > 1.0 + 1e-3, path.p < 1.0 - 1e-3
    assert above.sum() >= 2 and below.sum() >= 2
    assert not path.stable[above].any() and (path.n_negative[above] == 1).all()
    assert path.stable[below].all()


def test_von_mises_truss_snap_through_folds_at_analytic_limit_load():
    """The symmetric path folds at F = F_max and at -F_max (the closed form's
    limit loads, to 1e-8: the bars are exact), is unstable between the folds and
    ends on the snapped (inverted) branch; there the apex height matches F(y)
    pointwise (1e-8). A plain solve at 1.1 F_max started from the path's last
    point before the fold cannot stay on the near branch (none exists there): it
    either fails (a result code: Newton has no nearby root; which of the two
    happens depends on rounding along the Newton path) or jumps (apex at least
    2 cm below the fold's)."""
    lk, F_max = von_mises_truss()
    path = sj.continuation(lk, 0.0, 1.5)
    assert path.status == "reached p1"
    folds = path.limit_points
    assert len(folds) == 2, [(c.kind, c.p) for c in path.critical]
    assert abs(folds[0].p - 1.0) < 1e-8 and abs(folds[1].p + 1.0) < 1e-8
    i0, i1 = folds[0].index, folds[1].index
    assert path.stable[:i0].all() and path.stable[i1 + 1 :].all()
    assert not path.stable[i0 + 1 : i1].any()
    a = 0.3 * math.cos(math.radians(15.0))
    EA = 1e6 * math.pi * 0.005**2
    y = np.asarray([float(sj.tip_pose(lk, q)[1, 3]) for q in path.q])
    ell = np.hypot(a, y)
    F = -2 * EA * (ell / 0.3 - 1) * y / ell
    assert np.abs(F / F_max - path.p).max() < 1e-8
    assert y[-1] < -0.07  # snapped through
    beyond, _ = von_mises_truss(load_factor=1.1)
    jump = sj.solve_statics(beyond, path.q[i0 - 1], warn_unstable=False, throw=False)
    apex = float(sj.tip_pose(lk, jump.q)[1, 3])
    failed = jump.result != sj.RESULTS.successful
    assert failed or apex < y[i0] - 0.02, f"converged near the fold: apex {apex}"


def test_prepared_continuation_compiles_nothing_along_the_path(jax_events):
    """``sorojax.prepare(sorojax.continuation, ...)`` compiles the corrector of a
    later call beforehand (a structure and settings of its own here: ``max_iter``
    11); the call then compiles no corrector, and its path equals the one traced
    with the corrector compiled at the call (the same program, bit for bit)."""
    from sorojax.statics._continuation import _correct

    lk, _ = von_mises_truss()
    settings = dict(max_iter=11, ds_max=0.3)
    ahead = sj.prepare(sj.continuation, lk, 0.0, 0.5, **settings)
    assert ahead is not None
    ahead.result()
    with jax_events("compile") as compiled:
        path = sj.continuation(lk, 0.0, 0.5, **settings)
    assert not [name for name in compiled if "_correct" in name], compiled
    _correct.prepared.clear()  # compiled at the call now
    _correct.programs.clear()
    again = sj.continuation(lk, 0.0, 0.5, **settings)
    np.testing.assert_array_equal(path.p, again.p)
    np.testing.assert_array_equal(path.q, again.q)
