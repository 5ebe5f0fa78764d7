"""Batched sweeps: one at a time vs ``jax.vmap`` vs ``sorojax.sweep`` over devices.

Two workloads on the four-cable tapered arm (``sorojax._mechanisms.
cable_manipulator``, order 1: 8 DoF, damped):

* statics: equilibrium tip position for N random tension vectors (0-10 N each);
* dynamics: 0.5 s from rest under N random constant tension vectors (ROS34PW2,
  adaptive, rtol 1e-3), tip position at the end.

For each: one case at a time (a jitted single solve called N times from Python,
after a warm-up), one vmapped program on one device, and ``sorojax.sweep`` over
every device JAX sees. On a CPU, ``--devices K`` creates K host devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=K``, set before JAX starts).
Compile times are reported apart; throughput is the median of ``--repeats`` warm
runs. ``--sizes`` sweeps the batch size for the throughput-vs-size chart (on a GPU:
``--sizes 1 4 16 64 256 1024 4096 16384``).

``--processes 1 2 [4]`` measures instead the statics sweep (``--n-statics`` cases)
across that many local CPU processes joined by ``sorojax.initialize_processes``
(``sweeps_processes.py``'s measurement: cases/s and the efficiency against one
process; ``sweeps_processes{tag}.json``). More processes than cores oversubscribe the
machine. Without it the script ends by printing the stored
``results/sweeps_processes.json`` figures, if any, labelled as stored.

Run::

    python benchmarks/sweeps.py [--devices 2] [--n-statics 1024] [--n-dynamics 256]
        [--sizes ...] [--processes 1 2] [--out benchmarks/results]
"""

import argparse
import os
import sys


def _args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--devices", type=int, default=None, help="CPU host devices")
    ap.add_argument("--n-statics", type=int, default=1024)
    ap.add_argument("--n-dynamics", type=int, default=256)
    ap.add_argument("--sizes", type=int, nargs="*", default=None)
    ap.add_argument(
        "--processes",
        type=int,
        nargs="*",
        default=None,
        help="local processes (e.g. 1 2 4): the multi-process statics sweep",
    )
    ap.add_argument(
        "--loop-cases", type=int, default=128, help="cases timed one by one"
    )
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--skip-dynamics", action="store_true")
    ap.add_argument(
        "--chunk",
        type=lambda v: None if v == "none" else (v if v == "auto" else int(v)),
        default="auto",
        help="sweep's cases per device per pass: a number, 'none' or 'auto'",
    )
    ap.add_argument(
        "--load-steps",
        type=int,
        default=None,
        help="solve_statics load_steps (None: its automatic schedule)",
    )
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--tag", default="", help="suffix of the result files")
    return ap.parse_args(argv)


ARGS = _args(sys.argv[1:] if __name__ == "__main__" else [])
if ARGS.devices:
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "")
        + f" --xla_force_host_platform_device_count={ARGS.devices}"
    )

import csv  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from _common import environment  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import cable_manipulator  # noqa: E402

ARM = cable_manipulator(order=1, eta=3e4)


def statics_case(T):
    sol = sj.solve_statics(ARM, u=T, throw=False, load_steps=ARGS.load_steps)
    return sj.tip_pose(ARM, sol.q)[:3, 3], sol.result._value


def dynamics_case(T):
    tr = sj.simulate(ARM, 0.5, u=T, n_save=2, solver="ros34pw2", throw=False)
    return tr.tip_positions(ARM)[-1], tr.result._value


def _median_time(fn, repeats):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def measure(name, case, T, loop_cases, repeats):
    """Throughput [cases/s] one by one, vmapped (1 device), swept (all devices)."""
    n = T.shape[0]
    row = {"workload": name, "n": n, "devices": len(jax.devices())}
    one = jax.jit(case, compiler_options=sj.compiler_options())
    t = time.perf_counter()
    jax.block_until_ready(one(T[0]))
    row["compile_one_s"] = time.perf_counter() - t
    k = min(loop_cases, n)

    def loop():
        return [one(T[i]) for i in range(k)]

    row["one_by_one_per_s"] = k / _median_time(loop, repeats)
    vm = jax.jit(jax.vmap(case), compiler_options=sj.compiler_options())
    t = time.perf_counter()
    out_v = jax.block_until_ready(vm(T))
    row["compile_vmap_s"] = time.perf_counter() - t
    row["vmap_per_s"] = n / _median_time(lambda: vm(T), repeats)
    t = time.perf_counter()
    out_s = jax.block_until_ready(sj.sweep(case, T, chunk=ARGS.chunk))
    row["compile_sweep_s"] = time.perf_counter() - t
    row["sweep_per_s"] = n / _median_time(
        lambda: sj.sweep(case, T, chunk=ARGS.chunk), repeats
    )
    row["sweep_vs_vmap_max_diff_m"] = float(
        np.abs(np.asarray(out_s[0]) - np.asarray(out_v[0])).max()
    )
    row["failed_cases"] = int(np.sum(np.asarray(out_s[1]) != 0))
    row["vmap_speedup"] = row["vmap_per_s"] / row["one_by_one_per_s"]
    row["sweep_speedup"] = row["sweep_per_s"] / row["one_by_one_per_s"]
    print(
        f"{name:8s} n={n:5d} devices={row['devices']}: one by one "
        f"{row['one_by_one_per_s']:8.1f}/s, vmap {row['vmap_per_s']:8.1f}/s "
        f"({row['vmap_speedup']:.2f}x), sweep {row['sweep_per_s']:8.1f}/s "
        f"({row['sweep_speedup']:.2f}x); compile one/vmap/sweep "
        f"{row['compile_one_s']:.1f}/{row['compile_vmap_s']:.1f}/"
        f"{row['compile_sweep_s']:.1f} s; failed {row['failed_cases']}",
        flush=True,
    )
    return row


def tensions(n, seed=0):
    return 10.0 * jax.random.uniform(jax.random.key(seed), (n, 4))


def processes_main():
    """``--processes``: ``sweeps_processes.py``'s measurement, its figures and file."""
    import pathlib

    import sweeps_processes

    cores = os.cpu_count() or 1
    if max(ARGS.processes) > cores:
        print(
            f"note: {max(ARGS.processes)} processes on {cores} cores oversubscribe "
            "the machine (processes share cores)",
            flush=True,
        )
    rows = sweeps_processes.measure(ARGS.processes, ARGS.n_statics, ARGS.repeats)
    sweeps_processes.report(rows)
    sweeps_processes.write(
        rows, pathlib.Path(ARGS.out) / f"sweeps_processes{ARGS.tag}.json"
    )


def stored_processes():
    """Print the stored multi-process figures (``results/sweeps_processes.json``)."""
    path = os.path.join(os.path.dirname(__file__), "results", "sweeps_processes.json")
    if not os.path.exists(path):
        return
    with open(path) as f:
        data = json.load(f)
    env = data["environment"]
    print(
        f"across processes, stored in {os.path.relpath(path)} ({env['cpu_count']} "
        f"cores, load average {env['load_average_at_start'][0]:.1f} at start):"
    )
    for r in data["rows"]:
        print(
            f"  statics n={r['cases']:5d}, {r['processes']} process(es): "
            f"{r['cases_per_s']:8.1f} cases/s, efficiency "
            f"{r.get('efficiency', float('nan')):.2f}"
        )


def main():
    if ARGS.processes:
        processes_main()
        return
    env = environment()
    print(f"jax {jax.__version__} on {jax.devices()}", flush=True)
    rows = []
    if ARGS.sizes:
        for size in ARGS.sizes:
            T = tensions(size)
            for name, case in (("statics", statics_case), ("dynamics", dynamics_case)):
                if name == "dynamics" and ARGS.skip_dynamics:
                    continue
                t = time.perf_counter()
                jax.block_until_ready(sj.sweep(case, T, chunk=ARGS.chunk))
                first = time.perf_counter() - t
                per_s = size / _median_time(
                    lambda c=case, T=T: sj.sweep(c, T, chunk=ARGS.chunk), 3
                )
                rows.append(
                    {
                        "workload": name,
                        "n": size,
                        "sweep_per_s": per_s,
                        "first_s": first,
                    }
                )
                print(f"{name:8s} n={size:6d}: {per_s:10.1f} cases/s", flush=True)
    else:
        rows.append(
            measure(
                "statics",
                statics_case,
                tensions(ARGS.n_statics),
                ARGS.loop_cases,
                ARGS.repeats,
            )
        )
        if not ARGS.skip_dynamics:
            rows.append(
                measure(
                    "dynamics",
                    dynamics_case,
                    tensions(ARGS.n_dynamics, 1),
                    min(ARGS.loop_cases, 64),
                    ARGS.repeats,
                )
            )
    os.makedirs(ARGS.out, exist_ok=True)
    stem = os.path.join(ARGS.out, f"sweeps{ARGS.tag}")
    keys = sorted({k for r in rows for k in r})
    with open(stem + ".csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    with open(stem + ".json", "w") as f:
        json.dump({"environment": env, "rows": rows}, f, indent=1)
    if ARGS.sizes:
        _plot(rows, stem + ".png")
    print(f"wrote {stem}.csv/.json")
    stored_processes()


def _plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name in ("statics", "dynamics"):
        r = [x for x in rows if x["workload"] == name]
        if r:
            ax.loglog(
                [x["n"] for x in r], [x["sweep_per_s"] for x in r], "o-", label=name
            )
    ax.set_xlabel("cases per sweep")
    ax.set_ylabel("cases / s")
    ax.set_title(f"sorojax.sweep throughput on {jax.devices()[0].platform}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
