"""The ``sorojax`` console script.

``sorojax check | statics | simulate | plot`` work on scene files (see
:mod:`sorojax._cli_scene`).
``sorojax demo`` builds the built-in default scene (a rigid link on a revolute joint
carrying a two-division soft link), solves its statics, prints ndof, the tip pose and
timings (compile and warm separately) and writes a PNG of the configuration.
Compiled programs are kept in JAX's persistent cache
(:func:`sorojax.enable_compilation_cache`; ``SOROJAX_CACHE_DIR=off`` turns it off),
so a second run's first call loads the program instead of compiling it. The demo's
program runs once and for a millisecond, so it is compiled with LLVM at -O0 (about
half the code generation of XLA's default level; the same HLO and arithmetic, warm
runs a few times slower); ``--optimised`` compiles it as sorojax's functions are.
"""

import argparse
import os
import pathlib
import sys
import time

_DEMO_EXPORT = pathlib.Path(__file__).parent / "data" / "demo_statics.jaxexport"
"""The demo's program exported ahead of time (``jax.export``; see :func:`_demo`)."""


def _demo_program(linkage):
    """The demo's one program: statics and the poses at the solution (flat arrays)."""
    from .kinematics import forward_kinematics
    from .statics import solve_statics

    def program():
        sol = solve_statics(linkage, throw=False)
        g = forward_kinematics(linkage, sol.q)
        return (
            sol.q,
            sol.result._value,
            sol.num_steps,
            sol.residual_norm,
            sol.stable,
            sol.min_eigenvalue,
            g,
        )

    return program


def write_demo_export(path=_DEMO_EXPORT) -> pathlib.Path:
    """Export the demo's program for this JAX to ``path``.

    For maintainers, after a change to the solver or the scene:
    ``python -c "import sorojax._cli as c; c.write_demo_export()"``.
    ``tests/test_cli.py`` checks that the file still gives the results of the code.
    """
    import jax

    jax.config.update("jax_enable_x64", True)
    from .scenes import demo_linkage

    exported = jax.export.export(jax.jit(_demo_program(demo_linkage())))()
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(exported.serialize())
    return path


def _exported_demo(path=_DEMO_EXPORT):
    """The exported demo program's ``call``, or None where it cannot serve.

    None without the file, without ``flatbuffers`` (JAX's deserialiser), for a JAX
    that cannot read it, or on a backend other than the CPU it was exported for.
    """
    import jax

    try:
        exported = jax.export.deserialize(bytearray(pathlib.Path(path).read_bytes()))
    except Exception:  # noqa: BLE001 - any failure: trace the program instead
        return None
    if tuple(exported.platforms) != (jax.default_backend(),):
        return None
    return exported.call


def _prepare(output: bool, box: dict) -> None:
    """Build the scene and, for a figure, import matplotlib (beside the compile)."""
    from .scenes import demo_linkage

    box["linkage"] = demo_linkage()
    if output:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
        from mpl_toolkits.mplot3d import axes3d  # noqa: F401

        from . import viz  # noqa: F401


# PNG text chunk (keyword "Source") marking a figure the demo wrote: the demo
# replaces its own figure when run again, never another file of the same name.
_DEMO_MARK = "sorojax demo"


def _written_by_demo(path: pathlib.Path) -> bool:
    """Whether the file at ``path`` is a PNG that ``sorojax demo`` wrote.

    Reads the PNG's chunk headers up to the image data (text chunks come before it),
    not the whole file: any other file is recognised from its first bytes.
    """
    mark = b"Source\x00" + _DEMO_MARK.encode()
    with open(path, "rb") as f:
        if f.read(8) != b"\x89PNG\r\n\x1a\n":
            return False
        while len(header := f.read(8)) == 8:
            size, kind = int.from_bytes(header[:4], "big"), header[4:]
            if kind in (b"IDAT", b"IEND"):
                return False
            data = f.read(size)
            if kind == b"tEXt" and data == mark:
                return True
            f.seek(4, os.SEEK_CUR)  # the chunk's CRC
    return False


def _check_output(output: str, overwrite: bool) -> None:
    """Refuse (before any computation) to replace a file the demo did not write."""
    path = pathlib.Path(output)
    if output and path.exists() and not overwrite and not _written_by_demo(path):
        raise SystemExit(
            f"sorojax demo: {path} exists and was not written by sorojax demo; pass "
            "--overwrite to replace it, or -o to write the figure elsewhere."
        )


def _demo(args) -> int:
    import threading

    _check_output(args.output, args.overwrite)
    import jax

    jax.config.update("jax_enable_x64", True)  # before any array is made
    # The scene and matplotlib's import (~0.5 s) run in a thread while XLA compiles
    # (it releases the GIL).
    box: dict = {}
    prepare = threading.Thread(target=_prepare, args=(bool(args.output), box))
    prepare.start()
    import numpy as np

    from . import RESULTS, compiler_options, enable_compilation_cache
    from ._jit import FAST_OPTIONS

    cache = enable_compilation_cache()
    # The program exported ahead of time skips tracing and lowering (~0.7 s of a
    # first call); without it (another JAX, a GPU) it is traced here as usual.
    program = None if args.trace else _exported_demo()
    source = "exported program" if program is not None else "traced program"
    if program is None:
        prepare.join()
        program = _demo_program(box["linkage"])
    # A one-shot program (its run takes a millisecond): by default LLVM compiles it
    # at -O0, about half the code-generation time of XLA's default level (the same
    # HLO program and arithmetic; the warm run is a few times slower).
    options = compiler_options()
    if not args.optimised:
        options.update(FAST_OPTIONS)
    level = "XLA's default level" if args.optimised else "LLVM -O0 for a fast start"
    run = jax.jit(program, compiler_options=options)
    t0 = time.perf_counter()
    q, code, steps, residual, stable, min_eig, g = jax.block_until_ready(run())
    t_first = time.perf_counter() - t0
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        jax.block_until_ready(run())
        runs.append(time.perf_counter() - t0)
    prepare.join()
    linkage = box["linkage"]
    print("sorojax demo: rigid link on a revolute joint + two-division soft link")
    print(f"  ndof = {linkage.n_dof}, significant points = {linkage.n_points}")
    g = np.asarray(g)
    tip = g[linkage.tip_point(linkage.n_links)]
    np.set_printoptions(precision=5, suppress=True)
    ok = int(code) == RESULTS.successful._value
    print("  statics: converged" if ok else f"  statics: FAILED (result {int(code)})")
    print(f"  iterations = {int(steps)}, residual = {float(residual):.2e}")
    print(
        f"  equilibrium: {'stable' if bool(stable) else 'UNSTABLE'} (smallest "
        f"scaled tangent-stiffness eigenvalue {float(min_eig):.3g})"
    )
    print(f"  q = {np.asarray(q)}")
    print(f"  tip position [m] = {tip[:3, 3]}")
    print("  tip rotation =\n" + "\n".join("    " + str(r) for r in tip[:3, :3]))
    print(
        f"  time: first call ({source}: compile or load, run) {t_first:.2f} s, "
        f"warm median {1e3 * float(np.median(runs)):.2f} ms (compiled at {level}"
        + ("" if args.optimised else "; --optimised: as sorojax's functions")
        + ")"
    )
    if cache is not None:
        print(f"  compiled programs cached in {cache} (a later first call loads them)")
    if args.output:
        from .viz import plot_configuration

        fig, ax = plot_configuration(linkage, q, poses=g)
        ax.set_title("sorojax demo: static equilibrium")
        fig.savefig(args.output, dpi=120, metadata={"Source": _DEMO_MARK})
        print(f"  figure written to {args.output}")
    return 0 if ok else 1


def main(argv=None) -> int:
    """Entry point of the ``sorojax`` command."""
    parser = argparse.ArgumentParser(
        prog="sorojax", description=__doc__.splitlines()[0]
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo", help="solve the statics of the built-in default scene"
    )
    demo.add_argument(
        "-o", "--output", default="sorojax-demo.png", help="PNG to write ('' for none)"
    )
    demo.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the output file even if sorojax demo did not write it",
    )
    demo.add_argument(
        "--optimised",
        action="store_true",
        help="compile at XLA's default optimisation level (as sorojax's functions "
        "do) instead of LLVM -O0: slower to compile, faster warm runs",
    )
    demo.add_argument(
        "--trace",
        action="store_true",
        help="trace the program from the source instead of the exported one",
    )
    from . import _cli_scene

    _cli_scene.add_commands(sub)
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    return _cli_scene.run(args)


def console() -> None:
    """The ``sorojax`` console script: :func:`main`, then a prompt exit.

    Once the command has printed and written its files (closed, and the compiled
    programs already in the cache), the process exits without the interpreter's
    teardown: destroying XLA's client and thread pools and every module took
    ~0.2 s of the demo's ~3 s.
    """
    try:
        code = main()
        sys.stdout.flush()
    except BrokenPipeError:  # the output piped into a reader that closed (`| head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 1
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    sys.exit(main())
