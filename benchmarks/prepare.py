"""A script's first run with and without ``sorojax.prepare`` (issue 19, stop 35).

A first run waits for each program as the script reaches it. ``sorojax.prepare``
traces and lowers a later call's programs at once and compiles them in a worker
thread while the script goes on (XLA's compile does not hold Python's lock). This
script measures what that gains on the pattern of ``examples/manual_hybrid.py``:
the manual's 17-DoF hybrid, statics at -pi/4 and 50 N from q = 0, the rest
equilibrium, then ``--t1`` seconds of dynamics (Tsit5, rtol 1e-6, the revolute
driven at pi t / 2 and the tension ramped), each run in a fresh process with the
persistent compilation cache off:

* ``plain``: as a script without it (each program compiled when first called);
* ``prepared``: ``sj.prepare(sj.simulate, ...)`` first, with the dynamics'
  arguments (``q0`` the reference shape: the values do not matter, the solver is
  named).

The two variants alternate for ``--rounds`` rounds, so that the machine's drift
(25-50 % within minutes on the 2-core CPU this was written on) hits them alike.
Reported per run: the wall time from the first sorojax call to the trajectory
(import excluded), the statics' and the dynamics' first calls, and the process's
CPU time over the same span (both cores: the compile thread's work shows there).

Run::

    .venv/bin/python benchmarks/prepare.py [--rounds 3] [--t1 1.0]

Results: ``results/prepare.json``.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

from _common import ROOT, environment

VARIANTS = ("plain", "prepared")


def _child(variant: str, t1: float) -> dict:
    import math
    import time

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import sorojax as sj
    from sorojax.scenes import manual_hybrid

    def inputs(t):
        ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
        return jnp.stack([jnp.pi * t / 2, 50.0 * ramp])

    linkage = manual_hybrid()
    q_ref = jnp.zeros(linkage.n_dof)
    dynamics = dict(u=inputs, n_save=41, rtol=1e-6, atol=1e-8, solver="tsit5")
    cpu0, start = time.process_time(), time.perf_counter()
    if variant == "prepared":
        sj.prepare(sj.simulate, linkage, t1, q_ref, **dynamics)
    prepared = time.perf_counter()
    sol = sj.solve_statics(linkage, q_ref, u=jnp.array([-math.pi / 4, 50.0]))
    jax.block_until_ready(sol.q)
    statics = time.perf_counter()
    rest = sj.solve_statics(linkage, q_ref, u=jnp.zeros(2))
    traj = sj.simulate(linkage, t1, rest.q, **dynamics)
    jax.block_until_ready((traj.q, traj.efforts))
    end = time.perf_counter()
    return {
        "variant": variant,
        "wall_s": end - start,
        "prepare_s": prepared - start,
        "statics_first_call_s": statics - prepared,
        "rest_and_dynamics_s": end - statics,
        "cpu_s": time.process_time() - cpu0,
        "steps": int(traj.num_steps),
        "q_final": [float(x) for x in traj.q[-1]],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--t1", type=float, default=1.0, help="simulated time [s]")
    ap.add_argument("--child", choices=VARIANTS, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(_child(args.child, args.t1)))
        return
    env = {**os.environ, "SOROJAX_CACHE_DIR": "off", "PYTHONPATH": str(ROOT)}
    runs = []
    for r in range(args.rounds):
        for variant in VARIANTS:
            out = subprocess.run(
                [sys.executable, __file__, "--child", variant, "--t1", str(args.t1)],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            ).stdout
            run = json.loads(out.strip().splitlines()[-1])
            runs.append(run)
            print(
                f"round {r + 1} {variant:8s}: {run['wall_s']:.2f} s (statics "
                f"{run['statics_first_call_s']:.2f}, rest + dynamics "
                f"{run['rest_and_dynamics_s']:.2f}, prepare {run['prepare_s']:.2f}), "
                f"CPU {run['cpu_s']:.2f} s",
                flush=True,
            )
    # the same program either way: the same trajectory, bit for bit
    finals = {tuple(run["q_final"]) for run in runs}
    summary = {}
    for variant in VARIANTS:
        mine = [run for run in runs if run["variant"] == variant]
        summary[variant] = {
            key: statistics.median(run[key] for run in mine)
            for key in ("wall_s", "statics_first_call_s", "rest_and_dynamics_s")
            + ("cpu_s", "prepare_s")
        }
    gain = summary["plain"]["wall_s"] - summary["prepared"]["wall_s"]
    print(
        f"median wall: plain {summary['plain']['wall_s']:.2f} s, prepared "
        f"{summary['prepared']['wall_s']:.2f} s ({gain:+.2f} s saved); CPU "
        f"{summary['plain']['cpu_s']:.2f} / {summary['prepared']['cpu_s']:.2f} s; "
        f"identical final states: {len(finals) == 1}"
    )
    results = ROOT / "benchmarks" / "results"
    results.mkdir(exist_ok=True)
    payload = {
        "environment": environment(rounds=args.rounds, t1=args.t1),
        "runs": runs,
        "median": summary,
        "identical_final_states": len(finals) == 1,
    }
    (results / "prepare.json").write_text(json.dumps(payload, indent=1))


if __name__ == "__main__":
    main()
