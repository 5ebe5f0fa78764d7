"""The ``sorojax`` console script.

``sorojax demo`` builds the built-in default scene (a rigid link on a revolute joint
carrying a two-division soft link), solves its statics, prints ndof, the tip pose and
timings (compile and warm separately) and writes a PNG of the configuration.
Compiled programs are kept in JAX's persistent cache
(:func:`sorojax.enable_compilation_cache`; ``SOROJAX_CACHE_DIR=off`` turns it off),
so a second run's first call loads the program instead of compiling it.
"""

import argparse
import sys
import time


def _demo(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    from . import RESULTS, enable_compilation_cache, forward_kinematics, solve_statics
    from .scenes import demo_linkage

    cache = enable_compilation_cache()
    linkage = demo_linkage()
    print("sorojax demo: rigid link on a revolute joint + two-division soft link")
    print(f"  ndof = {linkage.n_dof}, significant points = {linkage.n_points}")
    t0 = time.perf_counter()
    sol = solve_statics(linkage, throw=False)
    jax.block_until_ready(sol.q)
    t_first = time.perf_counter() - t0
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        jax.block_until_ready(solve_statics(linkage, throw=False).q)
        runs.append(time.perf_counter() - t0)
    g = np.asarray(forward_kinematics(linkage, sol.q))
    tip = g[linkage.tip_point(linkage.n_links)]
    np.set_printoptions(precision=5, suppress=True)
    ok = bool(sol.result == RESULTS.successful)
    print("  statics: converged" if ok else f"  statics: FAILED ({sol.result})")
    print(
        f"  iterations = {int(sol.num_steps)}, "
        f"residual = {float(sol.residual_norm):.2e}"
    )
    print(
        f"  equilibrium: {'stable' if bool(sol.stable) else 'UNSTABLE'} (smallest "
        f"scaled tangent-stiffness eigenvalue {float(sol.min_eigenvalue):.3g})"
    )
    print(f"  q = {np.asarray(sol.q)}")
    print(f"  tip position [m] = {tip[:3, 3]}")
    print("  tip rotation =\n" + "\n".join("    " + str(r) for r in tip[:3, :3]))
    print(
        f"  time: first call (trace, compile or load, run) {t_first:.2f} s, "
        f"warm median {1e3 * float(np.median(runs)):.2f} ms"
    )
    if cache is not None:
        print(f"  compiled programs cached in {cache} (a later first call loads them)")
    if args.output:
        import matplotlib

        matplotlib.use("Agg")
        from .viz import plot_configuration

        fig, ax = plot_configuration(linkage, sol.q)
        ax.set_title("sorojax demo: static equilibrium")
        fig.savefig(args.output, dpi=120)
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
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    return 2


if __name__ == "__main__":
    sys.exit(main())
