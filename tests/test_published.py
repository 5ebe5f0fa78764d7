"""Published and closed-form references: follower-loaded cantilever, Bathe-Bolourchi
45-degree bend, SoRoSim's L-beam, and the section mechanics behind them.

- Follower load (Argyris & Symeonidis 1981 type): tip rotation of a clamped rod under
  a tip force that stays normal to the tip, against the closed form
  ``sqrt(2 alpha) = int_0^theta_L dpsi / sqrt(sin psi)``, ``alpha = P L^2 / EI``.
- Bathe & Bolourchi 1979 (also Simo & Vu-Quoc 1986): 45-degree bend, tip force 600
  out of its plane; tip displacement about (-23.5, -13.4, 53.4).
- Mathew et al. 2023 (SoRoSim, IEEE RAM, test 2): the L-beam under gravity,
  12.98 cm (GVS) / 13.27 cm (ANSYS); see ``examples/l_beam_sorosim.py``.
- Torsion constants (Saint-Venant series, Timoshenko & Goodier's / Roark's table,
  finite-difference Prandtl stress functions), Cowper's shear coefficients, and
  ``sorosim_mechanics`` against SoRoSim's section model assembled by hand.

Converged, high-order results live in the examples; the models here are small and
share their compiled solves (module-scope fixtures, array-valued parameters).
"""

import importlib.util
import math
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
import scipy.optimize
import scipy.sparse
import scipy.sparse.linalg

import sorojax as sj

# ----------------------------------------------------------------- follower load


def follower_tip_rotation(alpha: float) -> float:
    """Closed-form tip rotation of a cantilever under a normal follower tip force.

    With psi = theta_L - theta(s), moment balance of the part beyond s gives
    EI psi'' = P cos psi, psi(L) = psi'(L) = 0, whose first integral
    psi'^2 = 2 P / EI sin psi yields sqrt(2 alpha) = int_0^theta_L dpsi / sqrt(sin
    psi). The 1 / sqrt singularity at psi = 0 is removed by psi = u^2
    (integrand 2 u / sqrt(sin u^2) -> 2); the root is bracketed in (0, 3] rad
    (alpha up to 10; the law holds to theta_L = pi).
    """

    def integral(theta):
        def f(u):
            return 2.0 if u == 0.0 else 2 * u / math.sqrt(math.sin(u * u))

        return scipy.integrate.quad(f, 0.0, math.sqrt(theta), epsabs=1e-13)[0]

    return scipy.optimize.brentq(
        lambda t: integral(t) - math.sqrt(2 * alpha), 1e-12, 3.0, xtol=1e-15
    )


def follower_cantilever(P):
    """Unit rod (L = 1, EI = 1), all six modes, stiff in extension and shear.

    EA = 1e8 and G A_y = G A_z = 5e7 (in EI / L^2; G = E / 2): the axial and shear
    strains (~ P / (G A) < 2e-7) change the tip rotation by ~1e-8. Bending about z
    of order 6, the other modes of order 2 (22 DoF).
    """
    stiff = 1e8
    section = sj.SectionProperties(
        A=stiff, Iy=1.0, Iz=1.0, J=1.0, shear_area_y=stiff, shear_area_z=stiff
    )
    basis = sj.LegendreBasis((1, 1, 1, 1, 1, 1), (2, 2, 6, 2, 2, 2))
    rod = sj.SoftLink(sj.Division(1.0, section, basis), sj.Material(E=1.0, poisson=0.0))
    wrench = jnp.stack([0.0, 0.0, 0.0, 0.0, jnp.asarray(P, float), 0.0])
    return sj.Linkage(rod, point_wrenches=[sj.PointWrench(1, wrench, follower=True)])


def test_follower_closed_form_matches_its_ode_and_small_load_limit():
    """The quadrature reference agrees with EI psi'' = P cos psi integrated from the tip.

    Both conditions sit at the tip (psi = psi' = 0), so integrating backwards to
    the clamp is an initial-value problem with psi(0) = theta_L: an independent
    route (tolerance 1e-8, the ODE solver's). Small loads: theta_L -> alpha / 2, the
    linear cantilever's P L^2 / (2 EI) (relative correction O(alpha^2)).
    """
    for alpha in (1.0, 3.0, 6.0):

        def rhs(s, y, alpha=alpha):
            return [y[1], alpha * math.cos(y[0])]

        ivp = scipy.integrate.solve_ivp(
            rhs, (1.0, 0.0), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12
        )
        theta_ivp = ivp.y[0, -1]
        theta = follower_tip_rotation(alpha)
        assert abs(theta - theta_ivp) < 1e-8 * theta, (
            f"alpha {alpha}: quadrature {theta:.12f} vs ODE {theta_ivp:.12f}"
        )
    small = 1e-4
    assert follower_tip_rotation(small) == pytest.approx(small / 2, rel=1e-6)


@pytest.mark.parametrize("alpha", [1.0, 3.0, 6.0])
def test_follower_load_tip_rotation_matches_closed_form(alpha):
    """Tip rotation under a follower force normal to the tip, alpha = P L^2 / EI.

    Reference: the closed form (0.49588, 1.39866, 2.36555 rad at alpha 1, 3, 6).
    Tolerance 1e-4 relative; order 6 in bending is converged to ~1e-8 (order 4:
    2e-5 at alpha 6), extension and shear change it by < 1e-7.
    """
    linkage = follower_cantilever(alpha)  # one compile for the three loads
    sol = sj.solve_statics(linkage)
    R = np.asarray(sj.tip_pose(linkage, sol.q))[:3, :3]
    theta = math.atan2(R[1, 0], R[0, 0])
    ref = follower_tip_rotation(alpha)
    assert abs(theta / ref - 1) < 1e-4, f"tip rotation {theta:.8f} vs {ref:.8f} rad"
    assert abs(R[2, 0]) < 1e-12, "the rod left its plane (out-of-plane tip tangent)"


# ------------------------------------------------------------- Bathe-Bolourchi bend

BEND_R = 100.0
BEND_PUBLISHED = np.array([-23.5, -13.4, 53.4])  # Bathe & Bolourchi 1979
J_POLAR, J_SAINT_VENANT = 1 / 6, 0.140577  # unit square: 2 I; Saint-Venant


def bathe_bolourchi(J):
    """45-degree arc of radius 100 in the x-y plane (tangent to x at the clamp,
    bending towards +y), unit square, E = 1e7, poisson 0 (G = E / 2), Cowper's
    k = 5/6, dead tip force 600 along +z; angular strains of order 4, linear order
    3 (27 DoF). ``J`` is an array leaf: both torsion constants share one compile.
    """
    section = sj.SectionProperties(
        A=1.0, Iy=1 / 12, Iz=1 / 12, J=J, shear_area_y=5 / 6, shear_area_z=5 / 6
    )
    basis = sj.LegendreBasis((1, 1, 1, 1, 1, 1), (4, 4, 4, 3, 3, 3))
    division = sj.Division(
        BEND_R * math.pi / 4, section, basis, xi_ref=(0, 0, 1 / BEND_R, 1, 0, 0)
    )
    rod = sj.SoftLink(division, sj.Material(E=1e7, poisson=0.0, rho=1.0))
    force = sj.PointWrench(1, [0.0, 0.0, 0.0, 0.0, 0.0, 600.0])
    return sj.Linkage(rod, point_wrenches=[force])


@pytest.fixture(scope="module")
def bend_tips():
    """Tip displacement of the bend for J = 1/6 and J = 0.1406."""
    out = {}
    for J in (J_POLAR, J_SAINT_VENANT):
        linkage = bathe_bolourchi(J)
        q = sj.solve_statics(linkage).q
        tip = np.asarray(sj.tip_pose(linkage, q))[:3, 3]
        out[J] = tip - np.asarray(sj.tip_pose(linkage, np.zeros(linkage.n_dof)))[:3, 3]
    return out


def test_bathe_bolourchi_bend_reference_tip():
    """The reference arc's tip: R (sin 45, 1 - cos 45, 0) = (70.711, 29.289, 0)."""
    linkage = bathe_bolourchi(J_POLAR)
    tip0 = np.asarray(sj.tip_pose(linkage, np.zeros(linkage.n_dof)))[:3, 3]
    s = math.sqrt(0.5)
    expected = [BEND_R * s, BEND_R * (1 - s), 0.0]
    np.testing.assert_allclose(tip0, expected, atol=1e-9, err_msg="reference tip")


def test_bathe_bolourchi_tip_displacement_within_half_percent(bend_tips):
    """Tip displacement with J = 1/6 within 0.5 % of the published (-23.5, -13.4, 53.4).

    Measured as |u - u_pub| / |u_pub| (0.38 %; 0.28 % from Simo & Vu-Quoc's
    (47.23, 15.79, 53.37) tip). Published results of this case scatter by ~0.5 %
    with the element and the torsion constant; order 4 is converged to 2e-5.
    """
    u = bend_tips[J_POLAR]
    err = np.linalg.norm(u - BEND_PUBLISHED) / np.linalg.norm(BEND_PUBLISHED)
    assert err < 5e-3, f"tip displacement {u} vs published {BEND_PUBLISHED}: {err:.2%}"


def test_bathe_bolourchi_saint_venant_torsion_is_softer(bend_tips):
    """The Saint-Venant J (0.1406 < 1/6) lets the tip move further out of the plane.

    Lower torsional stiffness: the out-of-plane displacement grows (53.61 vs
    53.48) and the tip stays within 1 % of the published one (0.84 %: the
    published runs' scatter with J); the z-component within 0.5 %.
    """
    u_p, u_sv = bend_tips[J_POLAR], bend_tips[J_SAINT_VENANT]
    assert u_sv[2] > u_p[2], f"u_z: J=0.1406 {u_sv[2]:.4f} <= J=1/6 {u_p[2]:.4f}"
    err = np.linalg.norm(u_sv - BEND_PUBLISHED) / np.linalg.norm(BEND_PUBLISHED)
    assert err < 1e-2, f"J = 0.1406: tip {u_sv} is {err:.2%} from the published"
    assert abs(u_sv[2] / BEND_PUBLISHED[2] - 1) < 5e-3, f"u_z = {u_sv[2]:.4f}"


# ----------------------------------------------------------------- SoRoSim L-beam

# The scene and its linear reference live in the example (loaded, not copied).
_SPEC = importlib.util.spec_from_file_location(
    "l_beam_sorosim",
    pathlib.Path(__file__).parent.parent / "examples" / "l_beam_sorosim.py",
)
L_BEAM = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(L_BEAM)
L_G = L_BEAM.GRAVITY


def _max_deflection(gravity) -> float:
    """Max deflection [m] of the 30-DoF L under SoRoSim's section model."""
    linkage = L_BEAM.l_beam(gravity=gravity)  # horizontal L, sorosim_mechanics
    return L_BEAM.max_deflection(linkage, sj.solve_statics(linkage).q)


@pytest.fixture(scope="module")
def l_beam_deflections():
    """Max deflection [m]: out-of-plane gravity (full and 1e-4), in-plane gravity."""
    return {
        "full": _max_deflection((0.0, 0.0, -L_G)),
        "small": _max_deflection((0.0, 0.0, -1e-4 * L_G)) / 1e-4,
        "vertical": _max_deflection((0.0, -L_G, 0.0)),
    }


def test_l_beam_small_load_limit_is_exact_linear_solution(l_beam_deflections):
    """At 1e-4 of gravity the deflection per unit load is linear Timoshenko theory's.

    SoRoSim's section (GJ = G (Iy + Iz), k = 1); the 30-DoF basis holds the exact
    linear solution (quadratic moments, constant torques, linear shear forces), so
    only the O(load) nonlinearity remains (~1e-9). Tolerance 1e-7.
    """
    ref = L_BEAM.linear_corner_deflection("sorosim")
    got = l_beam_deflections["small"]
    assert abs(got / ref - 1) < 1e-7, f"linear limit {got:.9f} vs exact {ref:.9f} m"


def test_l_beam_against_published_deflection(l_beam_deflections):
    """SoRoSim's L-beam, SoRoSim's model at its 30 DoF vs the published 12.98 cm (GVS).

    Documented difference: sorojax gives 12.074 cm, 7.0 % below 12.98 cm (and 9.0 %
    below ANSYS's 13.27 cm). The model is right for the stated setup (the linear
    limit is exact, above; an independent discrete-rod solve reproduces the
    Kirchhoff variant, examples/l_beam_sorosim.py), so the gap is in the published
    setup, which the paper does not state in full. The band (-7.5 %, -6.5 %) pins
    the difference so that any change of sorojax's answer shows here.
    """
    d = l_beam_deflections["full"]
    rel = d / 0.1298 - 1
    assert -0.075 < rel < -0.065, f"max deflection {100 * d:.4f} cm: {rel:+.2%}"
    # The clamped ends stiffen the response (membrane tension): below linear.
    assert d < l_beam_deflections["small"], "large-load deflection above linear"


def test_l_beam_plane_decision(l_beam_deflections):
    """Only the horizontal L (gravity out of its plane) deflects ~13 cm.

    The vertical L (gravity in its plane) carries the corner by the vertical arm's
    axial stiffness: 0.58 cm, twenty times less than published.
    """
    assert l_beam_deflections["vertical"] < 0.01, "vertical L deflects > 1 cm"
    assert l_beam_deflections["full"] > 0.1, "horizontal L deflects < 10 cm"


# --------------------------------------------------------------- torsion constants


def _prandtl_rectangle(a, b, n):
    """Saint-Venant J of an a x b rectangle by finite differences (b / n spacing).

    Prandtl: lap(phi) = -2 inside, phi = 0 on the boundary, J = 2 int phi; the
    5-point Laplacian and the trapezoid rule (second order).
    """
    h = b / n
    m = round(a / h)

    def d2(k):
        main, off = -2 * np.ones(k - 1), np.ones(k - 2)
        return scipy.sparse.diags([off, main, off], [-1, 0, 1]) / h**2

    A = scipy.sparse.kronsum(d2(n), d2(m)).tocsc()
    phi = scipy.sparse.linalg.spsolve(A, -2 * np.ones(A.shape[0]))
    return 2 * h * h * phi.sum()


def _prandtl_ellipse(a, b, n):
    """Saint-Venant J of an ellipse (semi-axes a along y, b along z), by finite
    differences with Shortley-Weller stencils at the curved boundary (b / n
    spacing), J = 2 int phi by the trapezoid rule along rows then across them.
    """
    h = b / n
    ys = np.arange(-math.floor(a / h), math.floor(a / h) + 1) * h
    zs = np.arange(-n, n + 1) * h
    Y, Z = np.meshgrid(ys, zs, indexing="ij")
    inside = (Y / a) ** 2 + (Z / b) ** 2 < 1 - 1e-12
    idx = -np.ones(Y.shape, int)
    idx[inside] = np.arange(inside.sum())
    rows, cols, vals = [], [], []
    for i, j in zip(*np.nonzero(inside), strict=True):
        k, y, z = idx[i, j], Y[i, j], Z[i, j]
        diag = 0.0
        half_y = a * math.sqrt(max(0.0, 1 - (z / b) ** 2))
        half_z = b * math.sqrt(max(0.0, 1 - (y / a) ** 2))
        for c, half, lo, hi in (
            (y, half_y, (i - 1, j), (i + 1, j)),
            (z, half_z, (i, j - 1), (i, j + 1)),
        ):
            hm, hp = min(h, c + half), min(h, half - c)  # to a node or the boundary
            cm, cp = 2 / (hm * (hm + hp)), 2 / (hp * (hm + hp))
            diag -= cm + cp
            for dist, coef, nb in ((hm, cm, lo), (hp, cp, hi)):
                if dist == h and idx[nb] >= 0:  # a node, not the boundary (phi = 0)
                    rows.append(k)
                    cols.append(idx[nb])
                    vals.append(coef)
        rows.append(k)
        cols.append(k)
        vals.append(diag)
    n_in = int(inside.sum())
    A = scipy.sparse.csr_matrix((vals, (rows, cols)), shape=(n_in, n_in))
    phi = np.zeros(Y.shape)
    phi[inside] = scipy.sparse.linalg.spsolve(A, -2 * np.ones(n_in))
    row_integrals = []
    for j, z in enumerate(zs):
        half = a * math.sqrt(max(0.0, 1 - (z / b) ** 2))
        m = inside[:, j]
        yy = np.concatenate([[-half], ys[m], [half]])
        row_integrals.append(np.trapezoid(np.concatenate([[0], phi[m, j], [0]]), yy))
    return 2 * np.trapezoid(row_integrals, zs)


def test_square_torsion_constant():
    """Square: J = 0.14058 a^4 (series), 0.1406 a^4 in the tables; J < polar a^4/6.

    Also against the finite-difference Prandtl solution, Richardson-extrapolated
    from 16 and 32 cells (error ~3e-5): tolerance 1e-4.
    """
    a = 0.03
    J = float(sj.RectangularSection(a, a).torsion_constant(0.5))
    assert J / a**4 == pytest.approx(0.1406, abs=5e-5)
    fd = (4 * _prandtl_rectangle(1.0, 1.0, 32) - _prandtl_rectangle(1.0, 1.0, 16)) / 3
    assert J / a**4 == pytest.approx(fd, rel=1e-4), f"series {J / a**4} vs FD {fd}"
    polar = float(sj.RectangularSection(a, a, torsion="polar").torsion_constant(0.5))
    assert polar == pytest.approx(a**4 / 6, rel=1e-14)


@pytest.mark.parametrize(
    "ratio, beta",
    [(1.0, 0.141), (1.5, 0.196), (2.0, 0.229), (2.5, 0.249), (3.0, 0.263),
     (4.0, 0.281), (5.0, 0.291), (10.0, 0.312), (1e4, 1 / 3)],
)  # fmt: skip
def test_rectangle_torsion_constant_matches_table(ratio, beta):
    """J = beta a b^3 (a the long side) vs the table (Timoshenko & Goodier, Theory of
    Elasticity, section 109; Roark's Formulas for Stress and Strain, table 10.1).

    The table gives three decimals: tolerance 5.5e-4 on beta (the series itself is
    accurate to 1e-10). The limit of a thin strip is 1/3. Both orientations agree.
    """
    b = 0.01
    a = ratio * b
    J1 = float(sj.RectangularSection(a, b).torsion_constant(0.0))
    J2 = float(sj.RectangularSection(b, a).torsion_constant(1.0))
    assert J1 == pytest.approx(J2, rel=1e-14), "J depends on the orientation"
    assert abs(J1 / (a * b**3) - beta) < 5.5e-4, f"beta {J1 / (a * b**3):.5f}"


def test_rectangle_torsion_constant_matches_finite_differences():
    """a / b = 2 and 3: series vs Prandtl finite differences (Richardson, 16/32 cells:
    error ~1e-5): tolerance 1e-4."""
    for ratio in (2.0, 3.0):
        fd = (
            4 * _prandtl_rectangle(ratio, 1, 32) - _prandtl_rectangle(ratio, 1, 16)
        ) / 3
        J = float(sj.rectangle_torsion_constant(ratio, 1.0))
        assert J == pytest.approx(fd, rel=1e-4), f"a/b {ratio}: {J} vs FD {fd}"


def test_rectangle_torsion_constant_host_equals_traced():
    """Concrete sides take a NumPy path, traced ones the jax.numpy path: the same
    series, so equal to rounding (1e-14), arrays of sides included."""
    h, w = np.array([0.02, 0.05, 0.01]), np.array([0.01, 0.05, 0.03])
    host = np.asarray(sj.rectangle_torsion_constant(h, w))
    traced = np.asarray(jax.jit(jax.vmap(sj.rectangle_torsion_constant))(h, w))
    assert host.shape == (3,)
    np.testing.assert_allclose(host, traced, rtol=1e-14)


def test_ellipse_torsion_constant():
    """Ellipse J = pi a^3 b^3 / (a^2 + b^2) against three independent values.

    - a Prandtl finite-difference solve (a / b = 1.5, 40 cells across b; second
      order, measured error 1e-4 at this grid): tolerance 3e-4;
    - the circle limit a = b = r: the polar moment pi r^4 / 2 (to rounding);
    - the thin limit b << a: thin-strip theory J = (1/3) int t(y)^3 dy with
      t = 2 b sqrt(1 - y^2 / a^2), i.e. pi a b^3 (relative error (b / a)^2 = 1e-4
      at a / b = 100): tolerance 2e-4.
    """
    a, b = 0.015, 0.01
    J = float(sj.EllipticalSection(a, b).torsion_constant(0.5))
    assert J == pytest.approx(math.pi * a**3 * b**3 / (a**2 + b**2), rel=1e-14)
    fd = _prandtl_ellipse(1.5, 1.0, 40) * b**4
    assert J == pytest.approx(fd, rel=3e-4), f"closed form {J} vs FD {fd}"
    r = 0.02
    Jc = float(sj.EllipticalSection(r, r).torsion_constant(0.5))
    assert Jc == pytest.approx(math.pi * r**4 / 2, rel=1e-14)
    assert float(sj.CircularSection(r).torsion_constant(0.5)) == pytest.approx(Jc)
    a, b = 1.0, 0.01
    strip = scipy.integrate.quad(
        lambda y: (2 * b * math.sqrt(1 - y * y / a**2)) ** 3 / 3, -a, a
    )[0]
    Jt = float(sj.EllipticalSection(a, b).torsion_constant(0.5))
    assert Jt == pytest.approx(strip, rel=2e-4), f"thin ellipse {Jt} vs strip {strip}"


# ---------------------------------------------------------- Cowper's coefficients


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
def test_cowper_shear_coefficients(nu):
    """Cowper 1966 (J. Appl. Mech. 33, 335): circle 6 (1 + nu) / (7 + 6 nu),
    rectangle 10 (1 + nu) / (12 + 11 nu) (0.886 and 0.850 at nu = 0.3, his table;
    5/6 for a rectangle at nu = 0); an ellipse with equal semi-axes is a circle.
    Exact formulas: tolerance 1e-14.
    """
    circle = 6 * (1 + nu) / (7 + 6 * nu)
    rect = 10 * (1 + nu) / (12 + 11 * nu)
    for section, k in (
        (sj.CircularSection(0.01), circle),
        (sj.RectangularSection(0.02, 0.01), rect),
        (sj.EllipticalSection(0.01, 0.01), circle),
    ):
        ky, kz = (float(x) for x in section.shear_coefficients(0.5, nu))
        assert ky == pytest.approx(k, rel=1e-14), f"{type(section).__name__}: {ky}"
        assert kz == pytest.approx(k, rel=1e-14), f"{type(section).__name__}: {kz}"
    if nu == 0.3:
        assert round(circle, 3) == 0.886 and round(rect, 3) == 0.850
    if nu == 0.0:
        assert rect == pytest.approx(5 / 6, rel=1e-15)


def test_cowper_ellipse_coefficients_reach_the_right_stiffness_rows():
    """Ellipse a != b: G k_y A and G k_z A land on the shear-y and shear-z rows of K.

    Order-0 basis, one division of length L: K = L diag(GJ/L^2, EIy/L^2, EIz/L^2,
    EA, G k_y A, G k_z A) with k_y from m = a / b (semi-axis along y over the other)
    and k_z from m = b / a (Cowper's ellipse formula). Tolerance 1e-12.
    """
    a, b, L, E, nu = 0.02, 0.01, 0.5, 1e6, 0.4
    section = sj.EllipticalSection(a, b)
    basis = sj.LegendreBasis((1, 1, 1, 1, 1, 1), 0)
    rod = sj.SoftLink(sj.Division(L, section, basis), sj.Material(E=E, poisson=nu))
    K = np.asarray(sj.stiffness_matrix(sj.Linkage(rod)))
    G, A = E / (2 * (1 + nu)), math.pi * a * b

    def cowper(m):
        m2 = m * m
        den = (40 + 37 * nu) * m2 * m2 + (16 + 10 * nu) * m2 + nu
        return 12 * (1 + nu) * m2 * (3 * m2 + 1) / den

    assert K[4, 4] == pytest.approx(L * G * cowper(a / b) * A, rel=1e-12)
    assert K[5, 5] == pytest.approx(L * G * cowper(b / a) * A, rel=1e-12)
    assert cowper(a / b) != pytest.approx(cowper(b / a), rel=1e-3)


# ------------------------------------------------------------ SoRoSim's mechanics

_MODES = (1, 1, 1, 1, 1, 1)
_ORDERS = (2, 1, 2, 1, 0, 1)
_LENGTHS = (0.4, 0.3)
_E, _NU, _ETA = 2e6, 0.45, 300.0
_RECT_H, _RECT_W = (0.02, 0.012), (0.03, 0.018)  # tapers (start, end) [m]
_ELL_A, _ELL_B = (0.015, 0.01), (0.01, 0.008)


def _taper(ends, X1):
    return ends[0] + (ends[1] - ends[0]) * X1


def _sorosim_section_constants(kind, X1):
    """SoRoSim's model by hand: ``(A, Iy, Iz)`` of the tapered shape at X1."""
    if kind == "rect":
        h, w = _taper(_RECT_H, X1), _taper(_RECT_W, X1)
        return w * h, w * h**3 / 12, h * w**3 / 12
    a, b = _taper(_ELL_A, X1), _taper(_ELL_B, X1)
    return math.pi * a * b, math.pi * a * b**3 / 4, math.pi * a**3 * b / 4


def _hand_assembled(kind, L):
    """K and D of one division, SoRoSim's model, by 24-point Gauss-Legendre.

    Sigma = diag(G (Iy + Iz), E Iy, E Iz, E A, G A, G A), Upsilon = eta diag(Iy +
    Iz, 3 Iy, 3 Iz, 3 A, A, A); shifted Legendre blocks, angular rows / L; 24
    points integrate the polynomial integrands (degree <= 8) exactly.
    """
    G = _E / (2 * (1 + _NU))
    x, w = np.polynomial.legendre.leggauss(24)
    X1s, ws = (x + 1) / 2, w / 2
    n = sum(o + 1 for o in _ORDERS)
    K, D = np.zeros((n, n)), np.zeros((n, n))
    for X1, wk in zip(X1s, ws, strict=True):
        Phi = np.zeros((6, n))
        col = 0
        for row, order in enumerate(_ORDERS):
            for p in range(order + 1):
                coef = np.zeros(p + 1)
                coef[p] = 1.0
                value = np.polynomial.legendre.legval(2 * X1 - 1, coef)
                Phi[row, col] = value / (L if row < 3 else 1.0)
                col += 1
        A, Iy, Iz = _sorosim_section_constants(kind, X1)
        Sigma = np.diag([G * (Iy + Iz), _E * Iy, _E * Iz, _E * A, G * A, G * A])
        Ups = _ETA * np.diag([Iy + Iz, 3 * Iy, 3 * Iz, 3 * A, A, A])
        K += wk * L * Phi.T @ Sigma @ Phi
        D += wk * L * Phi.T @ Ups @ Phi
    return K, D


def _two_link(sections):
    material = sj.Material(E=_E, poisson=_NU, rho=1000.0, eta=_ETA)
    basis = sj.LegendreBasis(_MODES, _ORDERS)
    links = [
        sj.SoftLink(sj.Division(L, s, basis), material)
        for L, s in zip(_LENGTHS, sections, strict=True)
    ]
    return sj.Linkage(links)


def test_sorosim_mechanics_reproduces_sorosim_stiffness_and_damping():
    """``sorosim_mechanics`` gives SoRoSim's K and D: polar J, no shear correction.

    A tapered rectangle and a tapered ellipse (two links, all six modes, mixed
    orders): K and D equal the hand-assembled Galerkin sums of SoRoSim's
    Sigma and Upsilon, and those of a ``SectionProperties`` linkage given the same
    values, to 1e-12 (rounding of the quadrature sums). The default model differs
    (Saint-Venant J < polar; Cowper's k < 1), so the switch is not a no-op.
    """
    shaped = _two_link(
        [sj.RectangularSection(_RECT_H, _RECT_W), sj.EllipticalSection(_ELL_A, _ELL_B)]
    )
    switched = sj.sorosim_mechanics(shaped)

    def given(kind):
        def value(i):
            return lambda X1: _sorosim_section_constants(kind, X1)[i]

        A, Iy, Iz = value(0), value(1), value(2)
        return sj.SectionProperties(A=A, Iy=Iy, Iz=Iz, J=lambda X1: Iy(X1) + Iz(X1))

    properties = _two_link([given("rect"), given("ell")])
    blocks = [
        _hand_assembled(k, L) for k, L in zip(("rect", "ell"), _LENGTHS, strict=True)
    ]
    n = blocks[0][0].shape[0]
    K_ref, D_ref = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 2 * n))
    for i, (Kb, Db) in enumerate(blocks):
        K_ref[i * n : (i + 1) * n, i * n : (i + 1) * n] = Kb
        D_ref[i * n : (i + 1) * n, i * n : (i + 1) * n] = Db
    for name, lk in (
        ("sorosim_mechanics", switched),
        ("SectionProperties", properties),
    ):
        K = np.asarray(sj.stiffness_matrix(lk))
        D = np.asarray(sj.damping_matrix(lk))
        np.testing.assert_allclose(
            K, K_ref, rtol=1e-12, atol=1e-12 * np.abs(K_ref).max(), err_msg=f"K {name}"
        )
        np.testing.assert_allclose(
            D, D_ref, rtol=1e-12, atol=1e-12 * np.abs(D_ref).max(), err_msg=f"D {name}"
        )
    K_default = np.asarray(sj.stiffness_matrix(shaped))
    assert K_default[0, 0] < 0.99 * K_ref[0, 0], "default torsion not below polar"
    shear_y = sum(o + 1 for o in _ORDERS[:4])  # first shear-y column
    assert K_default[shear_y, shear_y] < 0.99 * K_ref[shear_y, shear_y]


def test_section_model_switch_reuses_the_compiled_program():
    """The section model is data: ``sorosim_mechanics``, a given shear coefficient
    and the default share one trace (hence one compile) of a jitted function, and
    each still gets its own values (the trace sees the model's array leaves).
    Reference: the same function called without jit (1e-12)."""
    shaped = _two_link(
        [sj.RectangularSection(_RECT_H, _RECT_W), sj.EllipticalSection(_ELL_A, _ELL_B)]
    )
    variants = [
        shaped,
        sj.sorosim_mechanics(shaped),
        _two_link(
            [
                sj.RectangularSection(_RECT_H, _RECT_W, shear_coefficient=0.9),
                sj.EllipticalSection(_ELL_A, _ELL_B, torsion="polar"),
            ]
        ),
    ]

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def stiffness(lk):
        return sj.stiffness_matrix(lk)

    Ks = [np.asarray(stiffness(lk)) for lk in variants]  # raises on a second trace
    for lk, K in zip(variants, Ks, strict=True):
        np.testing.assert_allclose(K, sj.stiffness_matrix(lk), rtol=1e-12)
    assert Ks[1][0, 0] > 1.01 * Ks[0][0, 0], "polar J not above Saint-Venant's"
    assert variants[1].links[0].divisions[0].section.torsion == "polar"
    assert variants[2].links[0].divisions[0].section.shear_coefficient == 0.9


# --------------------------------------------------------------------- bad input


@pytest.mark.parametrize("J", [0.0, -1e-8])
def test_section_properties_rejects_nonpositive_torsion_constant(J):
    """J <= 0 would make the rod free (or unstable) in torsion: ValueError naming J."""
    with pytest.raises(ValueError, match=r"SectionProperties\.J"):
        sj.SectionProperties(A=1e-4, Iy=1e-9, Iz=1e-9, J=J)


@pytest.mark.parametrize("k", [0.0, -0.5, 1.6, "a lot"])
@pytest.mark.parametrize(
    "make",
    [
        lambda **kw: sj.CircularSection(0.01, **kw),
        lambda **kw: sj.RectangularSection(0.02, 0.01, **kw),
        lambda **kw: sj.EllipticalSection(0.02, 0.01, **kw),
    ],
    ids=["circle", "rectangle", "ellipse"],
)
def test_sections_reject_shear_coefficient_outside_range(make, k):
    """A shear coefficient outside (0, 1.5] is not physical: ValueError naming it."""
    with pytest.raises(ValueError, match="shear_coefficient"):
        make(shear_coefficient=k)


def test_sections_reject_unknown_torsion_model():
    """Only 'saint-venant' and 'polar': ValueError naming the field."""
    with pytest.raises(ValueError, match="torsion"):
        sj.RectangularSection(0.02, 0.01, torsion="warping")
