"""A batched, differentiable parameter sweep: large-deflection cantilevers under vmap.

A clamped rod (1 m, r 1 cm, E 10 MPa, planar bending about z, inextensible and
shearless) carries a dead transverse tip load with P L^2 / (E I) from 0.5 to 10. All
loads are solved at once with ``jax.vmap`` over ``solve_statics`` (the same solves
match the elliptic-integral solution of Bisshopp and Drucker to 1e-5 in
tests/test_statics.py), the load-deflection curve is plotted, and the stiffness
dy_tip/dP along the curve comes from ``jax.vmap(jax.grad)`` through the solves
(implicit function theorem).

Run::

    python examples/cantilever_sweep.py [--n 32] [--out DIR]
"""

import argparse
import math
import pathlib

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import cantilever  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

L, R, E = 1.0, 0.01, 1e7
EI = E * math.pi * R**4 / 4


def tip(P):
    """Tip position (x, y) under a +y tip load ``P`` [N] (traced: works under vmap)."""
    rod = cantilever(
        L,
        R,
        E,
        modes=(0, 0, 1, 0, 0, 0),
        order=6,
        tip_wrench=jnp.stack([0.0, 0.0, 0.0, 0.0, P, 0.0]),
    )
    sol = sj.solve_statics(rod, load_steps=4, throw=False)
    return sj.tip_pose(rod, sol.q)[:2, 3]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=32, help="number of loads")
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "cantilever_sweep.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    alpha = np.linspace(0.5, 10.0, args.n)
    P = jnp.asarray(alpha * EI / L**2)

    def y_and_tip(p):
        t = tip(p)
        return t[1], t

    # One program for the tips and their derivatives (the gradient program holds
    # the forward solve anyway: a separate forward program was a second compile),
    # compiled as sorojax compiles its own: sorojax.jit (run once, so at -O0 in
    # the default compile tiers: half the compile; see sorojax.compile_mode).
    dy_and_xy = jax.vmap(jax.grad(y_and_tip, has_aux=True))
    dy, xy = sj.jit(dy_and_xy)(P)
    dy, xy = np.asarray(dy), np.asarray(xy)
    print(f"{args.n} solves; tip y / L from {xy[0, 1]:.4f} to {xy[-1, 1]:.4f}")
    print(f"d(tip y)/dP from {dy[0]:.4e} to {dy[-1]:.4e} m/N (stiffening)")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    a1.plot(alpha, xy[:, 1] / L, "o-", ms=3, label="tip y / L")
    a1.plot(alpha, 1 - xy[:, 0] / L, "s-", ms=3, label="1 - tip x / L")
    a1.set_xlabel("P L^2 / (E I)")
    a1.legend()
    a1.grid(alpha=0.3)
    a2.semilogy(alpha, dy * EI / L**3, "o-", ms=3)
    a2.set_xlabel("P L^2 / (E I)")
    a2.set_ylabel("d(tip y)/dP  [L^3 / (E I)]")
    a2.grid(alpha=0.3)
    fig.suptitle("large-deflection cantilever: vmap over loads, grad through statics")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return alpha, xy, dy


if __name__ == "__main__":
    main()
