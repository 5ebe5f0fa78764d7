"""Cost of the generalised dynamic terms against ndof and against the number of points.

Run from the repository root::

    .venv/bin/python benchmarks/terms.py            # ~3-5 min on 2 CPU cores
    .venv/bin/python benchmarks/terms.py --quick    # fewer sizes

For the free-fall rod geometry (L 0.5 m, r 2 -> 1 cm, E 1 MPa), modes (1, 1, 1, 0, 0, 0):
warm time (median of 7 timed loops of 50 calls, after compile) of

* ``M``: ``mass_matrix`` (Jacobians formed, sum w J^T M J: O(points ndof^2)),
* ``Cqd``: ``coriolis_force`` (no Jacobian: forward-mode twists + backward wrench
  recursion, O(points ndof)),
* ``C``: ``coriolis_matrix`` (Jdot formed: O(points ndof^2)),
* ``qdd``: ``forward_dynamics`` (all terms, one Cholesky solve: O(points ndof^2 + ndof^3)),
* ``jac``: the Jacobian of the state derivative (what implicit solvers use),

(1) against ndof = 3 (order + 1) for orders 1..19 (6..60 DoF) at the default number of
points, (2) against the number of Gauss points (8..128) at 12 DoF. Compile times are
reported separately. Writes ``results/terms.{csv,json,png}``.
"""

import argparse
import csv
import json
import os
import pathlib
import subprocess
import time

# warm timings at XLA's default level from the first call (sorojax.compile_mode)
os.environ.setdefault("SOROJAX_COMPILE", "full")

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import sorojax as sj  # noqa: E402
from sorojax.scenes import free_fall_q0, free_fall_rod  # noqa: E402

OUT = pathlib.Path(__file__).parent / "results"


def timed(fn, *args, loops=50, repeats=7):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    compile_s = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(loops):
            out = fn(*args)
        jax.block_until_ready(out)
        runs.append((time.perf_counter() - t0) / loops)
    return compile_s, float(np.median(runs))


def measure(order, n_gauss):
    rod = free_fall_rod(order=order, n_gauss=n_gauss)
    n = rod.n_dof
    q = free_fall_q0(rod) + 0.01 * jnp.arange(n) / n
    qd = 0.1 * jnp.ones(n)

    def state_derivative(y):
        return jnp.concatenate([y[n:], sj.forward_dynamics(rod, y[:n], y[n:])])

    y = jnp.concatenate([q, qd])
    fns = {
        "M": (jax.jit(lambda q: sj.mass_matrix(rod, q)), (q,)),
        "Cqd": (jax.jit(lambda q, qd: sj.coriolis_force(rod, q, qd)), (q, qd)),
        "C": (jax.jit(lambda q, qd: sj.coriolis_matrix(rod, q, qd)), (q, qd)),
        "qdd": (jax.jit(state_derivative), (y,)),
        "jac": (jax.jit(jax.jacfwd(state_derivative)), (y,)),
    }
    row = {
        "order": order,
        "n_dof": n,
        "n_points": rod.layout.n_points,
        "n_gauss": n_gauss,
    }
    for name, (fn, args) in fns.items():
        c, w = timed(fn, *args)
        row[f"{name}_compile_s"] = c
        row[f"{name}_warm_us"] = w * 1e6
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    OUT.mkdir(exist_ok=True)
    load0 = os.getloadavg()
    orders = [1, 3, 9, 19] if args.quick else [1, 2, 3, 5, 7, 9, 13, 19]
    gauss = [8, 32, 128] if args.quick else [8, 16, 32, 64, 128]
    rows = []
    names = ("M", "Cqd", "C", "qdd", "jac")
    print("sweep ndof (default points)")
    print("  ndof points " + " ".join(f"{k:>9}" for k in names) + "   [us]")
    for o in orders:
        r = measure(o, None)
        r["sweep"] = "ndof"
        rows.append(r)
        print(
            f"  {r['n_dof']:4d} {r['n_points']:6d} "
            + " ".join(f"{r[k + '_warm_us']:9.1f}" for k in names),
            flush=True,
        )
    print("sweep points (12 DoF)")
    for g in gauss:
        r = measure(3, g)
        r["sweep"] = "points"
        rows.append(r)
        print(
            f"  {r['n_dof']:4d} {r['n_points']:6d} "
            + " ".join(f"{r[k + '_warm_us']:9.1f}" for k in names),
            flush=True,
        )
    load1 = os.getloadavg()
    with open(OUT / "terms.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    meta = {"git_head": head, "loadavg_start": load0, "loadavg_end": load1}
    (OUT / "terms.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, sweep, xkey in (
        (axes[0], "ndof", "n_dof"),
        (axes[1], "points", "n_points"),
    ):
        sel = [r for r in rows if r["sweep"] == sweep]
        for k in names:
            ax.loglog(
                [r[xkey] for r in sel], [r[k + "_warm_us"] for r in sel], "o-", label=k
            )
        ax.set_xlabel(xkey)
        ax.set_ylabel("warm time per call [us]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("against ndof (default points)")
    axes[1].set_title("against points (12 DoF)")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(OUT / "terms.png", dpi=120)
    print(f"load average {load0[0]:.1f} -> {load1[0]:.1f}; wrote {OUT}/terms.*")


if __name__ == "__main__":
    main()
