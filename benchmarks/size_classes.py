"""Size classes (issue 19): an order sweep with and without ``sorojax.size_class``.

A convergence study solves one scene at orders 1..P. Unpadded, each order is a new
structure and compiles its programs again; padded to the class of order P, the
orders share them. Each variant runs in a fresh process with JAX's persistent cache
off: once in sorojax's default compile mode (tiers, as a user's script) for each
order's first call (a structure's first call includes its trace and compile) and
the sweep's total, once with every program at XLA's default level for the warm
call (median of ``--repeats``; in the tiers, early calls run -O0 code). Reported:
those, the tip position, and and the tip difference between the padded and unpadded models of
each order (class order >= 4 runs every order with the 6th-order Magnus step and
the class's points, so low orders differ from their unpadded models by that step's
smaller error).

Scenes:

* ``statics``: the 3D cantilever of tests/test_size_class.py (0.5 m, E 1 MPa,
  torsion and both bendings, gravity and a tip force), orders 1..6, class 6;
* ``dynamics``: 0.5 s of the damped free-fall rod (``free_fall_rod(order,
  eta=1e4)``), orders 1..4, class 4, default solver;
* ``divisions``: the statics cantilever at order 2 with 1..4 divisions, class of
  order 2 and 4 divisions (the "order" column holds the number of divisions).

Run::

    .venv/bin/python benchmarks/size_classes.py [--repeats 5] [--tag ""]

Writes ``benchmarks/results/size_classes<tag>.json`` and prints a table.
"""

import argparse
import json
import statistics
import subprocess
import sys
import time

from _common import ROOT, environment

ORDERS = {
    "statics": (1, 2, 3, 4, 5, 6),
    "dynamics": (1, 2, 3, 4),
    "divisions": (1, 2, 3, 4),  # numbers of divisions (order 2), not orders
}


def _scene(scene, value):
    from sorojax import scenes

    if scene == "dynamics":
        return scenes.free_fall_rod(value, eta=1e4)
    return scenes.cantilever(
        length=0.5,
        radius=0.01,
        E=1e6,
        modes=(1, 1, 1, 0, 0, 0),
        order=value if scene == "statics" else 2,
        n_divisions=1 if scene == "statics" else value,
        gravity=(0.0, 0.0, -9.81),
        tip_wrench=[0.0, 0.0, 0.0, 0.0, 0.2, 0.05],
    )


def child(scene, padded, mode, repeats):
    """One sweep in this (fresh) process, compile ``mode``; prints one JSON line."""
    import os

    os.environ["SOROJAX_COMPILE"] = mode
    import jax
    import numpy as np

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_enable_compilation_cache", False)
    import sorojax as sj
    from sorojax import scenes

    top = max(ORDERS[scene])
    rows = []
    t_sweep = time.perf_counter()
    for order in ORDERS[scene]:
        lk = _scene(scene, order)
        if padded and scene == "divisions":
            lk = sj.size_class(lk, 2, divisions=top)
        elif padded:
            lk = sj.size_class(lk, top)

        if scene != "dynamics":

            def run(lk=lk):
                sol = sj.solve_statics(lk)
                return sol.q, sol.result

        else:
            q0 = scenes.free_fall_q0(lk)

            def run(lk=lk, q0=q0):
                tr = sj.simulate(lk, 0.5, q0, n_save=2)
                return tr.q[-1], tr.result

        t = time.perf_counter()
        q, result = jax.block_until_ready(run())
        first = time.perf_counter() - t
        warm = []
        for _ in range(repeats):
            t = time.perf_counter()
            jax.block_until_ready(run())
            warm.append(time.perf_counter() - t)
        tip = np.asarray(sj.tip_pose(lk, q))[:3, 3]
        rows.append(
            {
                "order": order,
                "n_dof": lk.n_dof,
                "first_call_s": first,
                "warm_median_s": statistics.median(warm),
                "tip": tip.tolist(),
                "result": int(result._value),
            }
        )
    print(
        json.dumps(
            {
                "scene": scene,
                "padded": padded,
                "mode": mode,
                "sweep_s": time.perf_counter() - t_sweep,
                "rows": rows,
            }
        )
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--tag", default="")
    ap.add_argument("--child", nargs=3, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child[0], args.child[1] == "padded", args.child[2], args.repeats)
        return
    out = {"environment": environment(), "runs": []}
    for scene in ORDERS:
        runs = {}
        for variant in ("unpadded", "padded"):
            for mode in ("tiered", "full"):
                p = subprocess.run(
                    [sys.executable, __file__, "--child", scene, variant, mode]
                    + ["--repeats", str(args.repeats)],
                    capture_output=True,
                    text=True,
                )
                if p.returncode:
                    print(f"{scene} {variant}: failed\n{p.stderr[-2000:]}", flush=True)
                    continue
                runs[variant, mode] = json.loads(p.stdout.strip().splitlines()[-1])
                out["runs"].append(runs[variant, mode])
        if len(runs) < 4:
            continue
        a, b = runs["unpadded", "tiered"], runs["padded", "tiered"]
        wa, wb = runs["unpadded", "full"]["rows"], runs["padded", "full"]["rows"]
        print(
            f"\n{scene}: sweep {a['sweep_s']:.2f} s unpadded, {b['sweep_s']:.2f} s "
            "padded (tiers; full level: "
            f"{runs['unpadded', 'full']['sweep_s']:.2f} / "
            f"{runs['padded', 'full']['sweep_s']:.2f} s)"
        )
        print("order  ndof   first call [s]   warm [ms]       |tip difference| [m]")
        for ra, rb, fa, fb in zip(a["rows"], b["rows"], wa, wb, strict=True):
            d = max(abs(x - y) for x, y in zip(ra["tip"], rb["tip"], strict=True))
            print(
                f"{ra['order']:5d}  {ra['n_dof']:2d}/{rb['n_dof']:2d}  "
                f"{ra['first_call_s']:6.2f} {rb['first_call_s']:6.2f}   "
                f"{1e3 * fa['warm_median_s']:6.2f} {1e3 * fb['warm_median_s']:6.2f}   "
                f"{d:.1e}  (results {ra['result']}, {rb['result']})"
            )
    path = ROOT / "benchmarks" / "results" / f"size_classes{args.tag}.json"
    path.write_text(json.dumps(out, indent=1))
    print(f"\nwrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
