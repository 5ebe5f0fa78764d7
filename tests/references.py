"""Independent reference solutions (pure numpy/scipy) for the sorojax test suite.

Everything here is derived from the mathematics directly and deliberately does
NOT import jax or sorojax, so that it can serve as an independent oracle.

Conventions (shared with the simulator):
    * SI units.
    * The rod axis is the local x axis; planar problems bend in the x-y plane.
    * Cross-section quantities: ``A`` area, ``I`` second moment about the
      bending (z) axis, ``E`` Young's modulus, ``G`` shear modulus.
    * Shear stiffness is ``G * A`` and ``G`` enters nowhere else: pass the effective
      ``k G`` for a shear coefficient ``k`` (sorojax's shaped sections use Cowper's
      ``k`` by default: ``Sigma = diag(GJ, EIy, EIz, EA, k GA, k GA)``).

Contents:
    elastica_cantilever_tip_load            -- exact elliptic-integral elastica
    elastica_cantilever_tip_load_shooting   -- independent ODE (shooting) check
    cosserat_planar_static                  -- planar Reissner/Cosserat rod statics
    cosserat_planar_static_with_rigid_tip_body
    euler_bernoulli_cantilever_tip_deflection
    timoshenko_cantilever_tip_deflection
    cantilever_beta_L_roots / cantilever_natural_frequencies
    pendulum_period
    rigid_double_pendulum_rhs / rigid_double_pendulum / rigid_double_pendulum_energy
    gradient_vs_central_difference           -- derivative check of any scalar map
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp
from scipy.optimize import brentq
from scipy.special import ellipeinc, ellipk, ellipkinc

__all__ = [
    "elastica_cantilever_tip_load",
    "elastica_cantilever_tip_load_shooting",
    "cosserat_planar_static",
    "cosserat_planar_static_with_rigid_tip_body",
    "euler_bernoulli_cantilever_tip_deflection",
    "timoshenko_cantilever_tip_deflection",
    "cantilever_beta_L_roots",
    "cantilever_natural_frequencies",
    "pendulum_period",
    "rigid_double_pendulum_rhs",
    "rigid_double_pendulum",
    "rigid_double_pendulum_energy",
]

# ---------------------------------------------------------------------------
# 1. Elastica: cantilever with a transverse dead tip load
# ---------------------------------------------------------------------------


def _elastica_parameters(theta0):
    """Elliptic-integral parameters for a given tip rotation ``theta0``.

    Returns ``(m, psi, s0)`` with ``m = k**2 = (1 + sin theta0) / 2``,
    ``s0 = sin theta0`` and ``psi`` the complementary amplitude defined by
    ``tan(psi) = sqrt(2 s0 / (1 - s0))`` (see the derivation in
    :func:`elastica_cantilever_tip_load`).
    """
    s0 = math.sin(theta0)
    m = 0.5 * (1.0 + s0)
    # sin(psi) = sqrt(2 s0 / (1 + s0)), cos(psi) = sqrt((1 - s0) / (1 + s0));
    # (1 - s0) is evaluated as 2 sin^2(pi/4 - theta0/2) to avoid cancellation.
    one_minus_s0 = 2.0 * math.sin(0.25 * math.pi - 0.5 * theta0) ** 2
    psi = math.atan2(math.sqrt(2.0 * s0), math.sqrt(one_minus_s0))
    return m, psi, s0


def elastica_cantilever_tip_load(alpha):
    """Exact large-deflection cantilever under a transverse tip dead load.

    Model:
        Inextensible, unshearable Euler (Kirchhoff) elastica of length ``L = 1``
        clamped at ``x = 0`` with its tangent along ``+x``. A dead load ``P``
        acts at the free end in the ``+y`` direction (perpendicular to the
        *undeformed* axis and keeping that direction). With ``theta(s)`` the
        tangent angle and ``alpha = P L**2 / (E I)``, moment equilibrium gives::

            theta'' = -alpha * cos(theta),  theta(0) = 0,  theta'(1) = 0.

        The first integral is ``theta'**2 / 2 = alpha (sin theta0 - sin theta)``
        with ``theta0 = theta(1)`` the tip rotation. The substitution
        ``1 + sin(theta) = 2 k**2 sin(phi)**2`` with
        ``k**2 = (1 + sin theta0) / 2`` turns ``ds`` into
        ``dphi / (sqrt(alpha) sqrt(1 - k**2 sin(phi)**2))`` and gives
        (Bisshopp & Drucker 1945)::

            sqrt(alpha) = K(k) - F(phi1, k),       sin(phi1) = 1 / (k sqrt 2)
            x_tip       = sqrt(2 sin(theta0) / alpha)
            y_tip       = 1 - (2 / sqrt(alpha)) (E(k) - E(phi1, k))

        For accuracy the differences ``K - F(phi1)`` and ``E - E(phi1)`` are
        rewritten with Legendre's addition theorem (``F(phi1) + F(psi) = K``
        iff ``tan(phi1) tan(psi) = 1/k'``; then
        ``E(phi1) + E(psi) = E + k**2 sin(phi1) sin(psi)``), which gives the
        cancellation-free forms ``sqrt(alpha) = F(psi, k)`` and
        ``E - E(phi1) = E(psi, k) - sqrt(sin(theta0) / 2)`` with
        ``tan(psi) = sqrt(2 sin theta0 / (1 - sin theta0))``. ``theta0`` is
        found with Brent's method to machine precision.

    Assumptions:
        Quasi-static, linear-elastic moment-curvature law ``M = E I theta'``,
        no axial strain, no shear strain, planar deformation, no self-weight.

    Sources:
        K. E. Bisshopp and D. C. Drucker, "Large deflection of cantilever
        beams", Quart. Appl. Math. 3 (1945) 272-275; see also K. Mattiasson,
        "Numerical results from large deflection beam and frame problems
        analysed by means of elliptic integrals", IJNME 17 (1981) 145-153.
        Legendre's addition theorem: Byrd & Friedman, Handbook of Elliptic
        Integrals (1971), formulas 116.01-116.02.

    Args:
        alpha: Dimensionless load ``P L**2 / (E I)`` (``alpha >= 0``).

    Returns:
        Tuple ``(x_tip / L, y_tip / L, theta_tip)`` of floats: horizontal tip
        position (i.e. ``1 -`` horizontal displacement), vertical tip
        deflection and tip rotation in radians. Accurate to ~1e-13 for
        ``1e-3 <= alpha <= 1e3`` (relative accuracy of ``y_tip`` degrades like
        ``eps / alpha`` as ``alpha -> 0``, where ``y_tip ~ alpha / 3``).
    """
    alpha = float(alpha)
    if alpha < 0.0:
        raise ValueError("alpha must be non-negative (load along +y)")
    if alpha == 0.0:
        return 1.0, 0.0, 0.0
    sqa = math.sqrt(alpha)

    def length_residual(theta0):
        m, psi, _ = _elastica_parameters(theta0)
        return float(ellipkinc(psi, m)) - sqa

    # residual(0) = -sqrt(alpha) < 0 and residual -> +inf as theta0 -> pi/2
    # (K(k) diverges logarithmically as k -> 1).
    hi = 0.5 * math.pi - 1e-15
    if length_residual(hi) <= 0.0:
        raise ValueError("alpha too large for double precision (alpha > ~1e3)")
    theta0 = brentq(length_residual, 0.0, hi, xtol=1e-15, rtol=1e-15, maxiter=500)
    m, psi, s0 = _elastica_parameters(theta0)
    x_tip = math.sqrt(2.0 * s0 / alpha)
    e_diff = float(ellipeinc(psi, m)) - math.sqrt(0.5 * s0)
    y_tip = 1.0 - 2.0 * e_diff / sqa
    return float(x_tip), float(y_tip), float(theta0)


def elastica_cantilever_tip_load_shooting(alpha, rtol=1e-13):
    """Independent numerical elastica solution by shooting (cross-check only).

    Model:
        Same problem as :func:`elastica_cantilever_tip_load`, written as the
        first-order system ``x' = cos theta, y' = sin theta, theta' = kappa,
        kappa' = -alpha cos theta`` on ``s in [0, 1]`` with
        ``x = y = theta = 0`` at ``s = 0``. The unknown root curvature
        ``kappa(0)`` is found with Brent's method so that ``kappa(1) = 0``;
        integration uses DOP853 at ``rtol``. Shooting is ill-conditioned for
        large loads (sensitivity ~ exp(sqrt(alpha))); use for alpha <~ 30. ``kappa(0)`` lies in
        ``[0, sqrt(2 alpha)]`` (first integral: ``kappa(0)**2 =
        2 alpha sin(theta0)``); the largest root in that interval is taken.

    Source:
        Direct numerical integration of the elastica ODE (no elliptic
        integrals), used to validate the closed form.

    Args:
        alpha: Dimensionless load ``P L**2 / (E I)``.
        rtol: Relative tolerance of the ODE integrator.

    Returns:
        Tuple ``(x_tip, y_tip, theta_tip)`` as floats.
    """
    alpha = float(alpha)
    if alpha == 0.0:
        return 1.0, 0.0, 0.0

    def rhs(_s, z):
        return [math.cos(z[2]), math.sin(z[2]), z[3], -alpha * math.cos(z[2])]

    def integrate(k0):
        return solve_ivp(
            rhs,
            (0.0, 1.0),
            [0.0, 0.0, 0.0, k0],
            method="DOP853",
            rtol=rtol,
            atol=rtol * 1e-2,
        ).y[:, -1]

    # First integral: kappa(0)**2 = 2 alpha sin(theta0) <= 2 alpha. The
    # physical (monotone-theta) branch is the largest root below sqrt(2 alpha);
    # smaller roots correspond to looping solutions for large alpha, so scan
    # downwards from sqrt(2 alpha) for the first sign change.
    kmax = math.sqrt(2.0 * alpha)
    grid = kmax * np.linspace(1.0, 0.0, 81)
    res = [integrate(k)[3] for k in grid]
    for j in range(1, len(grid)):
        if res[j] == 0.0:
            k0 = grid[j]
            break
        if np.sign(res[j]) != np.sign(res[j - 1]):
            k0 = brentq(
                lambda k: integrate(k)[3],
                grid[j],
                grid[j - 1],
                xtol=1e-15,
                rtol=1e-15,
                maxiter=200,
            )
            break
    else:  # pragma: no cover
        raise RuntimeError("no shooting bracket found")
    z = integrate(k0)
    return float(z[0]), float(z[1]), float(z[2])


# ---------------------------------------------------------------------------
# 2./3. Planar Cosserat (Reissner) rod statics
# ---------------------------------------------------------------------------


def _cross2(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _solve_planar_cosserat(
    L,
    E,
    G,
    A,
    I,
    rho,
    g_vec,
    tip_force_fn,
    tip_moment_fn,
    extensible,
    shearable,
    n_mesh,
    rtol=1e-12,
):
    """Core solver shared by the planar Cosserat references.

    Method:
        With dead loads the global internal force is known in closed form,
        ``n(s) = n(L) + f (L - s)``, and ``p'`` depends only on ``theta`` and
        ``n(s)``. The remaining two-point problem for ``(theta, m, x, y)``
        (dimensionless: lengths / L, moments / (EI/L), forces / (EI/L^2)) is

        * first solved with ``scipy.integrate.solve_bvp`` (global collocation,
          immune to the ~exp(sqrt(P L^2/EI)) sensitivity of simple shooting)
          with load continuation in ``lam in [0, 1]`` (all loads scaled by
          ``lam``, step halving when Newton fails or the tip angle jumps by
          more than 0.3 rad), which keeps the solution on the branch
          connected to the unloaded state; then
        * polished by backward shooting from the free end on the single
          unknown ``theta(L)`` (DOP853 at ``rtol``, Brent's method in a tight
          bracket around the collocation value) so that ``theta(0) = 0`` to
          ~1e-14; ``(x, y, theta, m)`` are then integrated backward with
          ``p(L) = 0`` and shifted so that ``p(0) = 0``. If no sign change is
          found near the collocation value the collocation solution is kept.

    ``tip_force_fn(lam)`` returns the global (dead) tip force at load factor
    ``lam``; ``tip_moment_fn(lam, theta_tip)`` returns the tip moment.
    """
    L, E, G, A, I, rho = map(float, (L, E, G, A, I, rho))
    g_vec = np.asarray(g_vec, dtype=float).reshape(2)
    EI = E * I
    fscale = EI / L**2
    mscale = EI / L
    a_bar = E * A * L**2 / EI  # axial stiffness / fscale
    g_bar = G * A * L**2 / EI  # shear stiffness / fscale
    q_bar = rho * A * g_vec * L**3 / EI  # distributed load per unit s_bar

    def make_rhs(lam):
        q = lam * q_bar
        nL = np.asarray(tip_force_fn(lam), dtype=float) / fscale

        def rhs(s, z):
            # works for scalar s / z of shape (4,) and vectorised (4, M)
            th, mm = z[0], z[1]
            c, sn = np.cos(th), np.sin(th)
            # global internal force from n' + f = 0 integrated from the tip
            nx = nL[0] + q[0] * (1.0 - s)
            ny = nL[1] + q[1] * (1.0 - s)
            # material components n_mat = R^T n and strains nu
            n1 = c * nx + sn * ny
            n2 = -sn * nx + c * ny
            nu1 = 1.0 + n1 / a_bar if extensible else 1.0 + 0.0 * n1
            nu2 = n2 / g_bar if shearable else 0.0 * n2
            dx = c * nu1 - sn * nu2  # p' = R nu
            dy = sn * nu1 + c * nu2
            # theta' = m / EI ;  m' = -(p' x n)_z
            return np.array([mm, -(dx * ny - dy * nx), dx, dy])

        return rhs

    def make_bc(lam):
        def bc(za, zb):
            return np.array(
                [za[0], za[2], za[3], zb[1] - tip_moment_fn(lam, zb[0]) / mscale]
            )

        return bc

    # --- 1. collocation with load continuation -----------------------------
    mesh = np.linspace(0.0, 1.0, 101)
    sol = None
    guess_x, guess_y = mesh, np.zeros((4, mesh.size))
    guess_y[2] = mesh
    lam, dlam = 0.0, 1.0
    while lam < 1.0:
        lam_new = min(1.0, lam + dlam)
        trial = solve_bvp(
            make_rhs(lam_new),
            make_bc(lam_new),
            guess_x,
            guess_y,
            tol=1e-6,
            max_nodes=3000,
        )
        jump = np.inf
        if trial.success:
            prev_tip = guess_y[0, -1]
            jump = abs(trial.sol(1.0)[0] - prev_tip)
        if not trial.success or (jump > 0.3 and dlam > 1.0 / 256):
            dlam *= 0.5
            if dlam < 1e-5:
                raise RuntimeError("planar Cosserat: continuation failed")
            continue
        lam, sol = lam_new, trial
        guess_x, guess_y = sol.x, sol.y
        dlam = min(1.0, 2.0 * dlam)
    sol = solve_bvp(
        make_rhs(1.0), make_bc(1.0), sol.x, sol.y, tol=1e-9, max_nodes=500000
    )
    th_colloc = float(sol.sol(1.0)[0])

    # --- 2. polish by backward shooting on theta(L) ------------------------
    rhs = make_rhs(1.0)

    def integrate_back(tht, dense=False):
        z_tip = [tht, tip_moment_fn(1.0, tht) / mscale, 0.0, 0.0]
        return solve_ivp(
            rhs,
            (1.0, 0.0),
            z_tip,
            method="DOP853",
            rtol=rtol,
            atol=rtol * 1e-2,
            dense_output=dense,
        )

    def theta_base(tht):
        return integrate_back(tht).y[0, -1]

    th_tip = None
    for delta in (1e-7, 1e-5, 1e-3):
        lo, hi = th_colloc - delta, th_colloc + delta
        if np.sign(theta_base(lo)) != np.sign(theta_base(hi)):
            th_tip = brentq(theta_base, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200)
            break

    s_bar = np.linspace(0.0, 1.0, int(n_mesh) + 1)
    if th_tip is not None:
        back = integrate_back(th_tip, dense=True)
        z = back.sol(s_bar)
        z[:, -1] = back.y[:, 0]
        z[:, 0] = back.y[:, -1]
        base = back.y[:, -1].copy()
        method = "shooting"
    else:  # pragma: no cover - fallback for pathological loads
        z = sol.sol(s_bar)
        base = np.zeros(4)
        base[0] = z[0, 0]
        method = "collocation"
    out = {
        "s": s_bar * L,
        "x": (z[2] - base[2]) * L,
        "y": (z[3] - base[3]) * L,
        "theta": z[0].copy(),
        "m": z[1] * mscale,
        "residual": float(base[0]),
        "method": method,
    }
    out["tip"] = (float(out["x"][-1]), float(out["y"][-1]), float(out["theta"][-1]))
    return out


def cosserat_planar_static(
    L,
    E,
    G,
    A,
    I,
    rho,
    g_vec,
    tip_mass=0.0,
    tip_force=(0.0, 0.0),
    tip_moment=0.0,
    extensible=True,
    shearable=True,
    n_mesh=200,
):
    """Static equilibrium of a planar Cosserat (Reissner) cantilever rod.

    Model:
        Geometrically exact planar rod (Reissner 1972 / Simo-Reissner) with
        reference arc length ``s in [0, L]``, centreline ``p(s) = (x, y)`` and
        section rotation ``R(theta)`` about ``z``. Clamped at ``s = 0`` at the
        origin with ``theta(0) = 0`` (tangent along ``+x``). Strains:
        ``kappa = theta'`` and ``nu = R^T p'`` (``nu1`` stretch, ``nu2``
        shear). Linear-elastic constitutive law in the material frame::

            m  = E I kappa
            n1 = E A (nu1 - 1),  n2 = G A nu2     (n_mat = R^T n)

        with ``nu1 = 1`` if not ``extensible`` and ``nu2 = 0`` if not
        ``shearable`` (the corresponding force becomes a reaction).
        Equilibrium with global internal force ``n`` and moment ``m``::

            n' + f = 0,   f = rho A g_vec   (per unit *reference* length)
            m' + (p' x n)_z = 0

        Boundary conditions at ``s = L``: ``n(L) = tip_force + tip_mass g_vec``
        (dead loads) and ``m(L) = tip_moment``. The force balance is integrated
        in closed form, ``n(s) = n(L) + f (L - s)``, leaving a two-point problem
        for ``(theta, m, x, y)``, solved with ``scipy.integrate.solve_bvp``
        (tol 1e-6 during continuation, 1e-9 at full load) with load
        continuation in a load factor ``lam in [0, 1]``
        applied to all loads, then polished to ~1e-12 by backward shooting
        from the free end on ``theta(L)``; see ``_solve_planar_cosserat``.

    Assumptions:
        Quasi-static, planar, small strains with linear elasticity, dead
        (non-follower) loads, gravity acting on the reference length (mass is
        conserved, so weight per reference length is ``rho A g``). For very
        large loads the continuation follows the equilibrium branch connected
        to the unloaded configuration.

    Sources:
        E. Reissner, "On one-dimensional finite-strain beam theory: the plane
        problem", ZAMP 23 (1972) 795-804; S. S. Antman, Nonlinear Problems of
        Elasticity, 2nd ed., Springer (2005), ch. 4.

    Args:
        L, E, G, A, I, rho: Length, Young's and shear moduli, area, second
            moment of area about z, density (SI units).
        g_vec: Gravity 2-vector in the x-y plane, e.g. ``(0, -9.81)``.
        tip_mass: Point mass at the tip (adds weight ``tip_mass * g_vec``).
        tip_force: Global dead tip force ``(Fx, Fy)``.
        tip_moment: Tip moment about ``+z``.
        extensible: Allow axial strain (``EA`` finite) if True.
        shearable: Allow transverse shear strain (``GA`` finite) if True.
        n_mesh: Number of intervals of the uniform output mesh.

    Returns:
        Dict with arrays ``'s', 'x', 'y', 'theta', 'm'`` (length ``n_mesh+1``),
        ``'tip' = (x_tip, y_tip, theta_tip)`` and ``'residual'`` (``theta(0)`` of the
        final solution, ~1e-13) and ``'method'`` (``'shooting'`` if polished,
        else ``'collocation'``).
    """
    g_vec = np.asarray(g_vec, dtype=float).reshape(2)
    F = np.asarray(tip_force, dtype=float).reshape(2) + float(tip_mass) * g_vec
    M = float(tip_moment)
    return _solve_planar_cosserat(
        L,
        E,
        G,
        A,
        I,
        rho,
        g_vec,
        tip_force_fn=lambda lam: lam * F,
        tip_moment_fn=lambda lam, tht: lam * M,
        extensible=extensible,
        shearable=shearable,
        n_mesh=n_mesh,
    )


def cosserat_planar_static_with_rigid_tip_body(
    L,
    E,
    G,
    A,
    I,
    rho,
    g_vec,
    body_mass,
    body_com_offset=(0.0, 0.0),
    tip_force=(0.0, 0.0),
    tip_moment=0.0,
    extensible=True,
    shearable=True,
    n_mesh=200,
):
    """Planar Cosserat cantilever carrying a rigid body with an offset CM.

    Model:
        As :func:`cosserat_planar_static`, but the tip carries a rigid body
        attached rigidly to the tip cross-section. Its centre of mass sits at
        ``p(L) + R(theta_tip) c`` with ``c = body_com_offset`` expressed in the
        tip (material) frame. The body weight ``W = body_mass * g_vec`` acts
        at the CM, so the rod tip receives the force ``W`` and the
        configuration-dependent moment ``((R(theta_tip) c) x W)_z``::

            n(L) = tip_force + W
            m(L) = tip_moment + (R(theta_tip) c) x W

        Since the solver shoots on ``theta_tip``, the tip moment is known
        exactly for each trial (no outer fixed-point iteration).

    Assumptions:
        Statics only (the body's rotational inertia plays no role), dead
        loads, same rod assumptions as :func:`cosserat_planar_static`.

    Sources:
        Rigid-body statics (Newton-Euler with zero accelerations) coupled to
        Reissner's planar rod, see references of
        :func:`cosserat_planar_static`.

    Args:
        L, E, G, A, I, rho, g_vec: As in :func:`cosserat_planar_static`.
        body_mass: Mass of the rigid tip body.
        body_com_offset: CM offset ``c`` from the rod tip in the tip frame,
            e.g. ``(0.05, 0.0)`` along the tip tangent.
        tip_force, tip_moment: Additional dead tip force / moment.
        extensible, shearable, n_mesh: As in :func:`cosserat_planar_static`.

    Returns:
        Same dict as :func:`cosserat_planar_static` plus ``'cm'`` (global CM
        position as a length-2 array).
    """
    g_vec = np.asarray(g_vec, dtype=float).reshape(2)
    c = np.asarray(body_com_offset, dtype=float).reshape(2)
    W = float(body_mass) * g_vec
    F = np.asarray(tip_force, dtype=float).reshape(2) + W
    M = float(tip_moment)

    def rot(th):
        return np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])

    def tip_moment_fn(lam, tht):
        return lam * (M + _cross2(rot(tht) @ c, W))

    out = _solve_planar_cosserat(
        L,
        E,
        G,
        A,
        I,
        rho,
        g_vec,
        tip_force_fn=lambda lam: lam * F,
        tip_moment_fn=tip_moment_fn,
        extensible=extensible,
        shearable=shearable,
        n_mesh=n_mesh,
    )
    xt, yt, tht = out["tip"]
    out["cm"] = np.array([xt, yt]) + rot(tht) @ c
    return out


# ---------------------------------------------------------------------------
# 4. Linear beam tip deflections
# ---------------------------------------------------------------------------


def euler_bernoulli_cantilever_tip_deflection(P, L, E, I):
    """Linear Euler-Bernoulli cantilever tip deflection under a tip load.

    Model:
        ``w(L) = P L**3 / (3 E I)`` for a clamped-free prismatic beam with a
        transverse tip load ``P`` (small deflections, no shear deformation).

    Source:
        Standard beam theory, e.g. Timoshenko & Gere, Mechanics of Materials.

    Args:
        P: Transverse tip load. L: Length. E: Young's modulus. I: Second moment.

    Returns:
        Tip deflection (same sign as ``P``).
    """
    return P * L**3 / (3.0 * E * I)


def timoshenko_cantilever_tip_deflection(P, L, E, G, A, I):
    """Linear Timoshenko cantilever tip deflection under a tip load.

    Model:
        ``w(L) = P L**3 / (3 E I) + P L / (G A)``: bending plus uniform
        transverse shear strain ``gamma = P / (G A)``. The shear area is the
        plain ``A`` (shear-correction factor 1), consistent with the
        simulator's shear stiffness ``G A``.

    Source:
        S. P. Timoshenko, Phil. Mag. 41 (1921) 744; Timoshenko & Gere.

    Args:
        P: Transverse tip load. L: Length. E, G: Young's and shear moduli.
        A: Area. I: Second moment of area.

    Returns:
        Tip deflection (same sign as ``P``).
    """
    return P * L**3 / (3.0 * E * I) + P * L / (G * A)


# ---------------------------------------------------------------------------
# 5. Vibration and pendulum references
# ---------------------------------------------------------------------------


def cantilever_beta_L_roots(n=3):
    """First ``n`` roots of the clamped-free frequency equation.

    Model:
        ``1 + cos(x) cosh(x) = 0``, solved as ``cos(x) + 1/cosh(x) = 0``
        (same roots, bounded function) with Brent's method on the brackets
        ``[(k-1) pi, k pi]``, each of which contains exactly one root.

    Source:
        Euler-Bernoulli beam vibration, e.g. Blevins, Formulas for Natural
        Frequency and Mode Shape (1979), Table 8-1: 1.87510407, 4.69409113,
        7.85475744, 10.99554073, 14.13716839.

    Returns:
        ``numpy.ndarray`` of ``beta_k L``, ``k = 1..n``.
    """
    f = lambda x: math.cos(x) + 1.0 / math.cosh(x)  # noqa: E731
    return np.array(
        [
            brentq(f, (k - 1) * math.pi, k * math.pi, xtol=1e-15, rtol=1e-15)
            for k in range(1, int(n) + 1)
        ]
    )


def cantilever_natural_frequencies(E, I, rho, A, L, n=3):
    """Euler-Bernoulli clamped-free bending natural frequencies (rad/s).

    Model:
        ``omega_k = (beta_k L)**2 sqrt(E I / (rho A L**4))`` with ``beta_k L``
        the roots of ``1 + cos x cosh x = 0`` (see
        :func:`cantilever_beta_L_roots`). No shear deformation or rotary
        inertia (slender beam), small amplitudes.

    Source:
        Blevins (1979) Table 8-1; Meirovitch, Elements of Vibration Analysis.

    Returns:
        ``numpy.ndarray`` of angular frequencies ``omega_k`` in rad/s.
    """
    bl = cantilever_beta_L_roots(n)
    return bl**2 * math.sqrt(E * I / (rho * A * L**4))


def pendulum_period(length_to_cm, g, amplitude, inertia_about_pivot=None, mass=None):
    """Exact period of a (physical) pendulum released from rest.

    Model:
        ``I theta'' = -m g l sin(theta)`` released at ``theta = amplitude``.
        Energy conservation gives ``T = 4 sqrt(I / (m g l)) K(k)``,
        ``k = sin(amplitude / 2)``, with ``K`` the complete elliptic integral
        of the first kind (scipy's ``ellipk`` takes ``m = k**2``). For a point
        mass ``I = m l**2`` so ``T = 4 sqrt(l / g) K(k)``.

    Source:
        Classical result, e.g. Landau & Lifshitz, Mechanics, sec. 11, problem 1.

    Args:
        length_to_cm: Pivot-to-centre-of-mass distance ``l``.
        g: Gravitational acceleration magnitude.
        amplitude: Release angle in radians (``|amplitude| < pi``).
        inertia_about_pivot: Moment of inertia about the pivot; ``None`` for a
            point mass.
        mass: Total mass; required when ``inertia_about_pivot`` is given.

    Returns:
        Period in seconds.
    """
    l = float(length_to_cm)
    if inertia_about_pivot is None:
        ratio = l / g  # I / (m g l) with I = m l^2
    else:
        if mass is None:
            raise ValueError("mass is required with inertia_about_pivot")
        ratio = float(inertia_about_pivot) / (float(mass) * g * l)
    k = math.sin(0.5 * float(amplitude))
    return 4.0 * math.sqrt(ratio) * float(ellipk(k * k))


# ---------------------------------------------------------------------------
# 6. Rigid double pendulum (Lagrange's equations)
# ---------------------------------------------------------------------------


def _double_pendulum_terms(params, phi1, phi2):
    """Mass-matrix entries and coupling coefficient of the double pendulum."""
    m1, m2 = params["m1"], params["m2"]
    L1, d1, d2 = params["L1"], params["d1"], params["d2"]
    a11 = m1 * d1**2 + params["I1"] + m2 * L1**2
    a22 = m2 * d2**2 + params["I2"]
    c = m2 * L1 * d2
    return a11, a22, c


def rigid_double_pendulum_rhs(params):
    """Right-hand side ``y' = f(t, y)`` of a planar rigid double pendulum.

    Model:
        Two rigid bars in the x-y plane, hinged about z at the origin and at the
        tip of bar 1; gravity ``g`` along -y. Absolute angles ``phi1``, ``phi2``
        of the bars from +x; bar k has mass ``mk``, pivot-to-CM distance ``dk``
        (CM on the bar's axis), inertia ``Ik`` about z at its CM; bar 1's
        pivot-to-pivot length is ``L1``. With ``D = phi1 - phi2``::

            T = 1/2 (m1 d1^2 + I1) phi1'^2 + 1/2 I2 phi2'^2
                + 1/2 m2 (L1^2 phi1'^2 + d2^2 phi2'^2 + 2 L1 d2 cos(D) phi1' phi2')
            V = m1 g d1 sin(phi1) + m2 g (L1 sin(phi1) + d2 sin(phi2))

        Lagrange's equations, with ``a11 = m1 d1^2 + I1 + m2 L1^2``,
        ``a22 = m2 d2^2 + I2``, ``c = m2 L1 d2``::

            a11 phi1'' + c cos(D) phi2'' = -c sin(D) phi2'^2 - (m1 d1 + m2 L1) g cos(phi1)
            c cos(D) phi1'' + a22 phi2'' =  c sin(D) phi1'^2 - m2 d2 g cos(phi2)

    Source:
        Derived here from the Lagrangian above (e.g. Goldstein, Classical
        Mechanics, ch. 1-2, for the method).

    Args:
        params: dict with ``m1, m2, L1, d1, d2, I1, I2, g``.

    Returns:
        ``rhs(t, y)`` for ``y = (phi1, phi2, phi1', phi2')``.
    """
    m1, m2, L1, d1, d2, g = (params[k] for k in ("m1", "m2", "L1", "d1", "d2", "g"))

    def rhs(t, y):
        p1, p2, w1, w2 = y
        a11, a22, c = _double_pendulum_terms(params, p1, p2)
        D = p1 - p2
        a12 = c * math.cos(D)
        b1 = -c * math.sin(D) * w2**2 - (m1 * d1 + m2 * L1) * g * math.cos(p1)
        b2 = c * math.sin(D) * w1**2 - m2 * d2 * g * math.cos(p2)
        det = a11 * a22 - a12**2
        return np.array(
            [w1, w2, (a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det]
        )

    return rhs


def rigid_double_pendulum(params, y0, t_eval, rtol=1e-12, atol=1e-12):
    """States ``(phi1, phi2, phi1', phi2')`` of :func:`rigid_double_pendulum_rhs`.

    Method: ``scipy.integrate.solve_ivp`` with DOP853 at ``rtol``/``atol``.

    Returns:
        ``(4, len(t_eval))`` array of the states at ``t_eval``.
    """
    t_eval = np.asarray(t_eval, dtype=float)
    sol = solve_ivp(
        rigid_double_pendulum_rhs(params),
        (0.0, float(t_eval[-1])),
        np.asarray(y0, dtype=float),
        method="DOP853",
        t_eval=t_eval,
        rtol=rtol,
        atol=atol,
    )
    if not sol.success:  # pragma: no cover
        raise RuntimeError(f"double pendulum reference failed: {sol.message}")
    return sol.y


def rigid_double_pendulum_energy(params, y):
    """Total energy ``T + V`` of :func:`rigid_double_pendulum_rhs` (states by column)."""
    p1, p2, w1, w2 = np.asarray(y, dtype=float)
    a11, a22, c = _double_pendulum_terms(params, p1, p2)
    m1, m2, L1, d1, d2, g = (params[k] for k in ("m1", "m2", "L1", "d1", "d2", "g"))
    T = 0.5 * a11 * w1**2 + 0.5 * a22 * w2**2 + c * np.cos(p1 - p2) * w1 * w2
    V = m1 * g * d1 * np.sin(p1) + m2 * g * (L1 * np.sin(p1) + d2 * np.sin(p2))
    return T + V


def gradient_vs_central_difference(value_and_grad, x, h):
    """A scalar map's derivative at ``x`` against its central difference.

    ``value_and_grad(x) -> (value, derivative)`` (e.g. ``jax.value_and_grad`` of the
    function under test): the difference uses the same callable, so one compiled
    program serves the three calls. Returns ``(derivative, central difference,
    relative error)``; the truncation error is ~h^2 |third derivative| / 6.
    """
    g = float(value_and_grad(x)[1])
    fd = (float(value_and_grad(x + h)[0]) - float(value_and_grad(x - h)[0])) / (2 * h)
    return g, fd, abs(g - fd) / abs(fd)
