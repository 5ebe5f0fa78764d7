"""Cost of a gradient relative to the forward computation, and its memory.

* Statics: a 30-DoF rod (clamped, 1 m, r 1 cm, E 10 MPa, all six modes at
  Legendre order 4) under a 3D tip force; the QoI is the tip position's squared
  norm; gradient with respect to (E, the six tip-wrench entries) by reverse mode
  through ``solve_statics`` (implicit function theorem).
* Dynamics: SoRoSim's damped free-fall rod (12 DoF, eta 5e4 Pa s), 1 s with the
  default solver (ROS34PW2, adaptive); QoI the final tip height; gradient with
  respect to (E, eta) by reverse mode through ``simulate``
  (``RecursiveCheckpointAdjoint``). Memory: XLA's own accounting of the compiled
  gradient program (``memory_analysis()``: temporaries + arguments + outputs) for
  1 s and 5 s rollouts. The same gradient in forward mode as well (``jax.jacfwd``
  with ``adjoint=diffrax.ForwardMode()``: two tangents, the same discrete map's
  exact derivative).

Forward and gradient programs are compiled apart (compile times reported), warm
times are medians of ``--repeats`` calls.

Run::

    python benchmarks/gradients.py [--repeats 7] [--out benchmarks/results]
"""

import argparse
import json
import os
import statistics
import time

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from _common import environment  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import cantilever, free_fall_q0, free_fall_rod  # noqa: E402


def _timed(fn, x, repeats):
    jit = jax.jit(fn, compiler_options=sj.compiler_options())
    t = time.perf_counter()
    compiled = jit.lower(x).compile()
    compile_s = time.perf_counter() - t
    value = jax.block_until_ready(compiled(x))
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(compiled(x))
        ts.append(time.perf_counter() - t)
    mem = compiled.memory_analysis()
    mem_bytes = None
    if mem is not None:
        mem_bytes = int(
            mem.temp_size_in_bytes
            + mem.argument_size_in_bytes
            + mem.output_size_in_bytes
        )
    return {
        "compile_s": compile_s,
        "warm_s": statistics.median(ts),
        "bytes": mem_bytes,
        "value": jnp.asarray(value).tolist(),
    }


def statics(repeats):
    rod = cantilever(
        1.0, 0.01, 1e7, modes=(1, 1, 1, 1, 1, 1), order=4, tip_wrench=[0.0] * 6
    )
    assert rod.n_dof == 30

    def qoi(x):
        E, w = x[0], x[1:]
        lk = eqx.tree_at(lambda l: l.links[0].material.E, rod, E)
        lk = eqx.tree_at(lambda l: l.point_wrenches[0].wrench, lk, w)
        sol = sj.solve_statics(lk, throw=False)
        return jnp.sum(sj.tip_pose(lk, sol.q)[:3, 3] ** 2)

    x = jnp.array([1e7, 0.0, 0.0, 0.05, 0.0, 0.3, 0.2])
    fwd = _timed(qoi, x, repeats)
    grad = _timed(jax.grad(qoi), x, repeats)
    return {"n_dof": rod.n_dof, "forward": fwd, "gradient": grad}


def dynamics(t1, repeats):
    rod = free_fall_rod(eta=5e4)
    q0 = free_fall_q0(rod)

    def qoi(x, adjoint=None):
        lk = eqx.tree_at(lambda l: l.links[0].material.E, rod, x[0])
        lk = eqx.tree_at(lambda l: l.links[0].material.eta, lk, x[1])
        tr = sj.simulate(lk, t1, q0, n_save=2, throw=False, adjoint=adjoint)
        return tr.tip_positions(lk)[-1, 2]

    x = jnp.array([1e6, 5e4])
    fwd = _timed(qoi, x, repeats)
    grad = _timed(jax.grad(qoi), x, repeats)
    fmode = _timed(jax.jacfwd(lambda x: qoi(x, diffrax.ForwardMode())), x, repeats)
    g_rev, g_fwd = jnp.asarray(grad["value"]), jnp.asarray(fmode["value"])
    fmode["max_rel_diff_from_reverse"] = float(
        jnp.max(jnp.abs(g_fwd - g_rev) / jnp.abs(g_rev))
    )
    return {
        "n_dof": rod.n_dof,
        "t1": t1,
        "forward": fwd,
        "gradient": grad,
        "gradient_forward_mode": fmode,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    args = ap.parse_args()
    res = {"environment": environment()}
    res["statics"] = statics(args.repeats)
    jax.clear_caches()
    for t1 in (1.0, 5.0):
        res[f"dynamics_{t1:g}s"] = dynamics(t1, args.repeats)
        jax.clear_caches()
    for key, r in res.items():
        if key == "environment":
            continue
        f, g = r["forward"], r["gradient"]
        r["ratio"] = g["warm_s"] / f["warm_s"]
        print(
            f"{key:14s} {r['n_dof']:3d} DoF: forward {1e3 * f['warm_s']:8.2f} ms "
            f"(compile {f['compile_s']:.1f} s), gradient {1e3 * g['warm_s']:8.2f} ms "
            f"(compile {g['compile_s']:.1f} s): {r['ratio']:.2f}x; gradient memory "
            f"{(g['bytes'] or 0) / 2**20:.1f} MiB (forward {(f['bytes'] or 0) / 2**20:.1f})",
            flush=True,
        )
        fm = r.get("gradient_forward_mode")
        if fm is not None:
            print(
                f"{'':14s} forward mode (jax.jacfwd, ForwardMode): "
                f"{1e3 * fm['warm_s']:8.2f} ms (compile {fm['compile_s']:.1f} s): "
                f"{fm['warm_s'] / f['warm_s']:.2f}x; same gradient to "
                f"{fm['max_rel_diff_from_reverse']:.0e} relative",
                flush=True,
            )
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "gradients.json"), "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
