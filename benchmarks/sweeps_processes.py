"""Sweeps across local processes: cases per second for 1 and 2 (or more) processes.

The four-cable arm's statics (``benchmarks/sweeps.py``'s cases: order 1, 8 DoF,
random tensions up to 10 N), ``--cases`` of them, swept by ``sorojax.sweep`` in N
local CPU processes joined by ``sorojax.initialize_processes`` (jax.distributed,
gloo), one CPU device each. Each process times its sweep (its share, then the gather
of every output to every process) after an untimed first call that compiles it;
the rate is the cases over the slowest process's median time. Efficiency: the rate
over N times the one-process rate. Writes ``results/sweeps_processes.json``::

    .venv/bin/python benchmarks/sweeps_processes.py [--processes 1 2] [--cases 1024]

``benchmarks/sweeps.py --processes 1 2`` runs the same measurement. More processes
than cores oversubscribe the machine (4 processes on a 2-core CPU share 2 cores:
the rate cannot exceed the 2-process one).
"""

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OUT = Path(__file__).resolve().parent / "results" / "sweeps_processes.json"


def worker(pid: int, n_proc: int, port: str, n: int, repeats: int, out: str) -> None:
    import jax

    import sorojax as sj

    if n_proc > 1:
        sj.initialize_processes(f"localhost:{port}", n_proc, pid)
    jax.config.update("jax_enable_x64", True)
    from sorojax._mechanisms import cable_manipulator

    arm = cable_manipulator(order=1, eta=3e4)

    def case(T):
        sol = sj.solve_statics(arm, u=T, throw=False)
        return sj.tip_pose(arm, sol.q)[:3, 3], sol.result._value

    T = 10.0 * jax.random.uniform(jax.random.key(0), (n, 4))
    start = time.perf_counter()
    jax.block_until_ready(sj.sweep(case, T))
    first = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        tips, codes = jax.block_until_ready(sj.sweep(case, T))
        times.append(time.perf_counter() - start)
    Path(out).write_text(
        json.dumps(
            {
                "first_call_s": first,
                "times_s": times,
                "converged": int((codes == 0).sum()),
                "tip_sum": float(tips.sum()),
            }
        )
    )


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def run(n_proc: int, n: int, repeats: int) -> dict:
    port = str(_free_port())
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    env.pop("XLA_FLAGS", None)
    with tempfile.TemporaryDirectory() as tmp:
        outs = [os.path.join(tmp, f"{p}.json") for p in range(n_proc)]
        procs = [
            subprocess.Popen(
                [sys.executable, __file__, "--worker", str(p), str(n_proc), port,
                 str(n), str(repeats), outs[p]],
                env=env,
            )
            for p in range(n_proc)
        ]  # fmt: skip
        for proc in procs:
            if proc.wait(timeout=1800) != 0:
                raise RuntimeError(f"a worker of the {n_proc}-process run failed")
        per = [json.loads(Path(o).read_text()) for o in outs]
    slowest = [max(p["times_s"][k] for p in per) for k in range(repeats)]
    t = statistics.median(slowest)
    return {
        "processes": n_proc,
        "cases": n,
        "median_s": t,
        "cases_per_s": n / t,
        "first_call_s": max(p["first_call_s"] for p in per),
        "converged": per[0]["converged"],
        "tip_sum": per[0]["tip_sum"],
    }


def measure(processes, cases: int, repeats: int) -> list[dict]:
    """One row per process count; ``efficiency`` where 1 process was measured."""
    rows = [run(n, cases, repeats) for n in processes]
    base = next((r for r in rows if r["processes"] == 1), None)
    for r in rows:
        if base is not None:
            r["efficiency"] = r["cases_per_s"] / (r["processes"] * base["cases_per_s"])
    return rows


def report(rows: list[dict]) -> None:
    for r in rows:
        print(
            f"{r['processes']} process(es): {r['cases_per_s']:.0f} cases/s "
            f"(median {r['median_s'] * 1e3:.1f} ms for {r['cases']}, first call "
            f"{r['first_call_s']:.1f} s, efficiency "
            f"{r.get('efficiency', float('nan')):.2f})",
            flush=True,
        )


def write(rows: list[dict], path: Path = OUT) -> None:
    from _common import environment

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        json.dumps({"environment": environment(), "rows": rows}, indent=2) + "\n"
    )
    print(f"wrote {path}")


def main() -> None:
    if sys.argv[1:2] == ["--worker"]:
        pid, n_proc, port, n, repeats, out = sys.argv[2:8]
        worker(int(pid), int(n_proc), port, int(n), int(repeats), out)
        return
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--processes", type=int, nargs="+", default=[1, 2])
    p.add_argument("--cases", type=int, default=1024)
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args()
    import jax

    jax.config.update("jax_enable_x64", True)
    rows = measure(args.processes, args.cases, args.repeats)
    report(rows)
    write(rows)


if __name__ == "__main__":
    main()
