"""The SoRoSim manual's hybrid closed-chain example: statics and dynamics.

The scene (``sorojax.scenes.manual_hybrid``, 17 DoF): a rigid bar on a revolute
joint about z, a two-division soft rod on its tip, and a triangular loop (rigid
cross bar + two soft rods whose tips are welded by a fixed closed-loop joint; links
3-5 are our choice, the manual does not give them), gravity along -y, a 5 N follower
force at the end of link 5. Inputs: the revolute angle (prescribed; its torque is
solved for) and the tension of an oblique cable through links 2 and 4 (> 0 pulls;
the manual's -50 N is our +50 N).

Statics (manual section 3.4): angle -pi/4 and 50 N, from the assembled straight
configuration q = 0 with automatic load stepping; prints tip positions, the closure
error, the revolute torque and the tension. Dynamics: from the rest equilibrium
(angle 0, no tension) the revolute follows pi t / 2 while the tension ramps smoothly
to 50 N over the first second; prints the step counts, the largest closure error
along the motion and the torque. Writes a PNG (equilibrium, snapshots, torque);
``--video`` also writes an animation (mp4, or GIF without ffmpeg).

The first run compiles the statics and the dynamics of this closed-loop model; the
dynamics' programs are traced first and compiled in a worker thread while the
statics compile and run (``sorojax.prepare``): 12.5-14.5 s in all on a 2-core CPU
against 14.8-18.0 s without (six interleaved pairs). The compiled programs
are kept in JAX's persistent cache (``sorojax.enable_compilation_cache``), so a
second run takes about 10 s (the traces are not cached).

Run::

    python examples/manual_hybrid.py [--t1 2] [--video] [--out DIR]
"""

import argparse
import math
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import (  # noqa: E402
    MANUAL_HYBRID_TENSION,
    manual_hybrid,
    manual_hybrid_inputs,
)
from sorojax.viz import (  # noqa: E402
    animate,
    plot_cables,
    plot_configuration,
    plot_reference,
)

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

ANGLE = -math.pi / 4  # statics: revolute angle [rad]
TENSION = MANUAL_HYBRID_TENSION  # cable tension [N] (statics; end of the ramp)
# dynamics inputs at t: revolute angle pi t / 2, tension ramped over 1 s
inputs = manual_hybrid_inputs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t1", type=float, default=2.0, help="simulated time [s]")
    ap.add_argument("--out", default=".", help="folder for the figures")
    ap.add_argument("--video", action="store_true", help="also write an animation")
    ap.add_argument("--overwrite", action="store_true", help="replace old outputs")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "manual_hybrid.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    linkage = manual_hybrid()
    q_ref = jnp.zeros(linkage.n_dof)  # assembled: the rods start straight
    print(
        f"ndof {linkage.n_dof}, inputs {linkage.n_inputs} (angle, tension), "
        f"closure rows {linkage.n_constraints}"
    )

    # The dynamics' programs (below) compile in a worker thread while the statics
    # run: prepare takes the call's arguments (values aside) and compiles nothing
    # twice. rtol 1e-6: the loop's Baumgarte drift follows the integration error
    # (the test bounds it by 1e-6); at this rtol "auto" takes Tsit5 (named here, as
    # prepare cannot know the statics' solution that "auto" would look at).
    dynamics = dict(u=inputs, n_save=41, rtol=1e-6, atol=1e-8, solver="tsit5")
    sj.prepare(sj.simulate, linkage, args.t1, q_ref, **dynamics)

    # ------------------------------------------------------------------ statics
    t0 = time.perf_counter()
    sol = sj.solve_statics(linkage, q_ref, u=jnp.array([ANGLE, TENSION]))
    wall = time.perf_counter() - t0
    print(
        f"statics at angle {ANGLE:.4f} rad, tension {TENSION:g} N: "
        f"{'converged' if sol.result == sj.RESULTS.successful else sol.result}, "
        f"{int(sol.num_steps)} Newton iterations, residual "
        f"{float(sol.residual_norm):.1e} ({wall:.1f} s incl. compile)"
    )
    for link in (2, 4, 5):
        tip = np.asarray(sj.tip_pose(linkage, sol.q, link))[:3, 3]
        print(f"  tip of link {link} [m]: {np.array2string(tip, precision=4)}")
    print(
        f"  closure error {float(sol.constraint_error):.1e} (rank "
        f"{int(sol.constraint_rank)}), revolute torque "
        f"{float(sol.efforts[0]):.4f} N m, cable tension {TENSION:g} N (cable "
        f"length {float(sj.cable_lengths(linkage, q_ref)[0]):.4f} -> "
        f"{float(sj.cable_lengths(linkage, sol.q)[0]):.4f} m)"
    )

    # ----------------------------------------------------------------- dynamics
    rest = sj.solve_statics(linkage, q_ref, u=jnp.zeros(2))
    t0 = time.perf_counter()
    # throw=False: the call returns while the integration runs (JAX dispatches it
    # asynchronously), so the closure errors' program compiles meanwhile.
    traj = sj.simulate(linkage, args.t1, rest.q, throw=False, **dynamics)
    closure = traj.closure_errors(linkage)
    jax.block_until_ready(traj.q)
    wall = time.perf_counter() - t0
    if traj.result != sj.RESULTS.successful:
        raise RuntimeError(f"the dynamics failed: {traj.result}")
    err = np.asarray(closure)
    # host copies for the printout and the figure (indexing JAX arrays runs eager
    # operations, each compiled on its first use)
    ts, qs = np.asarray(traj.t), np.asarray(traj.q)
    print(
        f"dynamics over {args.t1:g} s, solver {traj.solver}: {int(traj.num_steps)} "
        f"steps ({int(traj.num_rejected_steps)} rejected), {wall:.1f} s incl. "
        f"compile; largest closure error {np.abs(err).max():.1e}"
    )
    tip = np.asarray(sj.tip_pose(linkage, qs[-1], 5))[:3, 3]
    # the efforts' program compiles in a worker thread: waited for last
    efforts = np.asarray(traj.efforts)
    print(
        f"  at t1: angle {qs[-1, 0]:.4f} rad, revolute torque "
        f"{efforts[-1, 0]:.4f} N m, tip of link 5 "
        f"{np.array2string(tip, precision=4)} m"
    )

    # ------------------------------------------------------------------- figure
    fig = plt.figure(figsize=(16, 5))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.computed_zorder = False  # draw the cable (inside the rods) over them
    plot_reference(linkage, ax=ax, color="0.8", frames=False, n_circle=10)
    plot_configuration(linkage, sol.q, ax=ax, n_circle=10)
    plot_cables(linkage, sol.q, ax, color="r")
    ax.set_title(f"statics: angle -pi/4, {TENSION:g} N (reference grey)")
    ax = fig.add_subplot(1, 3, 2, projection="3d")
    picks = np.linspace(0, len(ts) - 1, 5).astype(int)
    shades = plt.cm.viridis(np.linspace(0, 0.9, len(picks)))
    for k, c in zip(picks, shades, strict=True):
        plot_configuration(linkage, qs[k], ax=ax, color=c, n_circle=8)
    ax.set_title("dynamics: t = " + ", ".join(f"{ts[k]:.2f}" for k in picks))
    ax = fig.add_subplot(1, 3, 3)
    ax.plot(ts, efforts[:, 0], label="revolute torque [N m]")
    ax.plot(ts, np.asarray(traj.u)[:, 1] / 10, label="tension / 10 [N]")
    ax.set_xlabel("t [s]")
    ax.set_title("dynamics: inputs and solved torque")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout(w_pad=3)
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    if args.video:
        video = animate(
            linkage, traj, out / "manual_hybrid.mp4", fps=20, overwrite=args.overwrite
        )
        print(f"wrote {video}")
    return sol, traj


if __name__ == "__main__":
    main()
