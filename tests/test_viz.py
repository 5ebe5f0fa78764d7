"""Tests of the plotting subpackage (Agg backend): geometry of the drawn artists."""

import matplotlib

matplotlib.use("Agg")

import subprocess  # noqa: E402
import sys  # noqa: E402

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import sorojax  # noqa: E402
import sorojax.scenes  # noqa: E402
from sorojax.viz import plot_configuration, plot_reference, plotq, plotq0  # noqa: E402

N_CIRCLE = 12


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def demo():
    """The demo linkage (rigid bar + two-division soft rod) and a bent q."""
    lk = sorojax.scenes.demo_linkage()
    q = np.array([0.4, 2.0, -3.0, 1.0, 2.0, 3.0, 2.0])
    return lk, q


@pytest.fixture(scope="module")
def sections():
    """A soft rod of rectangular, elliptical and tapered circular divisions, then a
    rigid cylinder, and a bent q."""
    bend = sorojax.LegendreBasis((0, 1, 1, 0, 0, 0), 1)
    rod = sorojax.SoftLink(
        [
            sorojax.Division(0.3, sorojax.RectangularSection(0.02, 0.04), bend),
            sorojax.Division(0.3, sorojax.EllipticalSection(0.03, 0.01), bend),
            sorojax.Division(0.4, sorojax.CircularSection((0.02, 0.005)), bend),
        ],
        sorojax.Material(E=1e6, poisson=0.5, rho=1000.0),
    )
    tip = sorojax.RigidLink(
        sorojax.Joint("R", axis=(0.0, 1.0, 0.0)),
        length=0.1,
        section=sorojax.CircularSection(0.015),
        color="tab:green",
    )
    lk = sorojax.Linkage([rod, tip])
    q = np.linspace(-1.5, 2.0, lk.n_dof)
    return lk, q


def _by_gid(ax, prefix):
    arts = list(ax.collections)
    return {a.get_gid(): a for a in arts if (a.get_gid() or "").startswith(prefix)}


def _check_limits_contain(ax, p):
    for lim, x in zip((ax.get_xlim(), ax.get_ylim(), ax.get_zlim()), p, strict=True):
        assert lim[0] <= x <= lim[1]


def _check_equal_aspect(ax):
    ranges = np.array(
        [np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())]
    )
    aspect = np.asarray(ax.get_box_aspect())
    np.testing.assert_allclose(aspect / aspect.max(), ranges / ranges.max(), rtol=1e-9)


def test_import_sorojax_does_not_import_matplotlib():
    code = "import sys, sorojax, sorojax.viz; assert 'matplotlib' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_import_is_lazy_and_every_public_name_resolves():
    """``import sorojax`` imports neither diffrax nor optimistix (names load on
    first use: a statics script, plots and ``sorojax.io`` included, never waits for
    diffrax, ~0.4 s); every name in ``__all__``
    and every submodule then resolves (``kinematics`` is the function, not the
    submodule of that name), and an unknown name raises AttributeError."""
    code = (
        "import sys, sorojax as sj\n"
        "assert not {'diffrax', 'optimistix', 'lineax'} & set(sys.modules)\n"
        "assert callable(sj.kinematics)\n"
        "sj.solve_statics, sj.viz.plot_configuration, sj.io.__name__\n"
        "assert 'diffrax' not in sys.modules\n"
        "assert sj.io.load_trajectory is sj.load_trajectory\n"
        "missing = [n for n in sj.__all__ if getattr(sj, n, None) is None]\n"
        "assert not missing, missing\n"
        "assert sj.integrate.simulate is sj.simulate and 'simulate' in dir(sj)\n"
        "try:\n"
        "    sj.no_such_name\n"
        "except AttributeError as e:\n"
        "    assert 'no_such_name' in str(e)\n"
        "else:\n"
        "    raise SystemExit('no AttributeError')\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_aliases():
    assert plotq is plot_configuration
    assert plotq0 is plot_reference


def test_demo_artists_limits_and_png(demo, tmp_path):
    lk, q = demo
    fig, ax = plotq(lk, jnp.asarray(q), n_circle=N_CIRCLE, show_points=True)
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    # Link 1 rigid: one prism; link 2 soft with two divisions: one tube each.
    bodies = _by_gid(ax, "sorojax-link")
    assert set(bodies) == {
        "sorojax-link1-body",
        "sorojax-link2-division1",
        "sorojax-link2-division2",
    }
    assert "sorojax-points" in _by_gid(ax, "sorojax-points")
    for p in g[:, :3, 3]:
        _check_limits_contain(ax, p)
    _check_equal_aspect(ax)
    assert ax.get_xlabel() == "x [m]" and ax.get_zlabel() == "z [m]"
    # The tube passes through every rod point of each division, in order.
    lay = lk.layout.links[1]
    for k, dl in enumerate(lay.divisions, 1):
        tube = bodies[f"sorojax-link2-division{k}"]
        rod_pts = g[dl.first_point + np.arange(len(dl.X1)), :3, 3]
        assert np.all(np.diff(tube.sorojax_X1) > 0)
        for x, p in zip(dl.X1, rod_pts, strict=True):
            j = int(np.argmin(np.abs(tube.sorojax_X1 - x)))
            np.testing.assert_allclose(tube.sorojax_centres[j], p, atol=1e-12)
    path = tmp_path / "demo.png"
    fig.savefig(path)
    assert path.stat().st_size > 1000


def test_circular_rings_at_radius(demo):
    lk, q = demo
    _, ax = plotq(lk, q, n_circle=N_CIRCLE, n_sub=3)
    bodies = _by_gid(ax, "sorojax-link2")
    for k, div in enumerate(lk.links[1].divisions, 1):
        tube = bodies[f"sorojax-link2-division{k}"]
        rings, centres = tube.sorojax_rings, tube.sorojax_centres
        assert rings.shape == (len(tube.sorojax_X1), N_CIRCLE, 3)
        for ring, c, x in zip(rings, centres, tube.sorojax_X1, strict=True):
            r = float(div.section.radius(x))
            np.testing.assert_allclose(np.linalg.norm(ring - c, axis=1), r, atol=1e-9)
            # The ring lies in a plane through the axis point.
            d = ring - c
            normal = np.cross(d[0], d[N_CIRCLE // 4])
            normal /= np.linalg.norm(normal)
            np.testing.assert_allclose(d @ normal, 0.0, atol=1e-9)
        # The drawn polygons are built from exactly these ring points.
        if hasattr(tube, "_vec"):
            drawn = np.asarray(tube._vec)[:3].T
            ring_pts = rings.reshape(-1, 3)
            dist = np.min(
                np.linalg.norm(drawn[:, None, :] - ring_pts[None, :, :], axis=2), axis=1
            )
            assert dist.max() < 1e-9


def test_ring_normal_is_local_x_at_rod_points(demo):
    lk, q = demo
    _, ax = plotq(lk, q, n_circle=N_CIRCLE, n_sub=1)
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    dl = lk.layout.links[1].divisions[0]
    tube = _by_gid(ax, "sorojax-link2-division1")["sorojax-link2-division1"]
    assert len(tube.sorojax_X1) == len(dl.X1)
    for j in range(len(dl.X1)):
        gj = g[dl.first_point + j]
        d = tube.sorojax_rings[j] - gj[:3, 3]
        np.testing.assert_allclose(d @ gj[:3, 0], 0.0, atol=1e-9)
        # First outline point is along local y at the radius.
        r = float(lk.links[1].divisions[0].section.radius(dl.X1[j]))
        np.testing.assert_allclose(d[0], r * gj[:3, 1], atol=1e-9)


def test_rigid_prism_box(demo):
    lk, q = demo
    _, ax = plotq(lk, q)
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    gc = g[lk.layout.links[0].cm_point]
    body = _by_gid(ax, "sorojax-link1-body")["sorojax-link1-body"]
    rings = body.sorojax_rings
    assert rings.shape == (2, 4, 3)  # a box: two rectangles of four corners
    local = (rings.reshape(-1, 3) - gc[:3, 3]) @ gc[:3, :3]
    np.testing.assert_allclose(np.abs(local), [[0.15, 0.02, 0.02]] * 8, atol=1e-12)
    # The body ends at the joint frame and at the tip.
    joint, tip = g[lk.layout.links[0].joint_point], g[lk.layout.links[0].tip_point]
    np.testing.assert_allclose(body.sorojax_centres[0], joint[:3, 3], atol=1e-12)
    np.testing.assert_allclose(body.sorojax_centres[1], tip[:3, 3], atol=1e-12)


def test_sections_and_taper(sections, tmp_path):
    lk, q = sections
    fig, ax = plotq(lk, q, n_circle=N_CIRCLE, frames=True, color="tab:purple")
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    bodies = _by_gid(ax, "sorojax-link")
    assert set(bodies) == {
        "sorojax-link1-division1",
        "sorojax-link1-division2",
        "sorojax-link1-division3",
        "sorojax-link2-body",
    }
    _check_limits_contain(ax, g[lk.tip_point(2), :3, 3])
    _check_limits_contain(ax, g[lk.tip_point(1), :3, 3])
    _check_equal_aspect(ax)
    rect = bodies["sorojax-link1-division1"]
    ell = bodies["sorojax-link1-division2"]
    cone = bodies["sorojax-link1-division3"]
    cyl = bodies["sorojax-link2-body"]
    assert rect.sorojax_rings.shape[1] == 4
    assert ell.sorojax_rings.shape[1] == N_CIRCLE
    assert cyl.sorojax_rings.shape == (2, N_CIRCLE, 3)
    # Rectangle: corners at half width 0.02 along y and half height 0.01 along z;
    # the corner distance is constant along the rod.
    for ring, c in zip(rect.sorojax_rings, rect.sorojax_centres, strict=True):
        np.testing.assert_allclose(
            np.linalg.norm(ring - c, axis=1), np.hypot(0.02, 0.01), atol=1e-9
        )
        np.testing.assert_allclose(np.linalg.norm(ring[0] - ring[1]), 0.04, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(ring[1] - ring[2]), 0.02, atol=1e-9)
    # Ellipse: semi-axes 0.03 (first point) and 0.01 (quarter turn).
    for ring, c in zip(ell.sorojax_rings, ell.sorojax_centres, strict=True):
        d = np.linalg.norm(ring - c, axis=1)
        np.testing.assert_allclose(d[0], 0.03, atol=1e-9)
        np.testing.assert_allclose(d[N_CIRCLE // 4], 0.01, atol=1e-9)
        np.testing.assert_allclose(d.max(), 0.03, atol=1e-9)
        np.testing.assert_allclose(d.min(), 0.01, atol=1e-9)
    # Taper: radius 0.02 -> 0.005 linearly in X1.
    for ring, c, x in zip(
        cone.sorojax_rings, cone.sorojax_centres, cone.sorojax_X1, strict=True
    ):
        r = 0.02 + (0.005 - 0.02) * x
        np.testing.assert_allclose(np.linalg.norm(ring - c, axis=1), r, atol=1e-9)
    assert cone.sorojax_X1[0] == 0.0 and cone.sorojax_X1[-1] == 1.0
    # Colour override: every body has the same face colour (before shading).
    for b in bodies.values():
        assert b.get_facecolor().shape[0] > 0
    # Frames: one arrow per joint frame and tip, in three colours.
    frames = _by_gid(ax, "sorojax-frames")
    assert set(frames) == {f"sorojax-frames-{a}" for a in "xyz"}
    n_frames = int(np.isin(lk.layout.point_kind, (0, 3)).sum())
    sel = np.flatnonzero(np.isin(lk.layout.point_kind, (0, 3)))
    for a, name in enumerate("xyz"):
        qv = frames[f"sorojax-frames-{name}"]
        assert qv.sorojax_origins.shape == (n_frames, 3)
        np.testing.assert_allclose(qv.sorojax_origins, g[sel, :3, 3], atol=1e-12)
        # Arrows along the local axes, all of the same length.
        v = qv.sorojax_vectors
        lengths = np.linalg.norm(v, axis=1)
        np.testing.assert_allclose(lengths, lengths[0], rtol=1e-9)
        np.testing.assert_allclose(v / lengths[:, None], g[sel, :3, a], atol=1e-9)
    path = tmp_path / "sections.png"
    fig.savefig(path)
    assert path.stat().st_size > 1000


def test_plot_reference(sections):
    lk, _ = sections
    fig, ax = plot_reference(lk, n_circle=N_CIRCLE)
    g0 = np.asarray(sorojax.forward_kinematics(lk, np.zeros(lk.n_dof)))
    assert set(_by_gid(ax, "sorojax-frames")) == {f"sorojax-frames-{a}" for a in "xyz"}
    # Straight rod along x, rigid body beyond it: tip at (1.1, 0, 0).
    np.testing.assert_allclose(g0[lk.tip_point(2), :3, 3], [1.1, 0, 0], atol=1e-12)
    _check_limits_contain(ax, g0[lk.tip_point(2), :3, 3])
    _, ax2 = plotq0(lk, frames=False)
    assert not _by_gid(ax2, "sorojax-frames")


def test_overlay_and_errors(demo):
    lk, q = demo
    fig, ax = plotq0(lk)
    plotq(lk, q, ax=ax)
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    g0 = np.asarray(sorojax.forward_kinematics(lk, np.zeros(lk.n_dof)))
    # Both drawings are inside the limits.
    _check_limits_contain(ax, g[-1, :3, 3])
    _check_limits_contain(ax, g0[-1, :3, 3])
    assert len(_by_gid(ax, "sorojax-link")) == 3  # same gids, two drawings
    assert sum(1 for c in ax.collections if c.get_gid() == "sorojax-link1-body") == 2
    ax2d = fig.add_subplot(2, 2, 4)
    with pytest.raises(ValueError, match="3D"):
        plotq(lk, q, ax=ax2d)
    with pytest.raises(ValueError, match="n_circle"):
        plotq(lk, q, n_circle=2)
    with pytest.raises(ValueError, match="shape"):
        plotq(lk, np.zeros(3))
    with pytest.raises(ValueError, match=r"poses has shape \(3, 4, 4\)"):
        plotq(lk, q, poses=np.zeros((3, 4, 4)))


def test_poses_given_draw_the_same_tubes(demo):
    """``poses=forward_kinematics(lk, q)`` (the demo passes the ones it has) draws
    exactly what computing them inside does (ring centres equal, 0 tolerance)."""
    lk, q = demo
    _, ax1 = plotq(lk, q, n_circle=N_CIRCLE)
    g = np.asarray(sorojax.forward_kinematics(lk, q))
    _, ax2 = plotq(lk, q, n_circle=N_CIRCLE, poses=g)
    b1, b2 = _by_gid(ax1, "sorojax-link2"), _by_gid(ax2, "sorojax-link2")
    assert set(b1) == set(b2) and b1
    for gid in b1:
        np.testing.assert_array_equal(b1[gid].sorojax_centres, b2[gid].sorojax_centres)
    plt.close("all")


def test_rotation_interpolation_helpers():
    from sorojax.viz._plot import _interpolate, _so3_exp, _so3_log

    rng = np.random.default_rng(0)
    for th in (0.0, 1e-10, 0.3, 2.0, np.pi - 1e-8, np.pi):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        R = _so3_exp(th * axis)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(_so3_exp(_so3_log(R)), R, atol=1e-7)

    # Two poses on a circular arc of radius 1 about z (rod along local x): the
    # interpolated orientations turn uniformly and positions stay near the arc.
    def arc(phi):
        g = np.eye(4)
        g[:3, :3] = _so3_exp(np.array([0.0, 0.0, phi]))
        g[:3, 3] = [np.sin(phi), 1.0 - np.cos(phi), 0.0]
        return g

    s = np.array([0.25, 0.5, 0.75])
    gs = _interpolate(arc(0.0), arc(0.4), s)
    for gk, t in zip(gs, s, strict=True):
        np.testing.assert_allclose(gk[:3, :3], arc(0.4 * t)[:3, :3], atol=1e-12)
        radius = np.linalg.norm(gk[:3, 3] - [0, 1, 0])
        np.testing.assert_allclose(radius, 1.0, atol=1e-5)
    # Positions advance monotonically along the arc.
    angles = np.arctan2(gs[:, 0, 3], 1.0 - gs[:, 1, 3])
    assert np.all(np.diff(np.concatenate([[0.0], angles, [0.4]])) > 0)


def test_equilibrium_path_chart_draws_stable_solid_and_unstable_dashed():
    """A path stable, then unstable, then stable (a snap-through's shape): three
    lines, solid / dashed / solid, that pass through every point in order; the
    limit points are marked; a bad coordinate index is refused."""
    from sorojax.statics import CriticalPoint, EquilibriumPath
    from sorojax.viz import plot_equilibrium_path

    n = 9
    p = np.sin(np.linspace(0.0, 2.5 * np.pi, n))
    q = np.stack([np.linspace(1.0, -1.0, n), np.zeros(n)], axis=1)
    stable = np.array([1, 1, 1, 0, 0, 0, 1, 1, 1], bool)
    crit = tuple(
        CriticalPoint("limit", float(p[i]), q[i], np.zeros(0), q[i], i, 1, (0, 1))
        for i in (2, 6)
    )
    path = EquilibriumPath(
        p,
        q,
        np.zeros((n, 0)),
        stable,
        (~stable).astype(int),
        np.ones(n),
        np.zeros(n, int),
        crit,
        "reached p1",
        n,
    )
    ax = plot_equilibrium_path(path, 0)
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() in ("-", "--")]
    assert [ln.get_linestyle() for ln in lines] == ["-", "--", "-"]
    xs = np.concatenate([ln.get_xdata() for ln in lines])
    assert np.allclose(np.unique(xs), np.unique(p))
    assert sum(ln.get_marker() == "^" for ln in ax.get_lines()) == 2
    with pytest.raises(ValueError, match="coordinate"):
        plot_equilibrium_path(path, 5)


def test_section_extents_at_many_points_equal_one_point_at_a_time():
    """The figures take every ring's half-widths in one call of ``extent`` on an
    array of X1 (chunks of 64, the last padded); they must equal the point-by-point
    values to rounding, for every section shape, a taper, a custom profile written
    for arrays and one written for a scalar only (a Python ``if``: evaluated point
    by point instead), and keep the points' order."""
    from sorojax.viz._plot import section_extents

    def step_radius(X1):  # not for arrays: `if` needs a Python bool
        return 0.02 if float(X1) < 0.5 else 0.01

    sections = [
        sorojax.CircularSection((0.02, 0.005)),
        sorojax.RectangularSection(0.02, (0.04, 0.01)),
        sorojax.EllipticalSection(0.03, 0.01),
        sorojax.CircularSection(lambda X1: 0.01 + 0.005 * jnp.sin(3.0 * X1)),
        sorojax.CircularSection(step_radius),
    ]
    X1 = np.concatenate([np.linspace(0.0, 1.0, 70), [0.13, 0.5]])  # 2 chunks of 64
    for section in sections:
        hy, hz = section_extents(section, X1)
        assert hy.shape == hz.shape == X1.shape
        one = np.array([[float(v) for v in section.extent(x)] for x in X1])
        np.testing.assert_allclose(np.stack([hy, hz], -1), one, rtol=1e-14)
