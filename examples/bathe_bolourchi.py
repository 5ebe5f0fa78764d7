"""Bathe and Bolourchi's 45-degree bend: a curved cantilever loaded out of its plane.

The case (Bathe & Bolourchi 1979, Int. J. Numer. Meth. Eng. 14, 961; Simo & Vu-Quoc
1986, Comput. Methods Appl. Mech. Eng. 58, 79): a cantilever whose centre line is
a circular arc of radius 100 over 45 degrees, unit square section, E = 1e7,
poisson 0 (G = E / 2), a dead tip force of 600 normal to the plane of the arc.
Axes: the arc lies in the x-y plane, starts at the clamp at the origin tangent to
x and bends towards +y (centre (0, 100, 0), tip at (70.71, 29.29, 0)); the force
acts along +z. Published tip position (47.2, 15.9, 53.4) (Bathe & Bolourchi; Simo &
Vu-Quoc: 47.23, 15.79, 53.37), i.e. a tip displacement of about (-23.5, -13.4,
53.4); published values scatter by ~0.5 % with the element type and the torsion
constant used.

The model: one soft link of length 100 pi / 4, pre-curved by the reference strain
xi_ref = (0, 0, 1/R, 1, 0, 0) (bending about local z), all six strain modes,
Legendre orders (angular n, linear n - 1) raised until the tip displacement changes
by < 1e-5 of its size (n = 5, 33 DoF; 2.4e-6 from n = 4, 1e-7 to n = 6). Every
order is padded to the size class of order 6 (``sorojax.size_class``: the class's
16 points and 6th-order Magnus steps, the model's own coefficients switched on by
a 0/1 array), so the whole study compiles one statics program (first run 11.6 ->
9.1 s on a 2-core CPU); on their own default points the unpadded models' tips
differ from the padded ones by 7e-6 of |u| at n = 3 (fewer points and 4th-order
steps), 1e-8 at n = 4 and 3e-9 at n = 5.

Figures (tip displacement; this script prints them):

- J = 1/6 (polar, 2 I; ``torsion="polar"``), Cowper's k = 5/6:
  (-23.561, -13.605, 53.476), 0.38 % of |u| from (-23.5, -13.4, 53.4)
  (0.28 % from Simo & Vu-Quoc's);
- J = 0.1406 (Saint-Venant, the default): (-23.819, -13.732, 53.608), 0.84 % of
  |u| from (-23.5, -13.4, 53.4): the softer torsion lets the tip move 0.33 further
  (0.5 % of |u|);
- the shear coefficient (k = 1 instead of Cowper's 5/6) moves the tip by 7e-4
  (1.2e-5 of |u|): the rod is slender (R / side = 100).

Run::

    python examples/bathe_bolourchi.py [--out DIR] [--overwrite]
"""

import argparse
import math
import pathlib
import statistics
import time

import jax

jax.config.update("jax_enable_x64", True)

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.viz import plot_configuration, plot_reference  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

R, E, LOAD = 100.0, 1e7, 600.0
CLASS_ORDER = 6  # the size class of the convergence study (orders 3..6)
PUBLISHED = np.array([-23.5, -13.4, 53.4])  # Bathe & Bolourchi 1979
PUBLISHED_SVQ = np.array([47.23, 15.79, 53.37]) - [
    R * math.sin(math.pi / 4),
    R * (1 - math.cos(math.pi / 4)),
    0.0,
]  # Simo & Vu-Quoc 1986 (tip position minus the reference tip)


def bend(order=4, torsion="polar", shear_coefficient=None, load=LOAD):
    """The 45-degree bend with angular strains of ``order``, linear ``order - 1``.

    Args:
        order: Legendre order of the angular strains (linear strains one less).
        torsion: ``"polar"`` (J = 1/6) or ``"saint-venant"`` (J = 0.1406).
        shear_coefficient: ``None`` (Cowper's, 5/6 at poisson 0) or a number.
        load: tip force along +z.

    Returns:
        The :class:`sorojax.Linkage`.
    """
    section = sj.RectangularSection(
        1.0, 1.0, torsion=torsion, shear_coefficient=shear_coefficient
    )
    basis = sj.LegendreBasis((1, 1, 1, 1, 1, 1), (order,) * 3 + (order - 1,) * 3)
    division = sj.Division(
        R * math.pi / 4, section, basis, xi_ref=(0.0, 0.0, 1 / R, 1.0, 0.0, 0.0)
    )
    rod = sj.SoftLink(division, sj.Material(E=E, poisson=0.0, rho=1.0))
    wrench = np.array([0.0, 0.0, 0.0, 0.0, 0.0, load])
    return sj.Linkage(rod, point_wrenches=[sj.PointWrench(1, wrench)])


def padded_bend(order, torsion="polar", **kwargs):
    """:func:`bend` padded to the size class of order :data:`CLASS_ORDER`.

    Every order of the convergence study, both torsion constants and the load path
    share one compiled statics program (``sorojax.size_class``): the model's own
    coefficients are switched on by a 0/1 array, on the class's 16 points.
    """
    return sj.size_class(bend(order, torsion, **kwargs), CLASS_ORDER)


def n_own(linkage):
    """The model's own coordinates (its padding excluded)."""
    return len(sj.active_coordinates(linkage))


def tip_displacement(linkage, q):
    """Tip displacement from the reference arc ``(3,)``."""
    tip = np.asarray(sj.tip_pose(linkage, q))[:3, 3]
    tip0 = np.asarray(sj.tip_pose(linkage, np.zeros(linkage.n_dof)))[:3, 3]
    return tip - tip0


def relative_error(u, reference):
    """``|u - reference| / |reference|``."""
    return float(np.linalg.norm(u - reference) / np.linalg.norm(reference))


def solve(linkage, repeats=5):
    """Solve; return ``(tip displacement, q, first call [s], median warm [s])``."""
    t0 = time.perf_counter()
    sol = sj.solve_statics(linkage)
    sol.q.block_until_ready()
    first = time.perf_counter() - t0
    warm = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sj.solve_statics(linkage).q.block_until_ready()
        warm.append(time.perf_counter() - t0)
    median = statistics.median(warm) if warm else math.nan
    return tip_displacement(linkage, sol.q), sol.q, first, median


def tier():
    """How the warm calls were compiled (see ``sorojax.compile_mode``).

    In the default compile tiers a program called a few times runs at LLVM -O0
    (3-5x slower than at XLA's default level) until its second compile, in a
    worker thread, is done: the warm figures may be either tier's.
    """
    return "" if sj.compile_mode() == "full" else " (compile tiers: -O0 at first)"


def converge(torsion, tol=1e-5, min_order=3, max_order=CLASS_ORDER):
    """Raise the order until the tip displacement changes by < ``tol`` (relative)."""
    prev = None
    for order in range(min_order, max_order + 1):
        lk = padded_bend(order, torsion)
        u, q, first, warm = solve(lk)
        change = math.inf if prev is None else relative_error(u, prev)
        print(
            f"  {torsion:12s} order {order}: {n_own(lk)} DoF, tip displacement "
            f"{np.array2string(u, precision=4)}, change {change:.1e}; first call "
            f"{first:.1f} s, warm {1e3 * warm:.1f} ms{tier()}"
        )
        if change < tol:
            break
        prev = u
    return dict(order=order, linkage=lk, u=u, q=q, first=first, warm=warm)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "bathe_bolourchi.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    # Convergence in order with J = 1/6; the Saint-Venant J and k = 1 at the
    # converged order (the convergence in order does not depend on them).
    results = {"polar": converge("polar")}
    order = results["polar"]["order"]
    lk = padded_bend(order, "saint-venant")
    u, q, first, warm = solve(lk)
    results["saint-venant"] = dict(
        order=order, linkage=lk, u=u, q=q, first=first, warm=warm
    )
    u_k1 = solve(padded_bend(order, "polar", shear_coefficient=1.0), repeats=0)[0]
    shear_effect = float(np.linalg.norm(u_k1 - results["polar"]["u"]))
    for torsion, J in (("polar", "1/6"), ("saint-venant", "0.1406")):
        r = results[torsion]
        print(
            f"J = {J} ({torsion}), order {order} ({n_own(r['linkage'])} DoF): tip "
            f"displacement {np.array2string(r['u'], precision=3)}; |u - published| / "
            f"|published| = {100 * relative_error(r['u'], PUBLISHED):.2f} % (Bathe "
            f"& Bolourchi), {100 * relative_error(r['u'], PUBLISHED_SVQ):.2f} % (Simo "
            f"& Vu-Quoc); first call {r['first']:.1f} s, warm {1e3 * r['warm']:.1f} ms"
            f"{tier()}"
        )
    du = results["polar"]["u"] - results["saint-venant"]["u"]
    size = float(np.linalg.norm(results["polar"]["u"]))
    print(
        f"J = 1/6 minus J = 0.1406: {np.array2string(du, precision=3)}; shear "
        f"coefficient k = 1 instead of Cowper's 5/6 moves the tip by "
        f"{shear_effect:.1e} ({shear_effect / size:.1e} of |u|)"
    )
    results["shear_effect"] = shear_effect

    # Load path of the polar model (warm-started; the same compiled solve).
    lk = results["polar"]["linkage"]
    loads = np.linspace(0.0, LOAD, 13)
    path_u, q = [], None
    for p in loads:
        lk_p = padded_bend(results["polar"]["order"], "polar", load=p)
        q = sj.solve_statics(lk_p, q0=q).q
        path_u.append(tip_displacement(lk_p, q))
    path_u = np.array(path_u)

    fig = plt.figure(figsize=(11, 4.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    plot_reference(lk, ax=ax, color="0.75", frames=False)
    plot_configuration(lk, results["polar"]["q"], ax=ax)
    ax.set_title("45-degree bend, tip force 600 along z")
    ax2 = fig.add_subplot(1, 2, 2)
    for i, (name, color) in enumerate(zip("xyz", ("C0", "C1", "C2"), strict=True)):
        ax2.plot(loads, path_u[:, i], "-", color=color, label=f"u_{name}, J = 1/6")
        ax2.plot(
            [LOAD], [results["saint-venant"]["u"][i]], "s", mfc="none", color=color
        )
        ax2.plot([LOAD], [PUBLISHED[i]], "kx")
    ax2.plot([], [], "ks", mfc="none", label="J = 0.1406 (Saint-Venant)")
    ax2.plot([], [], "kx", label="Bathe & Bolourchi 1979")
    ax2.set_xlabel("tip force")
    ax2.set_ylabel("tip displacement")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return results


if __name__ == "__main__":
    main()
