"""Where one dynamics evaluation spends its time, part by part, and its floor.

One evaluation is what every solver stage calls: the kinematics, the mass matrix,
the contact forces, the mapping of all wrenches to generalised forces and the
linear solve. Each part, and the whole evaluation, is compiled inside a
``lax.fori_loop`` of N calls (the loop's state depends on the previous result, so
nothing is hoisted out and there is no dispatch between calls), with the XLA
options and runtime flags sorojax compiles and runs its own programs with; the
model's precomputed arrays are an argument of the program, the same in every call,
as inside ``simulate``. The
public ``forward_dynamics`` is also timed the same way (it computes the model's
constant arrays inside the call), and again in a loop compiled with
``sorojax.compiler_options(long_run=True)`` (XLA's YNNPACK fusions off: the options
for a program that runs many times).

Scenes:

* ``clamped rod``: ``sorojax.scenes.free_fall_rod()``: torsion and both bendings,
  cubic (12 DoF, 14 points), no contact;
* ``rod on floor``: ``benchmarks/contact.py``'s 0.3 m rod on a planar joint (9 DoF),
  without contact and with 10, 100 and 1000 floor samples;
* ``grasp``: ``examples/grasp.py``'s gripper (13 DoF: a prescribed palm, two cable-
  driven fingers, a free ball; contact with the floor and between the fingers and the
  ball), at rest with the fingers closed by 0.2 N of tension;
* ``rope of 10 divisions``: a free 0.3 m rope of ten cubic divisions (torsion, both
  bendings, linear stretch: 116 DoF, as cosseratbench's pile builds its rope), no
  contact, slightly bent; its mass matrix from composite inertias (the default for
  many coordinates in several groups) and again from the Jacobians (``Jacobians``).

Parts (each a function of the previous part's outputs), as the dynamics forms them:
``kinematics`` (poses and twists of the chain's points, their Jacobians and twist
rates, the leaves' steps and, with many leaves, their world positions and
velocities), ``mass`` (M from the Jacobians, or from composite inertias),
``contact`` (geometry, law and wrenches: the obstacles' on many leaves component by
component, at the leaves' chain points), ``mapping`` (every wrench to generalised
forces, through the leaves' steps), ``solve`` (the Cholesky solve or, with prescribed joints, the
saddle-point solve). ``flops`` are XLA's count for one call of a part
(``cost_analysis``).

Without ``--quick``, ``sample_ratio``: ``forward_dynamics`` of the rod with 1000
floor samples over the rod without contact (long-run options), the two loops timed
in turns, nine rounds: the median of the rounds' ratios.

The floor beside each evaluation: its flops at the rate this machine sustains on
fused float64 elementwise arithmetic (measured here: a degree-20 polynomial on 1e6
numbers), i.e. the time if the evaluation were flop-bound and perfectly fused.

Run::

    .venv/bin/python benchmarks/evaluation.py [--quick]

Writes ``benchmarks/results/evaluation.json``.
"""

import argparse
import contextlib
import json
import statistics
import sys
import time

import jax

import sorojax as sj  # runtime flags: set by _common (imported before any array)

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_enable_compilation_cache", False)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, environment  # noqa: E402

from sorojax.dynamics._composite import composite_mass, uses_composite  # noqa: E402
from sorojax.dynamics._contact import contact_loads, contact_pairs  # noqa: E402
from sorojax.dynamics._eom import (  # noqa: E402
    constrained_dynamics,
    mass_and_force,
    spd_solve,
)
from sorojax.dynamics._mass import _mass_from_J  # noqa: E402
from sorojax.dynamics._wrench_recursion import (  # noqa: E402
    force_from_point_rates,
    force_from_wrenches,
)
from sorojax.kinematics._recursion import chain_layout, point_rates  # noqa: E402
from sorojax.model import _precompute  # noqa: E402
from sorojax.model._precompute import LinkageData  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "examples"))
from contact import resting_rod  # noqa: E402


def _nudge(x, acc):
    """``x`` made to depend on the loop's carry (by a zero amount): no hoisting."""
    return jax.tree.map(lambda a: a + 0.0 * acc.astype(a.dtype), x)


def loop_program(fn, args, n, long_run=False):
    """``fn(*args)`` called ``n`` times in a compiled ``lax.fori_loop``: the
    compiled program (called with ``args``) and its compile time [s].

    A :class:`LinkageData` argument (the model's arrays) is the same in every call,
    as inside ``simulate``; the others are made to depend on the previous call.
    ``long_run``: compiled with ``sorojax.compiler_options(long_run=True)``.
    """
    fixed = [isinstance(a, LinkageData) for a in args]

    def run(args):
        def body(i, acc):
            moved = [
                a if f else _nudge(a, acc) for a, f in zip(args, fixed, strict=True)
            ]
            out = fn(*moved)
            leaves = jax.tree.leaves(out)
            return 1e-30 * sum(jnp.sum(x).astype(acc.dtype) for x in leaves)

        return jax.lax.fori_loop(0, n, body, jnp.zeros(()))

    opts = sj.compiler_options(long_run)  # as sorojax compiles its programs
    t0 = time.perf_counter()
    c = jax.jit(run, compiler_options=opts).lower(args).compile()
    return c, time.perf_counter() - t0


def per_call(fn, args, n, repeats, long_run=False):
    """Median time [s] of one ``fn(*args)`` inside a compiled loop of ``n`` calls
    (:func:`loop_program`), the compile time of that loop [s] and XLA's flop count
    of one call."""
    c, compile_s = loop_program(fn, args, n, long_run)
    opts = sj.compiler_options(long_run)
    one = jax.jit(fn, compiler_options=opts).lower(*args).compile()
    flops = one.cost_analysis().get("flops", np.nan)
    jax.block_until_ready(c(args))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(c(args))
        ts.append((time.perf_counter() - t0) / n)
    return statistics.median(ts), compile_s, float(flops)


def flop_rate(repeats=5) -> float:
    """Sustained float64 flop/s of a fused elementwise kernel on this machine."""
    x = jnp.linspace(0.0, 1.0, 1_000_000)

    def poly(x):
        y = jnp.ones_like(x)
        for k in range(20):
            y = y * x + (k + 1.0)
        return y

    f = jax.jit(poly, compiler_options=sj.compiler_options())
    jax.block_until_ready(f(x))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(x))
        ts.append(time.perf_counter() - t0)
    return 40 * x.size / min(ts)


def _grasp_state():
    from grasp import gripper

    lk = gripper()
    u = jnp.asarray([0.0, 0.2, 0.2])
    q = sj.solve_statics(lk, u=u, throw=False).q
    return lk, q, u


def scene_parts(name, lk, q, qd, u=None):
    """The parts of one evaluation as ``(label, function, arguments)``."""
    data = _precompute._precompute(lk)  # uncached: MIN_GROUP_DOF as set now
    t = jnp.zeros(())
    pr = point_rates(data, q, qd)
    lay = chain_layout(data)
    W = jnp.ones((lk.n_points, 6))
    if uses_composite(data):  # the rates' steps and chain terms, no Jacobian

        def mass(d, pr):
            return composite_mass(d, *pr.records, lay)

        def kinematics(d, q, qd):
            pr = point_rates(d, q, qd)
            k, ct = pr.records
            return pr.g, pr.eta, pr.etadot, k, ct._replace(relJ=None)

    else:

        def mass(d, pr):
            return _mass_from_J(d, pr.J, lay.row)

        def kinematics(d, q, qd):
            pr = point_rates(d, q, qd)
            if pr.leaf_frames is None:
                return pr
            # the leaves' world positions and velocities, not their poses and twists
            return pr.core, pr.J, pr.etadot, pr.leaves, pr.leaf_frames

    parts = [
        ("kinematics", kinematics, (data, q, qd)),
        ("mass", mass, (data, pr)),
    ]
    rows = None
    if lk.contact is not None:

        def contact(pr):
            return contact_loads(lk, t, pr, lay)

        parts.append(("contact", contact, (pr,)))
        rows = contact(pr)[1]
    # as mass_and_force (no point wrenches, hooks or actuators' wrenches here): W's
    # leaf rows are read where contacts between links may reach them
    on_leaves = lk.contact is not None and contact_pairs(lk)
    if rows is not None:
        rows = jnp.ones_like(rows)
    if uses_composite(data):

        def mapping(d, pr, W, rows):
            records = (*pr.records, lay, pr.leaves)
            return force_from_wrenches(d, records, W, rows, on_leaves)

    else:

        def mapping(d, pr, W, rows):
            return force_from_point_rates(d, pr, W, rows, on_leaves)

    parts.append(("mapping", mapping, (data, pr, W, rows)))
    if u is None:
        M, f = mass_and_force(lk, data, t, q, qd)
        parts.append(("solve", spd_solve, (M, f)))

        def whole(d, q, qd):
            return spd_solve(*mass_and_force(lk, d, t, q, qd))

    else:

        def whole(d, q, qd):
            return constrained_dynamics(lk, d, t, q, qd, lambda _: u).qdd

    parts.append(("evaluation", whole, (data, q, qd)))
    if name.endswith("Jacobians"):  # forward_dynamics would reuse its compiled trace
        return parts
    parts.append(("forward_dynamics", lambda q, qd: sj.forward_dynamics(lk, q, qd, u=u),
                  (q, qd)))  # fmt: skip
    return parts


def scenes(quick: bool):
    out = []
    lk = sj.scenes.free_fall_rod()
    q = jnp.asarray(sj.scenes.free_fall_q0(lk))
    out.append(("clamped rod", lk, q, jnp.full(lk.n_dof, 0.01), None))
    for n in (None, 10, 100) if quick else (None, 10, 100, 1000):
        lk = resting_rod(n)
        label = (
            "rod on floor, no contact" if n is None else f"rod on floor, {n} samples"
        )
        out.append((label, lk, jnp.zeros(lk.n_dof), jnp.full(lk.n_dof, 0.01), None))
    lk, q, u = _grasp_state()
    out.append(("grasp", lk, q, jnp.full(lk.n_dof, 0.01), u))
    lk = rope(10)
    q = 0.5 * jnp.sin(jnp.arange(lk.n_dof, dtype=float))
    out.append(("rope of 10 divisions", lk, q, jnp.full(lk.n_dof, 0.01), None))
    out.append(
        ("rope of 10 divisions, Jacobians", lk, q, jnp.full(lk.n_dof, 0.01), None)
    )
    return out


def rope(n_div: int) -> sj.Linkage:
    """A free rope of ``n_div`` cubic divisions (11 DoF each), as the pile's."""
    basis = sj.LegendreBasis((1, 1, 1, 1, 0, 0), (0, 3, 3, 1, 0, 0))
    sec = sj.CircularSection(0.005)
    link = sj.SoftLink(
        [sj.Division(0.3 / n_div, sec, basis) for _ in range(n_div)],
        sj.Material(E=1e6, rho=1000.0, eta=1e3),
        joint=sj.Joint("F"),
    )
    return sj.Linkage([link], gravity=(0.0, 0.0, -9.81))


@contextlib.contextmanager
def _jacobians(on: bool):
    """The mass matrix from the Jacobians (composite inertias off) while ``on``."""
    least = _precompute.MIN_GROUP_DOF
    if on:
        _precompute.MIN_GROUP_DOF = 10**9
    try:
        yield
    finally:
        _precompute.MIN_GROUP_DOF = least


def sample_ratio(rounds: int = 9, n: int = 200) -> dict:
    """``forward_dynamics`` of the rod with 1000 floor samples over the same rod
    without contact, both looped with the long-run options and timed in turns
    (``rounds`` each), so that the machine's drift meets both alike."""
    loops = {}
    for label, samples in (("no contact", None), ("1000 samples", 1000)):
        lk = resting_rod(samples)
        args = (jnp.zeros(lk.n_dof), jnp.full(lk.n_dof, 0.01))

        def fd(q, qd, lk=lk):
            return sj.forward_dynamics(lk, q, qd)

        c, _ = loop_program(fd, args, n, long_run=True)
        jax.block_until_ready(c(args))
        loops[label] = (c, args)
    times = {label: [] for label in loops}
    for _ in range(rounds):
        for label, (c, args) in loops.items():
            t0 = time.perf_counter()
            jax.block_until_ready(c(args))
            times[label].append((time.perf_counter() - t0) / n * 1e6)
    pairs = zip(times["1000 samples"], times["no contact"], strict=True)
    ratios = [a / b for a, b in pairs]
    out = {k: statistics.median(v) for k, v in times.items()}
    out["ratio"] = statistics.median(ratios)
    out["ratio_range"] = [min(ratios), max(ratios)]
    print(f"1000 samples against none, in turns: {out['1000 samples']:.1f} / "
          f"{out['no contact']:.1f} us = {out['ratio']:.2f}x "
          f"({min(ratios):.2f}-{max(ratios):.2f})")  # fmt: skip
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="no 1000-sample case")
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args()
    rate = flop_rate()
    print(f"fused elementwise float64 rate: {rate / 1e9:.2f} Gflop/s")
    rows = []
    for name, lk, q, qd, u in scenes(a.quick):
        n_samples = 0
        if lk.contact is not None:
            n_samples = len(sj.contact_state(lk, q).link)
        row = dict(scene=name, n_dof=lk.n_dof, n_points=lk.n_points,
                   n_contacts=n_samples, parts={})  # fmt: skip
        with _jacobians(name.endswith("Jacobians")):
            _scene_rows(name, lk, q, qd, u, row, a.repeats)
        ev = row["parts"]["evaluation"]
        row["floor_us"] = ev["flops"] / rate * 1e6
        print(f"{name:28s} floor (flops / rate) {row['floor_us']:.1f} us")
        rows.append(row)
    ratio = None if a.quick else sample_ratio()
    res = environment(flop_rate=rate, scenes=rows, sample_ratio=ratio)
    out = ROOT / "benchmarks" / "results" / "evaluation.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print(f"wrote {out}")


def _scene_rows(name, lk, q, qd, u, row, repeats):
    """Time every part of one scene into ``row["parts"]``."""
    for label, fn, args in scene_parts(name, lk, q, qd, u):
        n = 2000 if lk.n_points < 200 else 200
        sec, comp, flops = per_call(fn, args, n, repeats)
        row["parts"][label] = dict(us=sec * 1e6, flops=flops, compile_s=comp)
        print(f"{name:28s} {label:17s} {sec * 1e6:9.1f} us {flops / 1e3:9.1f} kflop")
        if label == "forward_dynamics":  # also as a long run's program
            sec, comp, flops = per_call(fn, args, n, repeats, long_run=True)
            row["parts"]["forward_dynamics_long_run"] = dict(
                us=sec * 1e6, flops=flops, compile_s=comp
            )
            print(f"{name:28s} {'(long-run options)':17s} {sec * 1e6:9.1f} us")


if __name__ == "__main__":
    main()
