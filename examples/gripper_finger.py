"""A tendon-driven gripper finger: rigid phalanges, soft hinges, a cable outside.

The scene (``sorojax.scenes.gripper_finger``): three rigid phalanges (45, 30, 25 mm)
joined to the ground and to each other by 10 mm soft hinges (E 1 MPa, bending about
z, 3 DoF in all), palm down under gravity. One tendon runs outside the body on the
palm side, from a ground pulley through two eyelets on each phalanx (a chain of
``CableAnchor`` s; straight segments between them). Solves the statics for a range
of tensions (each solve warm-started from the previous one; the tension is an input
array, so all solves share one compiled program), prints the curl and the fingertip
position, and writes a PNG of the curling finger with its tendon and of the curl
against the tension.

Run::

    python examples/gripper_finger.py [--t-max 8] [--n 9] [--out DIR]
"""

import argparse
import pathlib

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import finger_curl, gripper_finger  # noqa: E402
from sorojax.viz import plot_cables, plot_configuration  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-max", type=float, default=8.0, help="largest tension [N]")
    ap.add_argument("--n", type=int, default=9, help="number of tensions from 0")
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "gripper_finger.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    finger = gripper_finger()
    tensions = np.linspace(0.0, args.t_max, args.n)
    q = jnp.zeros(finger.n_dof)
    qs, curls = [], []
    print(
        f"ndof {finger.n_dof}; tendon length at rest "
        f"{1000 * float(sj.cable_lengths(finger, q)[0]):.2f} mm"
    )
    for T in tensions:
        sol = sj.solve_statics(finger, q0=q, u=jnp.array([T]))
        q = sol.q
        qs.append(np.asarray(q))
        curls.append(finger_curl(finger, q))
        tip = np.asarray(sj.tip_pose(finger, q))[:3, 3]
        print(
            f"T = {T:5.2f} N: curl {np.degrees(curls[-1]):7.2f} deg, fingertip "
            f"({1000 * tip[0]:6.1f}, {1000 * tip[1]:6.1f}) mm, "
            f"{int(sol.num_steps)} Newton iterations"
        )
    qs, curls = np.stack(qs), np.asarray(curls)

    fig = plt.figure(figsize=(11, 4.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(tensions)))
    for k in range(0, len(tensions), max(1, len(tensions) // 4)):
        plot_configuration(finger, qs[k], ax=ax, color=colors[k], n_circle=8)
        plot_cables(finger, qs[k], ax, color="k", linewidth=1.0)
    ax.set_proj_type("ortho")
    ax.view_init(elev=90, azim=-90)
    ax.set_zticks([])
    ax.set_zlabel("")
    ax.set_title("finger and tendon (top view, several tensions)")
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.plot(tensions, np.degrees(curls), "o-")
    ax2.set_xlabel("tendon tension [N]")
    ax2.set_ylabel("curl of the fingertip [deg]")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return tensions, qs, curls


if __name__ == "__main__":
    main()
