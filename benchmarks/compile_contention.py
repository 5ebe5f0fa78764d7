"""Two XLA compiles at once: what a compile in the calling thread pays beside one in a
worker thread (``sorojax.prepare``'s situation).

Each round runs two fresh processes (cache off), in alternating order:

* ``alone``: the four-cable arm's statics program (``examples/cable_manipulator.py``'s
  solve, 12 DoF) is traced, lowered and compiled, then 12 tiny programs (one
  multiplication each: what an eager JAX operation compiles on first use);
* ``beside``: the same, while a worker thread compiles the PD-controlled arm's
  8 s integration (both programs lowered first; the two compiles start together,
  as when ``sorojax.prepare``'s compile is still running at the next call);
* ``tiny``: tiny programs compiled one after another for as long as the worker
  compiles the PD-controlled arm's integration.

Python is not blocked by the worker (XLA's compile releases the GIL: a pure-Python
loop in the calling thread ran without a pause over 50 ms), so what the calling
thread loses is inside XLA. Reports the calling thread's compile times (the statics
program, the tiny programs' median and largest) in each process, and the worker's
compile time beside them.

Run::

    .venv/bin/python benchmarks/compile_contention.py [--rounds 2]

Writes ``benchmarks/results/compile_contention.json``.
"""

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import threading
import time

RESULTS_DIR = pathlib.Path(__file__).parent / "results"


def child(mode):
    """One process: the calling thread's compiles, ``alone`` or ``beside`` (JSON)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import sorojax as sj

    sys.path.insert(0, str(pathlib.Path(__file__).parent.parent / "examples"))
    import cable_manipulator as cm

    options = sj.compiler_options()
    arm = cm.cable_manipulator(order=2, eta=cm.ETA)
    tip = arm.tip_point(1)

    def statics(T):
        sol = sj.solve_statics(arm, u=T, throw=False)
        return sj.forward_kinematics(arm, sol.q)[tip, :3, 3]

    out = {"mode": mode}
    worker = None
    if mode in ("beside", "tiny"):
        hook = cm.pd_hook(tip, np.zeros(3), np.zeros(4))
        controlled = cm.cable_manipulator(order=2, eta=cm.ETA, actuator_strength=hook)

        def pd(t1):
            settings = dict(n_save=161, rtol=1e-6, atol=1e-8, solver="tsit5")
            return sj.simulate(controlled, t1, throw=False, **settings).q

        lowered = jax.jit(pd, compiler_options=options).lower(jnp.asarray(8.0))

        def compile_pd():
            t = time.perf_counter()
            lowered.compile()
            out["worker_compile_s"] = time.perf_counter() - t

        worker = threading.Thread(target=compile_pd)
    if mode == "tiny":  # tiny programs compiled while the worker compiles
        worker.start()
        tiny, k = [], 0
        while worker.is_alive():
            t = time.perf_counter()
            jax.jit(lambda x, k=k: x * (k + 3.0)).lower(np.ones(3)).compile()
            tiny.append(time.perf_counter() - t)
            k += 1
        out["tiny_compile_s"] = tiny
        print(json.dumps(out))
        return
    t = time.perf_counter()
    lowered_statics = jax.jit(statics, compiler_options=options).lower(np.ones(4))
    out["statics_trace_lower_s"] = time.perf_counter() - t
    if worker is not None:  # both compiles start together
        worker.start()
    t = time.perf_counter()
    lowered_statics.compile()
    out["statics_compile_s"] = time.perf_counter() - t
    tiny = []
    for k in range(12):
        t = time.perf_counter()
        jax.jit(lambda x, k=k: x * (k + 3.0)).lower(np.ones(3)).compile()
        tiny.append(time.perf_counter() - t)
    out["tiny_compile_s"] = tiny
    if worker is not None:
        worker.join()
    print(json.dumps(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child(args.child)
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    from _common import environment

    runs = {"alone": [], "beside": [], "tiny": []}
    order = ["alone", "beside", "tiny"]
    for r in range(args.rounds):
        for mode in order if r % 2 == 0 else order[::-1]:
            env = dict(os.environ, SOROJAX_CACHE_DIR="off")
            done = subprocess.run(
                [sys.executable, __file__, "--child", mode],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            )
            row = json.loads(done.stdout.strip().splitlines()[-1])
            runs[mode].append(row)
            tiny = row["tiny_compile_s"]
            if mode == "tiny":
                print(
                    f"round {r + 1} tiny  : {len(tiny)} tiny compiles during the "
                    f"worker's {row['worker_compile_s']:.2f} s compile: median "
                    f"{1e3 * statistics.median(tiny):.0f} ms, largest "
                    f"{1e3 * max(tiny):.0f} ms, sum {sum(tiny):.2f} s",
                    flush=True,
                )
                continue
            print(
                f"round {r + 1} {mode:6s}: statics trace+lower "
                f"{row['statics_trace_lower_s']:.2f} s, compile "
                f"{row['statics_compile_s']:.2f} s; tiny compiles median "
                f"{1e3 * statistics.median(tiny):.0f} ms, largest "
                f"{1e3 * max(tiny):.0f} ms"
                + (
                    f"; worker's compile {row['worker_compile_s']:.2f} s"
                    if "worker_compile_s" in row
                    else ""
                ),
                flush=True,
            )
    RESULTS_DIR.mkdir(exist_ok=True)
    path = RESULTS_DIR / "compile_contention.json"
    path.write_text(json.dumps({"environment": environment(), "runs": runs}, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
