"""Closed-chain mechanisms with a prescribed crank: four-bar and slider-crank.

Both mechanisms (``sorojax._mechanisms``: rigid 2 x 2 cm bars in the x-y plane,
revolute joints about z, the loop closed by a ``ClosedLoopJoint``) have the crank angle
as their input (``JointActuator(1, prescribed=True)``), so the solvers return the crank
torque as the joint effort.

1. **Statics under gravity**: a sweep of crank angles (each solve started 0.02 off
   the analytic assembly, one compiled solve per mechanism); the loop residual and
   the equilibrium residual stay at Newton's tolerance and the crank torque is the
   gravity torque (the derivative of the potential along the one-dof motion;
   checked against virtual work in tests/test_examples_actuated.py).
2. **Dynamics**: the crank driven at theta(t) = omega t (default one revolution per
   second) from the assembled configuration; the loop is held by Baumgarte
   stabilisation. Plots: constraint drift (max |closure error| over the rows), the
   crank torque (effort) against the crank angle next to the static torque, and
   the slider position against the textbook formula x = r cos(theta) +
   sqrt(l^2 - r^2 sin(theta)^2).

Run::

    python examples/mechanisms.py [--t1 3] [--omega 6.283] [--video] [--out DIR]

``--video`` also writes each driven mechanism as ``NAME.mp4`` (a GIF without ffmpeg),
seen from +z.
"""

import argparse
import math
import pathlib

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import (  # noqa: E402
    SLIDER_CRANK,
    four_bar,
    four_bar_assemble,
    slider_crank,
    slider_crank_assemble,
    slider_crank_position,
)
from sorojax.viz import animate  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

MECHANISMS = {
    "four_bar": (four_bar, four_bar_assemble),
    "slider_crank": (slider_crank, slider_crank_assemble),
}


def statics_sweep(linkage, assemble, angles, offset=0.02):
    """Equilibria under gravity at the crank ``angles``.

    Each solve starts ``offset`` (rad, m) off the analytic assembly in every
    coordinate, so that Newton has to re-close the loop (with closed loops the start
    must be near an assembled configuration).

    Returns a dict of arrays: angles, q, crank torque, equilibrium residual,
    constraint error, Newton iterations, constraint rank.
    """
    out = {k: [] for k in ("q", "torque", "residual", "constraint_error", "steps")}
    rank = None
    for th in angles:
        q0 = assemble(float(th)) + offset
        # host arrays in and out: no eager JAX operation (each compiles a small
        # program on first use, which waits while a prepared compile runs)
        sol = sj.solve_statics(linkage, q0, u=np.array([th]))
        out["q"].append(np.asarray(sol.q))
        out["torque"].append(float(np.asarray(sol.efforts)[0]))
        out["residual"].append(float(sol.residual_norm))
        out["constraint_error"].append(float(sol.constraint_error))
        out["steps"].append(int(sol.num_steps))
        rank = int(sol.constraint_rank)
    res = {k: np.asarray(v) for k, v in out.items()}
    res["angles"] = np.asarray(angles)
    res["constraint_rank"] = rank
    return res


def crank_angle(omega, t):
    """The prescribed crank angle ``omega t`` [rad] as the input vector."""
    return jnp.stack([omega * t])


def driven_arguments(linkage, assemble, omega, t1, rtol, n_save):
    """``simulate``'s arguments: the crank driven at ``omega`` [rad/s] from theta = 0.

    The input is one ``equinox.Partial`` of a module-level function: equal for both
    mechanisms, so (with their joints' directions as arrays) the slider-crank
    reuses the four-bar's compiled integration (a new lambda per call would be a
    new program).
    """
    u = eqx.Partial(crank_angle, omega)
    kwargs = dict(u=u, rtol=rtol, atol=rtol * 1e-2, n_save=n_save)
    return (linkage, t1, assemble(0.0)), kwargs


def driven(linkage, assemble, omega, t1, rtol, n_save):
    """Simulate the crank driven at ``omega`` [rad/s] for ``t1`` s from theta = 0."""
    call, kwargs = driven_arguments(linkage, assemble, omega, t1, rtol, n_save)
    traj = sj.simulate(*call, **kwargs)
    e = traj.closure_errors(linkage)
    drift = np.abs(np.asarray(e)).max(axis=1)
    return traj, drift


def joint_points(linkage, q):
    """World (x, y) of the base and tip of every link at ``q`` (for drawing)."""
    pts = []
    for i in range(1, linkage.n_links + 1):
        tip = np.asarray(sj.tip_pose(linkage, q, i))[:2, 3]
        length = float(linkage.links[i - 1].length)
        R = np.asarray(sj.tip_pose(linkage, q, i))[:2, :2]
        pts.append((tip - R[:, 0] * length, tip))
    return pts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t1", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument(
        "--omega", type=float, default=2 * math.pi, help="crank speed [rad/s]"
    )
    ap.add_argument("--rtol", type=float, default=1e-8, help="integrator rtol")
    ap.add_argument("--n-save", type=int, default=301, help="saved instants")
    ap.add_argument("--n-angles", type=int, default=24, help="statics crank angles")
    ap.add_argument(
        "--only", choices=sorted(MECHANISMS), default=None, help="one mechanism"
    )
    ap.add_argument("--statics-only", action="store_true", help="skip the dynamics")
    ap.add_argument("--out", default=".", help="folder for the outputs")
    ap.add_argument("--video", action="store_true", help="also write animations")
    ap.add_argument("--overwrite", action="store_true", help="replace old outputs")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "mechanisms.png"
    names = [args.only] if args.only else list(MECHANISMS)
    with_video = args.video and not args.statics_only
    videos = {n: out / f"{n}.mp4" for n in names} if with_video else {}
    outputs = [path] + [p for v in videos.values() for p in (v, v.with_suffix(".gif"))]
    for p in outputs:
        if p.exists() and not args.overwrite:
            raise SystemExit(f"{p} exists; pass --overwrite to replace it")

    angles = np.linspace(0.0, 2 * math.pi, args.n_angles, endpoint=False)
    results = {}
    linkages = {name: MECHANISMS[name][0]() for name in names}
    if not args.statics_only:
        # The integration's programs (one for both mechanisms) compile in a worker
        # thread while the statics run: the same arguments as the later call.
        first = names[0]
        # The statics' program first (traced and lowered here, compiled in the
        # worker): its lowering runs one small eager compile, which waits while a
        # compile already runs in the worker. Only the arguments' shapes matter.
        q_start = MECHANISMS[first][1](0.0)
        sj.prepare(sj.solve_statics, linkages[first], q_start, u=np.array([0.0]))
        call, kwargs = driven_arguments(
            linkages[first], MECHANISMS[first][1], args.omega, args.t1, args.rtol,
            args.n_save,
        )  # fmt: skip
        sj.prepare(sj.simulate, *call, **kwargs)
    for name in names:
        _, assemble = MECHANISMS[name]
        linkage = linkages[name]
        st = statics_sweep(linkage, assemble, angles)
        print(
            f"{name}: statics at {len(angles)} crank angles, max residual "
            f"{st['residual'].max():.1e}, max loop error "
            f"{st['constraint_error'].max():.1e}, rank {st['constraint_rank']} of "
            f"{linkage.n_constraints} rows; gravity torque "
            f"{st['torque'].min():+.4f} .. {st['torque'].max():+.4f} N m"
        )
        res = {"linkage": linkage, "statics": st}
        if not args.statics_only:
            traj, drift = driven(
                linkage, assemble, args.omega, args.t1, args.rtol, args.n_save
            )
            res |= {"traj": traj, "drift": drift}
            tau = np.asarray(traj.efforts)[:, 0]
            print(
                f"{name}: {args.t1} s at {args.omega:.3f} rad/s, "
                f"{int(traj.num_steps)} steps, max drift {drift.max():.1e}, "
                f"crank torque {tau.min():+.4f} .. {tau.max():+.4f} N m"
            )
            if name == "slider_crank":
                q = np.asarray(traj.q)
                theta, x = q[:, 0], q[:, 2] + SLIDER_CRANK["slider"] / 2
                x_ref = slider_crank_position(theta)
                res |= {"slider_x": x, "slider_x_ref": x_ref}
                print(f"slider: max |x - formula| = {np.abs(x - x_ref).max():.1e} m")
        results[name] = res

    _plot(results, args, path)
    print(f"wrote {path}")
    for name, video in videos.items():
        lk, traj = results[name]["linkage"], results[name]["traj"]
        written = animate(
            lk, traj, video, fps=20, view=(90, -90), overwrite=args.overwrite
        )
        print(f"wrote {written}")
    return results


def _plot(results, args, path):
    dyn = not args.statics_only
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    ax = axes[0, 0]
    colors = {"four_bar": "tab:blue", "slider_crank": "tab:orange"}
    shift = {"four_bar": 0.0, "slider_crank": -0.3}  # draw the two apart
    for name, res in results.items():
        lk, st = res["linkage"], res["statics"]
        picks = np.unique(np.linspace(0, len(st["angles"]) - 1, 4).astype(int))
        for j, k in enumerate(picks):
            alpha = 0.3 + 0.7 * j / max(1, len(picks) - 1)
            for a, b in joint_points(lk, st["q"][k]):
                ax.plot(
                    [a[0], b[0]],
                    [a[1] + shift[name], b[1] + shift[name]],
                    "-o",
                    color=colors[name],
                    alpha=alpha,
                    ms=3,
                )
        ax.text(-0.1, shift[name] + 0.15, name, color=colors[name])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m] (slider-crank drawn 0.3 m lower)")
    ax.set_title("static equilibria at four crank angles")
    ax.grid(alpha=0.3)

    ax = axes[0, 1]
    for name, res in results.items():
        st = res["statics"]
        ax.plot(
            st["angles"],
            st["torque"],
            "o",
            color=colors[name],
            ms=4,
            label=f"{name}: statics (gravity)",
        )
        if dyn:
            tr = res["traj"]
            th = np.mod(np.asarray(tr.q)[:, 0], 2 * math.pi)
            order = np.argsort(th)
            ax.plot(
                th[order],
                np.asarray(tr.efforts)[:, 0][order],
                "-",
                color=colors[name],
                lw=1,
                label=f"{name}: driven at {args.omega:.2f} rad/s",
            )
    ax.set_xlabel("crank angle [rad]")
    ax.set_ylabel("crank torque [N m]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)

    ax = axes[1, 0]
    if dyn:
        for name, res in results.items():
            t = np.asarray(res["traj"].t)
            ax.semilogy(
                t, np.maximum(res["drift"], 1e-16), color=colors[name], label=name
            )
        ax.axhline(1e-6, color="k", ls="--", lw=0.8, label="1e-6")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("max |closure error| [rad, m]")
        ax.set_title("constraint drift (Baumgarte)")
        ax.legend(fontsize=8)
    else:
        for name, res in results.items():
            st = res["statics"]
            ax.semilogy(
                st["angles"],
                np.maximum(st["constraint_error"], 1e-18),
                "o",
                color=colors[name],
                label=f"{name}: loop error",
            )
            ax.semilogy(
                st["angles"],
                np.maximum(st["residual"], 1e-18),
                "x",
                color=colors[name],
                label=f"{name}: residual",
            )
        ax.set_xlabel("crank angle [rad]")
        ax.set_title("statics residuals")
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)

    ax = axes[1, 1]
    sc = results.get("slider_crank")
    if dyn and sc is not None:
        t = np.asarray(sc["traj"].t)
        ax.plot(t, sc["slider_x"], "-", label="simulated pin x")
        ax.plot(t, sc["slider_x_ref"], "--", label="r cos + sqrt(l^2 - r^2 sin^2)")
        tw = ax.twinx()
        tw.semilogy(
            t,
            np.maximum(np.abs(sc["slider_x"] - sc["slider_x_ref"]), 1e-18),
            color="tab:red",
            lw=0.8,
        )
        tw.set_ylabel("|difference| [m]", color="tab:red")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("slider pin x [m]")
        ax.legend(fontsize=8, loc="lower left")
        ax.set_title("slider position vs the slider-crank formula")
    else:
        ax.set_axis_off()
    fig.suptitle("prescribed-crank mechanisms: statics and driven dynamics")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
