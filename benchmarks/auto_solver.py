"""``solver="auto"``'s high-order rule (stop 32): Dopri8 against Tsit5 at tight rtol.

"auto" takes Dopri8 at ``rtol <= AUTO_HIGH_ORDER_RTOL`` (1e-7) where no mode bounds an
explicit step (at most ``AUTO_HIGH_ORDER_STEPS`` explicit steps over the span), and
Tsit5 otherwise. This script times both solvers on a scene of each kind:

* ``four_bar``: the driven rigid four-bar of ``examples/mechanisms.py`` (3 s at one
  revolution per second, closed loop, prescribed crank; no springs, so no stability
  bound: "auto" takes Dopri8);
* ``hybrid``: 2 s of the manual's hybrid closed chain with its inputs ramped as in
  ``examples/manual_hybrid.py`` (stiffness ~1200 1/s, ~840 explicit steps' worth
  over the span: "auto" keeps Tsit5).

For each (scene, rtol, solver): the first call (trace, compile, run; persistent cache
off, programs at XLA's default level as ``simulate``'s integration is compiled), the
warm median over ``--repeats`` calls, the accepted steps, the largest loop closure
error over the saves, and what "auto" picks. Everything runs in this process (the
programs differ by solver and scene, so each first call compiles its own).

Run::

    .venv/bin/python benchmarks/auto_solver.py [--repeats 3] [--tag ""]

Writes ``benchmarks/results/auto_solver<tag>.json`` and prints a table.
"""

import argparse
import json
import math
import time

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_enable_compilation_cache", False)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, environment, timed  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import four_bar, four_bar_assemble  # noqa: E402
from sorojax.scenes import manual_hybrid  # noqa: E402


def crank_angle(omega, t):
    """The four-bar's prescribed crank angle (one revolution per second)."""
    return jnp.stack([omega * t])


def hybrid_inputs(t):
    """The hybrid's revolute angle pi t / 2 and a 50 N tension ramped over 1 s."""
    ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
    return jnp.stack([jnp.pi * t / 2, 50.0 * ramp])


def scenes():
    """``name -> (linkage, t1, q0, u, n_save, rtols)``."""
    lk = manual_hybrid()
    rest = sj.solve_statics(lk, jnp.zeros(lk.n_dof), u=jnp.zeros(2)).q
    return {
        "four_bar": (
            four_bar(),
            3.0,
            jnp.asarray(four_bar_assemble(0.0)),
            eqx.Partial(crank_angle, 2 * math.pi),
            301,
            (1e-7, 1e-8),
        ),
        "hybrid": (lk, 2.0, rest, hybrid_inputs, 41, (1e-6, 1e-8)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--tag", default="")
    a = ap.parse_args()
    rows = []
    for name, (lk, t1, q0, u, n_save, rtols) in scenes().items():
        for rtol in rtols:
            picked = sj.integrate.auto_solver(lk, q0, 0.0, t1, rtol)
            for solver in ("tsit5", "dopri8"):

                def run(solver=solver, rtol=rtol, lk=lk, t1=t1, q0=q0, u=u, n=n_save):
                    return sj.simulate(
                        lk,
                        t1,
                        q0,
                        u=u,
                        n_save=n,
                        rtol=rtol,
                        atol=rtol * 1e-2,
                        solver=solver,
                    )

                start = time.perf_counter()
                traj = jax.block_until_ready(run())
                first = time.perf_counter() - start
                warm, _ = timed(run, repeats=a.repeats, warmup=False)
                drift = float(np.abs(np.asarray(traj.closure_errors(lk))).max())
                rows.append(
                    {
                        "scene": name,
                        "rtol": rtol,
                        "solver": solver,
                        "auto_picks": picked,
                        "first_call_s": first,
                        "warm_s": warm,
                        "steps": int(traj.num_accepted_steps),
                        "max_closure_error": drift,
                    }
                )
                r = rows[-1]
                print(
                    f"{name:9s} rtol {rtol:.0e} {solver:7s} first {first:5.2f} s  "
                    f"warm {warm:6.3f} s  steps {r['steps']:5d}  drift {drift:.1e}  "
                    f"(auto: {picked})"
                )
    out = ROOT / "benchmarks" / "results" / f"auto_solver{a.tag}.json"
    out.write_text(json.dumps({"env": environment(), "rows": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
