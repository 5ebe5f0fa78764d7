"""Contact: cost, compile time, W with the contact tangent, stiffness, accuracy.

Five measurements, all in this process (persistent compilation cache off):

1. ``cost``: warm time of one evaluation of the dynamics (``forward_dynamics``: the
   right-hand side every solver step evaluates once per stage) of a rod resting on a
   floor with about 10, 100 and 1000 contact samples, against the same rod without
   contact (the rod's own points: 12). Compile time of each program.
2. ``compile``: first call of ``simulate`` (0.2 s, ROS34PW2 and Tsit5) of the
   dropped rod with and without its floor, and the XLA compile time of its
   integration program (JAX's compile log), which computes the contact report
   (``Trajectory.contact``) too.
3. ``w_tangent``: ROS34PW2 with W = (M, K, D) against W with the contacts' stiffness
   and damping (``Contact.tangent_in_w``), and Tsit5, on a block held by friction on
   a 15-degree plane and on a rod dropped onto a floor: steps and warm time.
4. ``stiffness``: the block on the plane at contact stiffnesses 1e3 .. 1e7 N/m:
   steps of Tsit5 (explicit: bounded by the contact's frequency) and of ROS34PW2
   with the contact tangent in W.
5. ``fixed_steps``: where methods fail: the block on the plane at constant steps
   (0.1 to 10 ms) for contact stiffnesses 1e3 .. 1e7 N/m, Tsit5 against ROS34PW2
   with the contact tangent in W: the largest step at which the block stays on
   the plane (finite, no penetration deeper than 1 mm) for 0.5 s.
6. ``touchdown``: the heavy cantilever resting on a frictionless floor against the
   elastica reference (tests/contact_reference.py) as the contact stiffness rises:
   centre-line error, clamp force error, where the contact zone starts, and the
   equivalent touchdown point (that of a rigid floor whose reaction has the same
   resultant force and moment, ``contact_reference.equivalent_touchdown``).
7. ``laws``: the penalty against the barrier law (``ContactLaw.kind``) on the heavy
   cantilever (statics: errors, Newton iterations, closest approach) and on the
   rod dropped onto the floor (dynamics: Tsit5 and ROS34PW2 steps, warm time,
   deepest penetration or smallest gap, energy drift).
8. ``statics_stiffness``: contact statics from the reference shape at penalty
   stiffnesses 1e3 .. 1e10 with the default settings, on the three scenes of
   ``tests/stiff_contact_scenes.py`` (a heavy cantilever on a floor, a rod over a
   sphere, two crossing rods): result, Newton iterations, stiffness stages, deepest
   penetration, the centre line's change from the decade below (its convergence
   to the rigid limit), first and warm call times.

Run::

    .venv/bin/python benchmarks/contact.py [--repeats 5] [--part laws ...]

Writes ``benchmarks/results/contact.json`` and ``benchmarks/results/contact.png`` (and
the docs' ``docs/img/contact-statics-stiffness.png``).
"""

import argparse
import json
import logging
import re
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_enable_compilation_cache", False)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, environment, timed  # noqa: E402

import sorojax as sj  # noqa: E402

sys.path.insert(0, str(ROOT / "tests"))
from contact_reference import (  # noqa: E402
    equivalent_touchdown,
    heavy_cantilever_on_floor,
)
from stiff_contact_scenes import SCENES, centre_line  # noqa: E402

G = 9.81


def resting_rod(n_samples: int | None):
    """A 0.3 m rod (r = 1 cm) on a floor sampled at ``n_samples`` points (None: none)."""
    rod = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2)
            )
        ],
        sj.Material(E=1e6, poisson=0.5, rho=1000.0, eta=1e3),
        joint=sj.Joint("A", axis=(0, 1, 0)),
    )
    place = np.eye(4)
    place[2, 3] = 0.01
    contact = None
    if n_samples is not None:
        law = sj.ContactLaw(stiffness=1e4, smoothing=1e-4, damping=10.0,
                            static_friction=0.5)  # fmt: skip
        contact = sj.Contact(sj.Plane(), law, spacing=0.3 / (n_samples - 1))
    return sj.Linkage(
        [rod], placements=place[None], gravity=(0, 0, -G), contact=contact
    )


def cost(repeats):
    out = []
    fd = eqx.filter_jit(lambda lk, q, qd: sj.forward_dynamics(lk, q, qd))
    for n in (None, 10, 100, 1000):
        lk = resting_rod(n)
        q = jnp.zeros(lk.n_dof)
        qd = jnp.full(lk.n_dof, 0.01)
        t0 = time.perf_counter()
        jax.block_until_ready(fd(lk, q, qd))
        first = time.perf_counter() - t0
        med, best = timed(fd, lk, q, qd, repeats=max(repeats, 20))
        n_contacts = 0 if lk.contact is None else len(sj.contact_state(lk, q).link)
        out.append(dict(samples=n_contacts, n_points=lk.n_points, n_dof=lk.n_dof,
                        first_call_s=first, warm_median_s=med, warm_min_s=best))  # fmt: skip
        print(f"cost: {n_contacts:5d} contacts, {lk.n_points:5d} points: first "
              f"{first:.2f} s, warm {med * 1e6:.0f} us")  # fmt: skip
    return out


def dropped(contact: bool, tangent: bool = True, stiffness=1e4):
    lk = resting_rod(31 if contact else None)
    place = np.eye(4)
    place[2, 3] = 0.05
    c = lk.contact
    if c is not None:
        law = sj.ContactLaw(stiffness=stiffness, smoothing=1e-4, damping=10.0)
        c = sj.Contact(c.obstacles, law, spacing=c.spacing, tangent_in_w=tangent)
    return sj.Linkage(lk.links, placements=place[None], gravity=(0, 0, -G), contact=c)


class _CompileLog(logging.Handler):
    """Collects JAX's "Finished XLA compilation of jit(NAME) in T sec" records."""

    pattern = re.compile(r"Finished XLA compilation of jit\((\w+)\) in ([0-9.e-]+) sec")

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.seconds: dict[str, float] = {}

    def emit(self, record):
        m = self.pattern.search(record.getMessage())
        if m:
            self.seconds[m[1]] = self.seconds.get(m[1], 0.0) + float(m[2])


def compile_share():
    """First ``simulate`` call without and with the floor, for ROS34PW2 and Tsit5,
    and the XLA compile seconds of its integration program (``_simulate``, which
    also computes the contact report)."""
    out = {}
    jax.config.update("jax_log_compiles", True)
    logger = logging.getLogger("jax")
    for solver in ("ros34pw2", "tsit5"):
        for contact in (False, True):
            lk = dropped(contact)
            q0 = jnp.zeros(lk.n_dof).at[0].set(0.1)
            log = _CompileLog()
            logger.addHandler(log)
            t0 = time.perf_counter()
            sj.simulate(lk, 0.2, q0, solver=solver, n_save=3)
            first = time.perf_counter() - t0
            logger.removeHandler(log)
            key = solver + ("_with_contact" if contact else "_without_contact")
            out[key] = dict(
                first_call_s=first,
                integration_compile_s=log.seconds.get("_simulate", float("nan")),
            )
        a, b = out[solver + "_without_contact"], out[solver + "_with_contact"]
        print(f"compile {solver}: first simulate {a['first_call_s']:.1f} s without "
              f"contact, {b['first_call_s']:.1f} s with; integration program "
              f"{a['integration_compile_s']:.1f} -> {b['integration_compile_s']:.1f} s")  # fmt: skip
    jax.config.update("jax_log_compiles", False)
    return out


def block(alpha_deg, stiffness=1e4, tangent=True):
    alpha = np.radians(alpha_deg)
    n = np.array([-np.sin(alpha), 0.0, np.cos(alpha)])
    c, s = np.cos(alpha), np.sin(alpha)
    place = np.eye(4)
    place[:3, :3] = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
    place[:3, 3] = n * 0.01
    body = sj.RigidLink(sj.Joint("F"), length=0.04, mass=0.1,
                        inertia=np.diag([1e-5] * 3), g_i=np.eye(4), g_f=np.eye(4))  # fmt: skip
    law = sj.ContactLaw(stiffness=stiffness, smoothing=1e-5,
                        damping=2 * np.sqrt(stiffness * 0.1 / 4),
                        static_friction=0.5, stick_velocity=1e-3)  # fmt: skip
    contact = sj.Contact(sj.Plane(normal=n), law,
                         shapes={1: sj.ContactBox((0.02, 0.02, 0.01))},
                         tangent_in_w=tangent)  # fmt: skip
    return sj.Linkage([body], placements=place[None], gravity=(0, 0, -G),
                      contact=contact)  # fmt: skip


def run_sim(lk, q0, t1, solver, repeats):
    kw = dict(solver=solver, n_save=11, rtol=1e-5, atol=1e-8, max_steps=400_000,
              throw=False)  # fmt: skip
    t0 = time.perf_counter()
    tr = sj.simulate(lk, t1, q0, **kw)
    first = time.perf_counter() - t0
    med, _ = timed(lambda: sj.simulate(lk, t1, q0, **kw).q, repeats=repeats,
                   warmup=False)  # fmt: skip
    return dict(steps=int(tr.num_steps), result=int(tr.result._value),
                first_call_s=first, warm_median_s=med)  # fmt: skip


def w_tangent(repeats):
    out = []
    cases = [
        ("block_15deg_held", lambda tw: block(15.0, tangent=tw),
         lambda lk: jnp.zeros(lk.n_dof), 1.0),
        ("rod_dropped", lambda tw: dropped(True, tw),
         lambda lk: jnp.zeros(lk.n_dof).at[0].set(0.1), 1.0),
    ]  # fmt: skip
    for name, make, q0f, t1 in cases:
        for solver, tw in (("ros34pw2", False), ("ros34pw2", True), ("tsit5", False)):
            lk = make(tw)
            r = run_sim(lk, q0f(lk), t1, solver, repeats)
            label = solver + (" + contact W" if tw else "")
            out.append(dict(scene=name, solver=label) | r)
            print(f"W: {name:18s} {label:22s} {r['steps']:7d} steps, warm "
                  f"{r['warm_median_s']:.3f} s")  # fmt: skip
    return out


def stiffness(repeats):
    out = []
    for k in (1e3, 1e4, 1e5, 1e6, 1e7):
        for solver in ("tsit5", "ros34pw2"):
            lk = block(15.0, stiffness=k)
            r = run_sim(lk, jnp.zeros(lk.n_dof), 0.5, solver, 1)
            out.append(dict(stiffness=k, solver=solver) | r)
            print(f"stiffness {k:8.0e} N/m {solver:9s}: {r['steps']:7d} steps, "
                  f"result {r['result']}, warm {r['warm_median_s']:.3f} s")  # fmt: skip
    return out


def fixed_steps():
    out = []
    steps = (1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
    for k in (1e3, 1e4, 1e5, 1e6, 1e7):
        for solver in ("tsit5", "ros34pw2"):
            lk = block(15.0, stiffness=k)
            stable = []
            for dt in steps:
                tr = sj.simulate(lk, 0.5, jnp.zeros(lk.n_dof), solver=solver,
                                 dt0=dt, adaptive=False, n_save=11, throw=False,
                                 max_steps=10_000)  # fmt: skip
                cs = tr.contact
                ok = (
                    int(tr.result._value) == 0
                    and bool(jnp.all(jnp.isfinite(tr.q)))
                    and float(jnp.max(cs.penetration)) < 1e-3
                )
                stable.append(ok)
            largest = max([dt for dt, ok in zip(steps, stable, strict=True) if ok],
                          default=0.0)  # fmt: skip
            out.append(dict(stiffness=k, solver=solver, steps=list(steps),
                            stable=stable, largest_stable_step=largest))  # fmt: skip
            print(f"fixed steps k={k:8.0e} {solver:9s}: stable at "
                  f"{[dt for dt, ok in zip(steps, stable, strict=True) if ok]}")  # fmt: skip
    return out


def cantilever_on_floor(law, L=1.0, EI=0.05, w=1.0, d=0.05, r=0.01):
    """The heavy cantilever 4 x order-3 bending divisions, clamped d + r above a
    floor of the given law, solved; errors against the elastica reference."""
    ref = heavy_cantilever_on_floor(L, EI, w, d)
    divs = [sj.Division(L / 4, sj.CircularSection(r),
                        sj.LegendreBasis((0, 1, 0, 0, 0, 0), 3)) for _ in range(4)]  # fmt: skip
    rod = sj.SoftLink(divs, sj.Material(E=EI / (np.pi * r**4 / 4), poisson=0.5,
                                        rho=w / (np.pi * r**2 * G)))  # fmt: skip
    place = np.eye(4)
    place[2, 3] = d + r
    lk = sj.Linkage([rod], placements=place[None], gravity=(0, 0, -G),
                    contact=sj.Contact(sj.Plane(), law, spacing=0.01))  # fmt: skip
    t0 = time.perf_counter()
    sol = sj.solve_statics(lk, max_steps=200, throw=False)
    first = time.perf_counter() - t0
    g = np.asarray(sj.forward_kinematics(lk, sol.q))
    lay = lk.layout
    pts = np.where(lay.point_kind == 2)[0]
    s = (lay.point_division[pts] - 1 + lay.point_X1[pts]) * L / 4
    err = np.max(np.hypot(g[pts, 0, 3] - np.interp(s, ref["s"], ref["x"]),
                          g[pts, 2, 3] - np.interp(s, ref["s"], ref["z"]) - r))  # fmt: skip
    cs = sol.contact
    fz = w * L - float(cs.total_force()[2])
    on = np.asarray(cs.normal_force) > 0
    a_eq = equivalent_touchdown(np.asarray(cs.force)[:, 2],
                                np.asarray(cs.point)[:, 0], w, L, g[-1, 0, 3])  # fmt: skip
    return dict(result=int(sol.result._value), newton=int(sol.num_steps),
                first_call_s=first, shape_error_L=err / L,
                clamp_force_rel_error=abs(fz / ref["clamp_force"][1] - 1),
                contact_start_x=float(np.min(np.asarray(cs.point)[on, 0])),
                touchdown_x=float(ref["x"][-1] - (L - ref["a"])),
                equivalent_touchdown=a_eq,
                touchdown_error_L=abs(a_eq - ref["a"]) / L,
                deepest_penetration=float(np.max(np.asarray(cs.penetration)[on])),
                touchdown_a=ref["a"])  # fmt: skip


def touchdown():
    out = []
    for k in (1e4, 1e5, 1e6, 1e7):
        row = dict(stiffness=k) | cantilever_on_floor(
            sj.ContactLaw(stiffness=k, smoothing=1e-7)
        )
        out.append(row)
        print(f"touchdown k={k:8.0e}: shape {row['shape_error_L']:.2e} L, clamp force "
              f"{row['clamp_force_rel_error']:.1e}, contact from x = "
              f"{row['contact_start_x']:.4f}, equivalent touchdown "
              f"{row['equivalent_touchdown']:.4f} (rigid floor: a = "
              f"{row['touchdown_a']:.4f}, error {row['touchdown_error_L']:.1e} L), "
              f"{row['newton']} Newton")  # fmt: skip
    return out


LAWS = {
    # name: (ContactLaw keywords for the cantilever (w = 1 N/m), for the dropped
    # rod (w = 3.1 N/m)); the barrier's reach 1e-4 m = 1e-2 of the radius, its
    # k g_hat near the load per length
    "penalty": (dict(stiffness=1e6, smoothing=1e-7),
                dict(stiffness=1e4, smoothing=1e-4, damping=10.0)),
    "penalty_stiff": (dict(stiffness=1e7, smoothing=1e-7),
                      dict(stiffness=1e6, smoothing=1e-5, damping=10.0)),
    "barrier": (dict(stiffness=1e4, smoothing=1e-4, kind="barrier"),
                dict(stiffness=3e4, smoothing=1e-4, damping=10.0, kind="barrier")),
    "barrier_tight": (dict(stiffness=1e5, smoothing=1e-5, kind="barrier"),
                      dict(stiffness=3e5, smoothing=1e-5, damping=10.0,
                           kind="barrier")),
}  # fmt: skip


def laws(repeats):
    out = []
    for name, (static_kw, dynamic_kw) in LAWS.items():
        st = cantilever_on_floor(sj.ContactLaw(**static_kw))
        print(f"law {name:14s} statics: shape {st['shape_error_L']:.1e} L, clamp "
              f"force {st['clamp_force_rel_error']:.1e}, touchdown "
              f"{st['touchdown_error_L']:.1e} L, closest {st['deepest_penetration']:.1e}"
              f" m, {st['newton']} Newton, first call {st['first_call_s']:.1f} s")  # fmt: skip
        row = dict(law=name, statics=st, dynamics={})
        for solver in ("tsit5", "ros34pw2"):
            lk = dropped(True)
            lk = sj.Linkage(lk.links, placements=lk.placements, gravity=(0, 0, -G),
                            contact=sj.Contact(lk.contact.obstacles,
                                               sj.ContactLaw(**dynamic_kw),
                                               spacing=lk.contact.spacing))  # fmt: skip
            q0 = jnp.zeros(lk.n_dof).at[0].set(0.1)
            r = run_sim(lk, q0, 1.0, solver, repeats)
            tr = sj.simulate(lk, 1.0, q0, solver=solver, n_save=201, rtol=1e-5,
                             atol=1e-8, max_steps=400_000, throw=False)  # fmt: skip
            e = np.asarray(jax.vmap(lambda q, v, lk=lk: sj.total_energy(lk, q, v))(
                tr.q, tr.qd))  # fmt: skip
            r |= dict(deepest_penetration=float(jnp.max(tr.contact.penetration)),
                      largest_energy_rise_rel=float(np.max(np.diff(e)) / abs(e[0])),
                      energy_end_rel=float(e[-1] / e[0]))  # fmt: skip
            row["dynamics"][solver] = r
            print(f"law {name:14s} {solver:9s}: {r['steps']:6d} steps, warm "
                  f"{r['warm_median_s']:.3f} s, deepest {r['deepest_penetration']:.1e}"
                  f" m, energy rise {r['largest_energy_rise_rel']:.1e}")  # fmt: skip
        out.append(row)
    return out


def statics_stiffness(repeats):
    out = []
    for name, build in SCENES.items():
        prev = None
        for k in 10.0 ** np.arange(3, 11):
            lk = build(jnp.asarray(k))
            t0 = time.perf_counter()
            sol = sj.solve_statics(lk, throw=False, warn_unstable=False)
            first = time.perf_counter() - t0
            warm, _ = timed(
                lambda lk=lk: sj.solve_statics(lk, throw=False, warn_unstable=False).q,
                repeats=repeats,
                warmup=False,
            )
            c = centre_line(lk, sol.q)
            pen = np.asarray(sol.contact.penetration)
            row = dict(
                scene=name, stiffness=float(k), result=str(sol.result),
                converged=bool(sol.result == sj.RESULTS.successful),
                newton=int(sol.num_steps), residual=float(sol.residual_norm),
                deepest_penetration=float(pen.max()),
                centre_line_change_m=(
                    None if prev is None else float(np.max(np.abs(c - prev)))
                ),
                first_call_s=first, warm_median_s=warm,
            )  # fmt: skip
            prev = c
            out.append(row)
            print(f"statics {name:20s} k {k:7.0e}: {row['newton']:4d} Newton, "
                  f"{'converged' if row['converged'] else row['result']}, deepest "
                  f"{row['deepest_penetration']:.2e} m, change "
                  f"{row['centre_line_change_m'] or float('nan'):.2e} m, warm "
                  f"{warm:.2f} s")  # fmt: skip
    return out


def statics_panel(ax, ss):
    """Newton iterations against the stiffness, a line per scene (x: failed)."""
    for name in dict.fromkeys(r["scene"] for r in ss):
        rows = [r for r in ss if r["scene"] == name]
        ax.plot([r["stiffness"] for r in rows], [r["newton"] for r in rows], "o-",
                label=name.replace("_", " "))  # fmt: skip
        bad = [r for r in rows if not r["converged"]]
        ax.plot([r["stiffness"] for r in bad], [r["newton"] for r in bad], "kx")
    ax.set(xscale="log", xlabel="penalty stiffness [N/m^2 on rods, N/m rod pairs]",
           ylabel="Newton iterations (default settings)",
           title="contact statics from the reference shape")  # fmt: skip
    if ss:
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8)


def statics_chart(ss, path):
    """The docs' figure of :func:`statics_panel`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.8))
    statics_panel(ax, ss)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def chart(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 6, figsize=(25, 3.8))
    c = res["cost"]
    ax[0].plot([r["samples"] for r in c[1:]], [r["warm_median_s"] * 1e6 for r in c[1:]],
               "o-", label="with contact")  # fmt: skip
    ax[0].axhline(c[0]["warm_median_s"] * 1e6, color="k", ls="--", label="no contact")
    ax[0].set(xscale="log", yscale="log", xlabel="contact samples",
              ylabel="one dynamics evaluation [us]", title="cost")  # fmt: skip
    ax[0].legend()
    st = res["stiffness"]
    for solver in ("tsit5", "ros34pw2"):
        rows = [r for r in st if r["solver"] == solver]
        ax[1].plot([r["stiffness"] for r in rows], [r["steps"] for r in rows], "o-",
                   label=solver + (" (contact in W)" if solver == "ros34pw2" else ""))  # fmt: skip
    ax[1].set(xscale="log", yscale="log", xlabel="contact stiffness [N/m]",
              ylabel="steps for 0.5 s", title="block held on a 15 deg plane")  # fmt: skip
    ax[1].legend()
    fs = res["fixed_steps"]
    for solver in ("tsit5", "ros34pw2"):
        rows = [r for r in fs if r["solver"] == solver]
        ax[3].plot([r["stiffness"] for r in rows],
                   [max(r["largest_stable_step"], 1e-5) for r in rows], "o-",
                   label=solver + (" (contact in W)" if solver == "ros34pw2" else ""))  # fmt: skip
    ax[3].set(xscale="log", yscale="log", xlabel="contact stiffness [N/m]",
              ylabel="largest stable constant step [s]",
              title="where methods fail (block, 0.5 s)")  # fmt: skip
    ax[3].legend()
    td = res["touchdown"]
    ax[2].plot([r["stiffness"] for r in td], [r["shape_error_L"] for r in td], "o-",
               label="centre line (max) / L")  # fmt: skip
    ax[2].plot([r["stiffness"] for r in td], [r["clamp_force_rel_error"] for r in td],
               "s-", label="clamp force (rel.)")  # fmt: skip
    ax[2].plot([r["stiffness"] for r in td], [r["touchdown_error_L"] for r in td],
               "^-", label="equivalent touchdown / L")  # fmt: skip
    ax[2].plot([r["stiffness"] for r in td],
               [abs(r["contact_start_x"] - r["touchdown_x"]) for r in td], "v:",
               label="where contact starts (x) / L")  # fmt: skip
    ax[2].set(xscale="log", yscale="log", xlabel="contact stiffness [N/m^2]",
              title="heavy cantilever on a floor vs elastica")  # fmt: skip
    ax[2].legend()
    lw = res.get("laws", [])
    for j, solver in enumerate(("tsit5", "ros34pw2")):
        x = np.arange(len(lw)) + (j - 0.5) * 0.38
        ax[4].bar(x, [r["dynamics"][solver]["steps"] for r in lw], 0.38,
                  label=solver)  # fmt: skip
    for i, r in enumerate(lw):
        ax[4].annotate(f"{r['dynamics']['tsit5']['deepest_penetration']:.0e} m",
                       (i, r["dynamics"]["tsit5"]["steps"]), ha="center",
                       va="bottom", fontsize=7)  # fmt: skip
    ax[4].set_xticks(np.arange(len(lw)), [r["law"] for r in lw], fontsize=8)
    ax[4].set(yscale="log", ylabel="steps for 1 s",
              title="rod dropped: law (deepest penetration)")  # fmt: skip
    ax[4].legend()
    statics_panel(ax[5], res.get("statics_stiffness", []))
    fig.tight_layout()
    fig.savefig(path, dpi=110)


PARTS = {
    "cost": lambda a: cost(a.repeats),
    "compile": lambda a: compile_share(),
    "w_tangent": lambda a: w_tangent(a.repeats),
    "stiffness": lambda a: stiffness(a.repeats),
    "fixed_steps": lambda a: fixed_steps(),
    "touchdown": lambda a: touchdown(),
    "laws": lambda a: laws(a.repeats),
    "statics_stiffness": lambda a: statics_stiffness(a.repeats),
}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--part", choices=tuple(PARTS), action="append",
                   help="run only these parts (repeatable): the others keep their "
                        "saved results")  # fmt: skip
    a = p.parse_args()
    out = ROOT / "benchmarks" / "results" / "contact.json"
    res = json.loads(out.read_text()) if a.part and out.exists() else {}
    env = environment()
    for name in a.part or PARTS:
        res[name] = PARTS[name](a)
        res.setdefault("environments", {})[name] = env
    res["environment"] = env
    out.write_text(json.dumps(res, indent=1))
    chart(res, ROOT / "benchmarks" / "results" / "contact.png")
    if res.get("statics_stiffness"):
        statics_chart(
            res["statics_stiffness"],
            ROOT / "docs" / "img" / "contact-statics-stiffness.png",
        )
    print("wrote", out)


if __name__ == "__main__":
    main()
