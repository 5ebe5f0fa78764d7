"""The scene-file commands of the ``sorojax`` console script.

``sorojax check FILE`` validates a scene file and prints what it holds;
``sorojax statics FILE`` solves its statics (the inputs and settings of its
``[statics]`` table, loads stepped as in :func:`~sorojax.solve_statics`) and writes
the solution (``.npz``) and a figure; ``sorojax simulate FILE`` integrates its
dynamics (``[simulate]``) with a progress bar and writes the trajectory (``.npz``,
as :func:`~sorojax.save_trajectory`), a figure and, with ``--video``, an animation;
``sorojax plot RESULT`` draws a saved solution or trajectory again.

Exit codes: 0 success; 1 the solver or the integration failed (its result code is
printed); 2 bad input (an invalid scene file or argument: the message names the file,
the key, its line and the value); 3 an output file exists (left unchanged: pass
``--overwrite``) or cannot be written.
"""

import argparse
import pathlib
import sys
import time

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_OUTPUT = 0, 1, 2, 3

EPILOG = (
    "exit codes: 0 success; 1 the solver or the integration failed; 2 bad input "
    "(an invalid scene file or argument); 3 an output file exists (pass "
    "--overwrite) or cannot be written."
)


class _Exit(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def add_commands(sub) -> None:
    """Add ``check``, ``statics``, ``simulate`` and ``plot`` to the subparsers."""
    fmt = argparse.RawDescriptionHelpFormatter
    check = sub.add_parser(
        "check",
        help="validate a scene file and print its model",
        description="Read a scene file, build its model and print its degrees of "
        "freedom, links, strain modes, masses, actuators, closed loops and contact.",
        epilog=EPILOG,
        formatter_class=fmt,
    )
    check.add_argument("scene", help="scene file (.toml)")
    statics = sub.add_parser(
        "statics",
        help="solve the statics of a scene file",
        description="Solve the static equilibrium of a scene file with the inputs "
        "and settings of its [statics] table (loads stepped automatically unless it "
        "sets load_steps); print the result, the actuator efforts and the link tip "
        "poses; write the solution (.npz) and a figure (.png).",
        epilog=EPILOG,
        formatter_class=fmt,
    )
    statics.add_argument("scene", help="scene file (.toml)")
    statics.add_argument(
        "-u", type=float, nargs="+", help="actuation inputs (replace [statics] u)"
    )
    statics.add_argument(
        "-o", "--output", help="solution file (.npz; default SCENE-statics.npz here)"
    )
    statics.add_argument(
        "--figure", help="figure (.png; default SCENE-statics.png here; '' for none)"
    )
    statics.add_argument("--overwrite", action="store_true", help="replace outputs")
    simulate = sub.add_parser(
        "simulate",
        help="simulate the dynamics of a scene file",
        description="Integrate the dynamics of a scene file with the settings of "
        "its [simulate] table, from its q0 (default the reference shape); write the "
        "trajectory (.npz, read it with sorojax.load_trajectory), a figure and, "
        "with --video, an animation.",
        epilog=EPILOG,
        formatter_class=fmt,
    )
    simulate.add_argument("scene", help="scene file (.toml)")
    simulate.add_argument(
        "--t1", type=float, help="final time [s] (replaces [simulate] t1)"
    )
    simulate.add_argument(
        "-o", "--output", help="trajectory (.npz; default SCENE-trajectory.npz here)"
    )
    simulate.add_argument(
        "--figure", help="figure (.png; default SCENE-trajectory.png; '' for none)"
    )
    simulate.add_argument(
        "--video",
        nargs="?",
        const="",
        help="also write an animation (default SCENE.mp4, or .gif without ffmpeg)",
    )
    simulate.add_argument("--no-progress", action="store_true", help="no progress bar")
    simulate.add_argument("--overwrite", action="store_true", help="replace outputs")
    plot = sub.add_parser(
        "plot",
        help="draw a saved statics solution or trajectory",
        description="Draw a solution written by `sorojax statics` (it holds its "
        "scene) or a trajectory written by `sorojax simulate` (give its --scene).",
        epilog=EPILOG,
        formatter_class=fmt,
    )
    plot.add_argument("result", help="a .npz written by sorojax statics or simulate")
    plot.add_argument("--scene", help="the scene file of a trajectory")
    plot.add_argument("-o", "--output", help="figure (.png; default RESULT-plot.png)")
    plot.add_argument("--overwrite", action="store_true", help="replace the figure")


def run(args) -> int:
    """Run a scene command; messages of failures go to stderr with the exit code."""
    command = {
        "check": _check,
        "statics": _statics,
        "simulate": _simulate,
        "plot": _plot,
    }[args.command]
    try:
        return command(args)
    except _Exit as err:
        print(f"sorojax {args.command}: {err}", file=sys.stderr)
        return err.code


# ----------------------------------------------------------------- helpers
def _load(path: str):
    import jax

    jax.config.update("jax_enable_x64", True)
    from .io import SceneError, load_scene

    try:
        return load_scene(path)
    except SceneError as err:
        raise _Exit(EXIT_INPUT, str(err)) from None
    except OSError as err:
        raise _Exit(EXIT_INPUT, f"cannot read the scene file: {err}") from None


def _outputs(args, scene_path: str, kinds: dict) -> dict:
    """The output paths (None: not written), refused before any work if they exist."""
    stem = pathlib.Path(scene_path).stem
    out = {}
    for name, (given, default) in kinds.items():
        if given == "":
            out[name] = None
            continue
        path = pathlib.Path(given if given is not None else f"{stem}{default}")
        if path.exists() and not args.overwrite:
            raise _Exit(
                EXIT_OUTPUT,
                f"{path} exists and was left unchanged: pass --overwrite to replace "
                "it, or choose another file name.",
            )
        if not path.parent.is_dir():
            raise _Exit(EXIT_OUTPUT, f"the folder of {path} does not exist.")
        out[name] = path
    return out


def _fail_setting(scene, key: str, message: str):
    from .io._scene import SceneError, _key_lines, _line_of

    lines = _key_lines(scene.path.read_text()) if scene.path else {}
    return SceneError(str(scene.path), key, message, _line_of(lines, key))


def _sized_arguments(scene, table: str) -> dict:
    """The keyword arguments of a scene's ``[statics]`` or ``[simulate]`` table.

    The vectors (``u``, ``q0``, ``qd0``; a function of t is kept) are checked
    against the model's sizes and made arrays.

    Raises:
        SceneError: a vector of the wrong length, at its key and line.
    """
    import jax.numpy as jnp

    lk = scene.linkage
    sizes = {
        "u": (lk.n_inputs, "inputs"),
        "q0": (lk.n_dof, "coordinates"),
        "qd0": (lk.n_dof, "coordinates"),
    }
    kw = dict(getattr(scene, table))
    for key, (n, what) in sizes.items():
        value = kw.get(key)
        if value is None or callable(value):
            continue
        if len(value) != n:
            raise _fail_setting(
                scene,
                f"{table}.{key}",
                f"= {list(value)} has {len(value)} entries: the model has {n} {what}.",
            )
        kw[key] = jnp.asarray(value)
    return kw


def _masses(linkage) -> list[float]:
    """Mass of each link [kg].

    rho A integrated along a rod (Gauss-Legendre), a rigid body's own.
    """
    import numpy as np

    from .model import SoftLink

    x, w = np.polynomial.legendre.leggauss(12)
    X1 = 0.5 * (x + 1)
    out = []
    for link in linkage.links:
        if isinstance(link, SoftLink):
            m = 0.0
            for d in link.divisions:
                A = np.array([float(d.section.properties(s)[0]) for s in X1])
                m += float(link.material.rho) * float(d.length) * 0.5 * float(w @ A)
            out.append(m)
        else:
            out.append(float(link.spatial_inertia()[3, 3]))
    return out


def _describe(scene) -> list[str]:
    from .model import Cable, JointActuator, SoftLink
    from .model._basis import MODE_NAMES

    lk = scene.linkage
    lines = []
    if scene.description:
        lines.append(f"  {scene.description}")
    lines.append(
        f"  {lk.n_links} links, ndof = {lk.n_dof}, significant points = "
        f"{lk.n_points}, inputs = {lk.n_inputs}"
    )
    masses = _masses(lk)
    for i, (link, parent, m) in enumerate(
        zip(lk.links, lk.parents, masses, strict=True), start=1
    ):
        joint = link.joint.kind
        if isinstance(link, SoftLink):
            divs = []
            for d in link.divisions:
                basis = d.basis
                modes = getattr(basis, "modes", None)
                if modes is None:
                    divs.append(f"{d.n_dof} dof (custom basis)")
                    continue
                names = ", ".join(
                    f"{name} ({order})"
                    for name, on, order in zip(
                        MODE_NAMES, modes, basis.orders, strict=True
                    )
                    if on
                )
                divs.append(
                    f"{float(d.length):.4g} m, modes (order) {names}: {d.n_dof} dof"
                )
            body = f"soft, {len(divs)} division(s): " + "; ".join(divs)
        else:
            body = f"rigid, length {float(link.length):.4g} m"
        lines.append(
            f"  link {i}: {body}; joint {joint} ({link.joint.n_dof} dof), parent "
            f"{parent}, mass {m:.4g} kg"
        )
    lines.append(f"  total mass {sum(masses):.4g} kg")
    for k, (a, sl) in enumerate(zip(lk.actuators, lk.input_slices, strict=True)):
        if isinstance(a, JointActuator):
            kind = "prescribed coordinates" if a.prescribed else "joint forces"
            text = f"joint actuator on link {a.link} ({kind})"
        elif isinstance(a, Cable):
            text = (
                f"cable {a.name!r} ({len(a.route)} route element(s); tension, "
                "> 0 pulls)"
            )
        else:  # pragma: no cover
            text = type(a).__name__
        lines.append(f"  actuator {k + 1}: {text}, u[{sl.start}:{sl.stop}]")
    for k, c in enumerate(lk.closed_loops, start=1):
        lines.append(
            f"  closed loop {k}: joint {c.kind} between link {c.link_A} and "
            f"{'ground' if c.link_B == 0 else f'link {c.link_B}'} "
            f"({c.n_constraints} constraints)"
        )
    if lk.contact is not None:
        c = lk.contact
        names = ", ".join(type(o).__name__.lower() for o in c.obstacles) or "none"
        samples = sum(sum(cells) for _, cells in c.cells)
        lines.append(
            f"  contact: obstacles {names}; {c.law.kind} law, k = "
            f"{float(c.law.stiffness):.3g}; {samples} sample cells"
            + (f"; rod pairs {list(c.rod_pairs)}" if c.rod_pairs else "")
            + (f"; self-contact {list(c.self_contact)}" if c.self_contact else "")
            + (f"; inside {list(c.inside)}" if c.inside else "")
        )
    g = [float(x) for x in lk.gravity]
    lines.append(f"  gravity {g} m/s^2, point wrenches {len(lk.point_wrenches)}")
    for key in ("statics", "simulate"):
        settings = getattr(scene, key)
        if settings:
            shown = ", ".join(f"{k} = {_short(v)}" for k, v in settings.items())
            lines.append(f"  [{key}] {shown}")
    return lines


def _short(v) -> str:
    import numpy as np

    if hasattr(v, "shape"):
        return np.array2string(np.asarray(v), precision=4, separator=", ")
    if callable(v):
        fn = getattr(v, "func", v)  # an equinox.Partial: its function and arguments
        args = [_short(a) for a in getattr(v, "args", ())]
        args += [f"{k}={_short(a)}" for k, a in getattr(v, "keywords", {}).items()]
        name = getattr(fn, "__name__", type(fn).__name__)
        return f"{name}({', '.join(args)})" if fn is not v else name
    return repr(v)


# ----------------------------------------------------------------- commands
def _check(args) -> int:
    scene = _load(args.scene)
    print(f"sorojax check: {args.scene} is a valid scene")
    for line in _describe(scene):
        print(line)
    return EXIT_OK


def _statics(args) -> int:
    scene = _load(args.scene)
    from .io import SceneError

    try:
        kw = _sized_arguments(scene, "statics")
    except SceneError as err:
        raise _Exit(EXIT_INPUT, str(err)) from None
    lk = scene.linkage
    if args.u is not None:
        if len(args.u) != lk.n_inputs:
            raise _Exit(
                EXIT_INPUT,
                f"-u {' '.join(map(str, args.u))}: {len(args.u)} values for a model "
                f"with {lk.n_inputs} inputs.",
            )
        import jax.numpy as jnp

        kw["u"] = jnp.asarray(args.u)
    out = _outputs(
        args,
        args.scene,
        {
            "solution": (args.output, "-statics.npz"),
            "figure": (args.figure, "-statics.png"),
        },
    )
    import jax
    import numpy as np

    from . import RESULTS, enable_compilation_cache, solve_statics
    from .kinematics import forward_kinematics

    enable_compilation_cache()
    t0 = time.perf_counter()
    sol = solve_statics(lk, throw=False, **kw)
    g = np.asarray(forward_kinematics(lk, sol.q))
    jax.block_until_ready(sol.q)
    wall = time.perf_counter() - t0
    ok = sol.result == RESULTS.successful
    np.set_printoptions(precision=6, suppress=True)
    print(f"sorojax statics: {args.scene} (ndof {lk.n_dof})")
    print(
        f"  {'converged' if ok else 'FAILED: ' + str(sol.result)}, "
        f"{int(sol.num_steps)} Newton iterations, residual "
        f"{float(sol.residual_norm):.2e}, {wall:.2f} s (compile included)"
    )
    print(
        f"  equilibrium {'stable' if bool(sol.stable) else 'UNSTABLE'} (smallest "
        f"tangent-stiffness eigenvalue {float(sol.min_eigenvalue):.3g})"
    )
    efforts = None if sol.efforts is None else np.asarray(sol.efforts)
    if efforts is not None and efforts.size:
        print(f"  prescribed-joint efforts [N m or N] = {efforts}")
    if lk.closed_loops:
        print(f"  closure error {float(sol.constraint_error):.2e}")
    tips = np.stack([g[lk.tip_point(i)] for i in range(1, lk.n_links + 1)])
    for i, tip in enumerate(tips, start=1):
        print(f"  tip of link {i} [m]: {tip[:3, 3]}")
    print(f"  q = {np.asarray(sol.q)}")
    if out["solution"] is not None:
        from .io._files import writing

        arrays = {
            "q": np.asarray(sol.q),
            "result": np.asarray(sol.result._value),
            "num_steps": np.asarray(sol.num_steps),
            "residual_norm": np.asarray(sol.residual_norm),
            "tips": tips,
            "u": np.asarray(kw.get("u", np.zeros(lk.n_inputs))),
            "scene": np.asarray(pathlib.Path(args.scene).read_text()),
        }
        if efforts is not None:
            arrays["efforts"] = efforts
        if sol.lam is not None:
            arrays["lam"] = np.asarray(sol.lam)
        with writing(out["solution"], args.overwrite) as tmp:
            np.savez(tmp, **arrays)
        print(f"  solution written to {out['solution']}")
    if out["figure"] is not None:
        fig = _statics_figure(lk, np.asarray(sol.q), g, pathlib.Path(args.scene).name)
        _save_figure(fig, out["figure"], args.overwrite)
        print(f"  figure written to {out['figure']}")
    return EXIT_OK if ok else EXIT_FAILED


def _statics_figure(lk, q, g, title):
    import matplotlib

    matplotlib.use("Agg")
    from .viz import plot_cables, plot_configuration, plot_reference

    fig, ax = plot_reference(lk, color="0.8", frames=False, n_circle=10)
    plot_configuration(lk, q, ax=ax, poses=g, n_circle=10)
    if any(type(a).__name__ == "Cable" for a in lk.actuators):
        plot_cables(lk, q, ax, color="r")
    ax.set_title(f"{title}: static equilibrium (reference grey)")
    return fig


def _save_figure(fig, path, overwrite):
    from .io._files import writing

    with writing(path, overwrite) as tmp:
        fig.savefig(tmp, dpi=110)


def _simulate(args) -> int:
    scene = _load(args.scene)
    lk = scene.linkage
    from .io import SceneError

    try:
        kw = _sized_arguments(scene, "simulate")
    except SceneError as err:
        raise _Exit(EXIT_INPUT, str(err)) from None
    t1 = kw.pop("t1", 1.0) if args.t1 is None else args.t1
    kw.pop("t1", None)
    if not t1 > 0:
        raise _Exit(EXIT_INPUT, f"--t1 {t1}: give a final time > 0 [s].")
    import numpy as np

    kinds = {
        "trajectory": (args.output, "-trajectory.npz"),
        "figure": (args.figure, "-trajectory.png"),
    }
    if args.video is not None:
        kinds["video"] = (args.video or None, ".mp4")
    out = _outputs(args, args.scene, kinds)
    from . import RESULTS, enable_compilation_cache, save_trajectory, simulate

    enable_compilation_cache()
    t0 = time.perf_counter()
    traj = simulate(lk, t1, throw=False, progress=not args.no_progress, **kw)
    qs = np.asarray(traj.q)
    wall = time.perf_counter() - t0
    ok = traj.result == RESULTS.successful
    print(f"sorojax simulate: {args.scene} (ndof {lk.n_dof}) to t = {t1:g} s")
    print(
        f"  {'done' if ok else 'FAILED: ' + str(traj.result)}, solver {traj.solver}, "
        f"{int(traj.num_steps)} steps, {wall:.2f} s (compile included)"
    )
    from .kinematics import tip_pose

    tip = np.asarray(tip_pose(lk, qs[-1], lk.n_links))[:3, 3]
    print(f"  tip of link {lk.n_links} at t1 [m]: {np.array2string(tip, precision=6)}")
    if out["trajectory"] is not None:
        save_trajectory(out["trajectory"], traj, overwrite=args.overwrite)
        print(f"  trajectory written to {out['trajectory']}")
    if out["figure"] is not None:
        fig = _trajectory_figure(
            lk, np.asarray(traj.t), qs, pathlib.Path(args.scene).name
        )
        _save_figure(fig, out["figure"], args.overwrite)
        print(f"  figure written to {out['figure']}")
    if out.get("video") is not None:
        from .viz import animate

        video = animate(lk, traj, out["video"], overwrite=args.overwrite)
        print(f"  animation written to {video}")
    return EXIT_OK if ok else EXIT_FAILED


def _trajectory_figure(lk, ts, qs, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .kinematics import tip_pose
    from .viz import plot_configuration

    fig = plt.figure(figsize=(11, 4.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    picks = np.unique(np.linspace(0, len(ts) - 1, 5).astype(int))
    shades = plt.cm.viridis(np.linspace(0, 0.9, len(picks)))
    for k, c in zip(picks, shades, strict=True):
        plot_configuration(lk, qs[k], ax=ax, color=c, n_circle=8)
    ax.set_title(f"{title}: t = " + ", ".join(f"{ts[k]:.2g}" for k in picks))
    ax2 = fig.add_subplot(1, 2, 2)
    tips = np.stack([np.asarray(tip_pose(lk, q, lk.n_links))[:3, 3] for q in qs])
    for j, name in enumerate("xyz"):
        ax2.plot(ts, tips[:, j], label=name)
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel(f"tip of link {lk.n_links} [m]")
    ax2.legend()
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _plot(args) -> int:
    import numpy as np

    path = pathlib.Path(args.result)
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise _Exit(EXIT_INPUT, f"cannot read {path}: {err}") from None
    statics = "scene" in data.files and "tips" in data.files
    if not statics and args.scene is None:
        raise _Exit(
            EXIT_INPUT,
            f"{path} is a trajectory: give its scene file with --scene FILE.",
        )
    output = args.output if args.output is not None else f"{path.stem}-plot.png"
    out = _outputs(args, str(path), {"figure": (output, ".png")})
    if statics:
        import jax

        jax.config.update("jax_enable_x64", True)
        from .io._scene import SceneError, loads_scene
        from .kinematics import forward_kinematics

        try:
            scene = loads_scene(str(data["scene"]), f"{path} (its scene)")
        except SceneError as err:
            raise _Exit(EXIT_INPUT, str(err)) from None
        q = np.asarray(data["q"])
        g = np.asarray(forward_kinematics(scene.linkage, q))
        fig = _statics_figure(scene.linkage, q, g, path.name)
    else:
        scene = _load(args.scene)
        from .io import load_trajectory

        try:
            traj = load_trajectory(path)
        except (OSError, ValueError, KeyError) as err:
            raise _Exit(EXIT_INPUT, f"cannot read {path}: {err}") from None
        qs = np.asarray(traj.q)
        if qs.shape[-1] != scene.linkage.n_dof:
            raise _Exit(
                EXIT_INPUT,
                f"{path} holds {qs.shape[-1]} coordinates, the scene "
                f"{args.scene} has {scene.linkage.n_dof}: give the scene it was "
                "simulated from.",
            )
        fig = _trajectory_figure(scene.linkage, np.asarray(traj.t), qs, path.name)
    _save_figure(fig, out["figure"], args.overwrite)
    print(f"sorojax plot: figure written to {out['figure']}")
    return EXIT_OK
