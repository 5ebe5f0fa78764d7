"""Dynamics of SoRoSim's free-fall rod: simulate, check the energy, plot, animate.

The rod of SoRoSim's dynamics tutorial (``sorojax.scenes.free_fall_rod``): 0.5 m,
radius 2 -> 1 cm, E 1 MPa, torsion and both bendings with cubic Legendre strain
(12 DoF), clamped, pre-bent 1 rad/m about y and released under gravity (-z), with
Kelvin-Voigt damping eta = 1e4 Pa s. Simulates ``--t1`` seconds with the default
solver, prints the step statistics and the energy lost, and writes a time-series PNG
(tip position and energies); with ``--video`` also an animation (mp4, or GIF when
ffmpeg is missing). Existing files are never overwritten (pass ``--overwrite``).

Run::

    python examples/free_fall_dynamics.py [--t1 5] [--video] [--out DIR]
"""

import argparse
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")

import sorojax as sj  # noqa: E402
from sorojax.scenes import free_fall_q0, free_fall_rod  # noqa: E402
from sorojax.viz import animate, plot_time_series  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t1", type=float, default=5.0, help="simulated time [s]")
    ap.add_argument("--out", default=".", help="folder for the figures")
    ap.add_argument("--video", action="store_true", help="also write an animation")
    ap.add_argument("--overwrite", action="store_true", help="replace old outputs")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "free_fall_dynamics.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    rod = free_fall_rod(order=3, eta=1e4)
    q0 = free_fall_q0(rod)
    t0 = time.perf_counter()
    traj = sj.simulate(rod, args.t1, q0, n_save=201)
    jax.block_until_ready(traj.q)
    wall = time.perf_counter() - t0
    E = np.asarray(traj.energies(rod))[:, 3]  # total; the plot below reuses it
    print(
        f"ndof {rod.n_dof}, solver {traj.solver}: {int(traj.num_steps)} steps "
        f"({int(traj.num_rejected_steps)} rejected), {wall:.2f} s incl. compile"
    )
    print(f"tip at t1 [m]: {np.asarray(traj.tip_positions(rod)[-1])}")
    print(
        f"energy {E[0]:.4f} J -> {E[-1]:.4f} J (never rising: {np.diff(E).max():.1e})"
    )

    fig = plot_time_series(traj, rod, quantities=("tip", "energy"))
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    if args.video:
        video = animate(
            rod, traj, out / "free_fall.mp4", fps=20, overwrite=args.overwrite
        )
        print(f"wrote {video}")
    return traj


if __name__ == "__main__":
    main()
