"""Tracing work of a model's programs, with and without reusing ``precompute``'s trace.

JAX cannot cache traces between processes, and within one process each new program
runs sorojax's Python again. ``sorojax.model.precompute`` (bases, section matrices,
K and D of a model) opens every program; it is an inlined jit
(``sorojax._jit.traced_once``), so a model's later programs re-emit its cached jaxpr.
This script measures that, deterministically: the number of Python function calls
made while tracing (``cProfile``'s call count; on this machine a trace's wall time
varies by +-30 % from minute to minute, its call count by well under 1 %), and the
process CPU time beside it. Each scenario runs in a fresh process, once with
``precompute`` as shipped ("cached") and once with its plain function put back in
every sorojax module ("uncached"):

* ``hybrid``: the programs of ``examples/manual_hybrid.py`` on the manual's 17-DoF
  hybrid, traced with ``jax.make_jaxpr``: statics, kinematics, cable lengths, 1 s of
  dynamics, closure errors at five states, energy;
* ``corrector``: the continuation corrector of each path of
  ``examples/snap_through.py`` (a forward-mode Jacobian of the statics rows, whose
  model depends on the load parameter: ``precompute`` runs under ``jvp`` there);
* ``statics``: one statics program of the hybrid (no reuse: the overhead of the
  inlined jit's first call).

Run::

    .venv/bin/python benchmarks/trace_reuse.py [--repeats 2]

Results: ``results/trace_reuse.json``.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

from _common import ROOT, environment

SCENARIOS = ("hybrid", "corrector", "statics")


def _uncache():
    """Put the plain ``_precompute`` wherever sorojax imported ``precompute``."""
    import sorojax.model._precompute as pre

    cached = pre.precompute
    for name, mod in list(sys.modules.items()):
        if name.startswith("sorojax") and getattr(mod, "precompute", None) is cached:
            mod.precompute = pre._precompute


def _child(scenario: str, uncached: bool) -> dict:
    import cProfile
    import functools
    import importlib
    import pstats
    import time

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import sorojax as sj

    for m in (
        "statics",
        "kinematics",
        "dynamics",
        "integrate",
        "statics._continuation",
    ):
        importlib.import_module(f"sorojax.{m}")
    if uncached:
        _uncache()
    pr = cProfile.Profile()
    cpu = 0.0

    def traced(f, *args):
        nonlocal cpu
        t = time.process_time()
        pr.enable()
        jax.make_jaxpr(f)(*args)
        pr.disable()
        cpu += time.process_time() - t

    sys.path.insert(0, str(ROOT / "examples"))  # the examples' scenes and inputs
    if scenario in ("hybrid", "statics"):
        from manual_hybrid import inputs

        lk = sj.scenes.manual_hybrid()
        q = jnp.zeros(lk.n_dof)
        traced(lambda: sj.solve_statics(lk, q, u=jnp.array([0.1, 5.0])).q)
        if scenario == "hybrid":
            traced(lambda: sj.forward_kinematics(lk, q))
            traced(lambda: sj.cable_lengths(lk, q))
            traced(
                lambda: (
                    sj.simulate(lk, 1.0, q, u=inputs, n_save=11, rtol=1e-6, atol=1e-8).q
                )
            )
            qs = jnp.zeros((5, lk.n_dof))
            traced(lambda: jax.vmap(lambda qi: sj.closure_errors(lk, qi))(qs))
            traced(lambda: sj.total_energy(lk, q, q))
    else:
        import matplotlib

        matplotlib.use("Agg")
        import snap_through

        import sorojax.statics._continuation as cont

        real, seen = cont._correct, set()

        def correct(*args, **kw):
            if id(args[0]) not in seen:  # the first call of each path's family
                seen.add(id(args[0]))
                traced(functools.partial(real, **kw), *args)
            return real(*args, **kw)

        cont._correct = correct
        with tempfile.TemporaryDirectory() as out:  # the example's PNG
            snap_through.main(["--out", out])
    return {"calls": pstats.Stats(pr).total_calls, "cpu_s": round(cpu, 3)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(_child(args.child[0], args.child[1] == "uncached")))
        return
    rows = []
    for scenario in SCENARIOS:
        for _ in range(args.repeats):
            for mode in ("cached", "uncached"):
                out = subprocess.run(
                    [sys.executable, __file__, "--child", scenario, mode],
                    capture_output=True,
                    text=True,
                    check=True,
                    env={**os.environ, "SOROJAX_CACHE_DIR": "off"},
                )
                row = {"scenario": scenario, "mode": mode}
                row.update(json.loads(out.stdout.strip().splitlines()[-1]))
                rows.append(row)
                print(
                    f"{scenario:10s} {mode:9s} {row['calls']:>9d} calls "
                    f"{row['cpu_s']:6.2f} s CPU"
                )
    path = ROOT / "benchmarks" / "results" / "trace_reuse.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"env": environment(), "rows": rows}, indent=1) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
