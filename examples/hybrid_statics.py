"""Statics of the built-in hybrid scene, and a design gradient through the solve.

The scene (``sorojax.scenes.demo_linkage``): a rigid bar on a sprung revolute joint
(about z) carrying a two-division soft rod, gravity along -y, a 0.5 N follower force at
the soft tip. Solves the equilibrium, prints the tip position, and takes the gradient
of the tip height with respect to the joint stiffness and the rod's Young's modulus by
the implicit function theorem (no finite differences): one compiled program gives
the equilibrium, its poses and the derivatives (``jax.grad`` with ``has_aux``).
Writes a PNG of the configuration next to the reference shape.

Run::

    python examples/hybrid_statics.py [--out DIR]
"""

import argparse
import pathlib

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")

import sorojax as sj  # noqa: E402
from sorojax.scenes import demo_linkage  # noqa: E402
from sorojax.viz import plot_configuration, plot_reference  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "hybrid_statics.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    linkage = demo_linkage()
    tip = linkage.tip_point(linkage.n_links)

    def tip_height(params):
        """Tip height at the equilibrium for (joint stiffness, E).

        As aux: the solution and the poses (equilibrium, reference) for the figure.
        """
        k, E = params
        lk = eqx.tree_at(
            lambda l: (l.links[0].joint.stiffness, l.links[1].material.E),
            linkage,
            (k, E),
        )
        # throw=False: under jit, throw=True would add a host callback (the error
        # check), which keeps the program out of the persistent cache; the result
        # code is checked below
        sol = sj.solve_statics(lk, throw=False)
        g = sj.forward_kinematics(lk, sol.q)
        g0 = sj.forward_kinematics(lk, jnp.zeros(lk.n_dof))
        return g[tip, 1, 3], (sol, g, g0)

    k0 = linkage.links[0].joint.stiffness
    E0 = linkage.links[1].material.E
    # One program gives the equilibrium, the poses and the derivatives (the
    # implicit function theorem at the solution), compiled as sorojax compiles its
    # own: sorojax.jit (XLA options and compile tiers; run once, so at -O0).
    run = sj.jit(jax.grad(tip_height, has_aux=True))
    (dk, dE), (sol, g, g0) = run((k0, E0))
    if sol.result != sj.RESULTS.successful:
        raise RuntimeError(f"statics failed: {sol.result}")
    print(f"ndof {linkage.n_dof}, {int(sol.num_steps)} Newton iterations")
    print(f"tip position [m]: {np.asarray(g[tip, :3, 3])}")
    print(f"d(tip y)/d(joint stiffness) = {float(dk.squeeze()):.4e} m per N m/rad")
    print(f"d(tip y)/d(E)               = {float(dE):.4e} m per Pa")

    fig, ax = plot_reference(linkage, color="0.75", frames=False, poses=g0)
    plot_configuration(linkage, sol.q, ax=ax, poses=g)
    ax.set_title("hybrid scene: reference (grey) and equilibrium")
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return sol, (dk, dE)


if __name__ == "__main__":
    main()
