"""The soft grasp's speed against MuJoCo: the same scene, 1 s simulated, warm.

The scene is ``examples/grasp.py`` (imported, its numbers read from its linkage): a
palm on a prescribed vertical slide, two soft fingers (8 cm, r 6 mm, E 1 MPa, rho
1100, eta 500 Pa s) curled toward a free 2 cm, 20 g ball by a cable 4 mm off their
axis (tension ramped to T over 0.3 s), friction 0.8, a floor; the palm lifts 5 cm
between 0.4 and 0.8 s.

* **sorojax**: ``examples.grasp.grasp`` at T = 4 N, by default with ROS34PW2 (the
  contacts' tangent in W) at rtol 1e-3, atol 1e-6 (``--solver``, ``--rtol``,
  ``--atol``; the example's own Tsit5 at 1e-4 / 1e-7 takes 2.3x the steps). Its
  first call (trace, compile and one run; persistent compilation cache off) and its
  warm calls are timed; compile = first call - warm median. These programs are
  compiled at XLA's default level (``_common.py``: ``SOROJAX_COMPILE=full``) and
  after the reference's; a user's first call, the example's own
  ``grasp(gripper(), T, t1)`` in a fresh process in the default compile tiers, is
  timed apart (``sorojax_fresh_first_call_s``, ``--repeats`` processes).
* **MuJoCo** (the ``mujoco`` package; MJCF written here as a string):

  - each finger a ``<composite type="cable">`` of ``--segments`` capsules (default 8:
    1 cm, the spacing of sorojax's contact samples) with the
    ``mujoco.elasticity.cable`` plugin (bend = E, twist = G = E / (2 (1 + nu))); the
    plugin gives joint k (k >= 1) the stiffness EI / ds and none to the joint at the
    palm, so that joint gets a spring of its own, 2 EI / ds (the clamp's half cell).
    With it the cable's tip sags under its own weight within 1.1 % of w L^4 / (8 EI)
    and a free finger curled by 4 N * 4 mm ends within 1e-3 L of the exact circle
    (``cantilever_check``); material damping as joint damping 3 eta I / ds (sorojax's
    bending damping is 3 eta I per length, ``section_matrices``);
  - the cable as what it is in a bending-only rod: a uniform internal moment T d
    (the cable's length changes by d times the bending angle, so its virtual work
    is T d times the angles), applied as a motor on every joint of the finger
    (joint at the palm included) about its bending axis, gear d, control T;
  - the palm a slide joint with a position actuator (kp, kv = critical for the
    carried mass) whose target is the prescribed height plus kv / kp times its rate
    (no lag while it moves); its tracking error is reported;
  - contact: MuJoCo's soft constraints, elliptic cones, mu 0.8 everywhere, time
    constant sqrt(m_ball / k) (the frequency of sorojax's penalty k = 2e3 N/m
    under the ball), damping ratio 1 (sorojax's contact damping, 1 N s/m, is
    lighter: ratio 0.08), ``impratio`` 10 (friction constraints stiffer than the
    normal ones, MuJoCo's knob against the creep of soft friction; at its default
    1 the held ball slips about 1 mm by 1 s, also reported). The fingers touch the
    ball and the floor, not each other;
  - integrator ``implicitfast``; the timestep is the largest of a sweep at which
    the grasp ends within 1 mm of the finest step's ball height and slip;
  - timed both as a Python loop of ``mj_step`` (controls written each step) and
    as ``mujoco.rollout`` (the same controls precomputed, stepped in C++).

sorojax's own step is swept the same way (``--sj-dts``, default 8, 4 and 2 ms):
the largest whose lift and slip end within 1 mm of its adaptive reference is timed
too (``sorojax_largest_step``), beside the example's default 2 ms step.

Timing: the CPU is shared, so the warm runs are interleaved (``interleaved``):
each round times MuJoCo 5 + 5 times, one warm sorojax run, MuJoCo again; the
ratio of each round and their median are reported beside the medians and minima.

PyElastica (installed, 1.0) is not in the comparison, though it could express the
scene with parts of its own: rod-sphere contact with friction
(``RodSphereContact``), a frictionless rigid-body-plane contact for the ball on the
floor (``InteractionPlaneRigidBody``), rod-plane contact for the fingertips, a
boundary condition written for the moving palm and a tip torque for the cable. It
would differ more than MuJoCo does: its rods stretch and shear (the fingers here
bend only), its dampers act on the nodes' velocities (``dissipation``), not on the
strain rate as eta does, and its explicit symplectic stepper's step is bounded by
the 1 MPa rod's axial wave across an element.

Run::

    .venv/bin/python benchmarks/grasp_peers.py [--repeats 3] [--t1 1.0] [--tension 4]

Writes ``benchmarks/results/grasp_peers.json`` (overwritten) and prints a table.
"""

import argparse
import json
import os
import statistics
import sys
import time

os.environ.setdefault("SOROJAX_CACHE_DIR", "off")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_enable_compilation_cache", False)

import mujoco  # noqa: E402
import mujoco.rollout  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, environment  # noqa: E402

sys.path.insert(0, str(ROOT / "examples"))
import grasp as ex  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "grasp_peers.json"
T_LIFT = 0.4  # the lift starts (examples/grasp.py: inputs)


def scene():
    """The grasp's numbers, read from ``examples/grasp.py``'s linkage."""
    lk = ex.gripper()
    finger, mat = lk.links[1], lk.links[1].material
    law = lk.contact.law
    place = np.asarray(lk.placements)
    return dict(
        L=float(finger.length), r=ex.R_FINGER, E=float(mat.E),
        poisson=float(mat.poisson), rho=float(mat.rho), eta=float(mat.eta),
        d=float(lk.actuators[1].route[0].path.z), m_palm=float(lk.links[0].mass),
        m_ball=float(lk.links[3].mass), R_ball=ex.R_BALL, palm_z=float(place[0, 2, 3]),
        finger_x=float(place[2, 0, 3]), mu=float(law.static_friction),
        k=float(law.stiffness), c=float(law.damping), lift=ex.LIFT, g=ex.G,
    )  # fmt: skip


def palm_height(t, p):
    """The prescribed palm height [m] above its start and its rate [m/s]."""
    s = np.clip((t - T_LIFT) / 0.4, 0.0, 1.0)
    rate = np.where((t > T_LIFT) & (t < T_LIFT + 0.4), p["lift"] / 0.4, 0.0)
    return p["lift"] * s, rate


def tension(t, T):
    """The cables' tension [N]: a ramp to ``T`` over 0.3 s."""
    return T * np.clip(t / 0.3, 0.0, 1.0)


# ------------------------------------------------------------------------ MuJoCo
def _finger(name, x, p, n_seg, flip):
    """MJCF of one finger: a cable hanging from the palm, local z toward the ball."""
    ds = p["L"] / n_seg
    area, inertia = np.pi * p["r"] ** 2, np.pi * p["r"] ** 4 / 4
    # base frame: x down the finger, z toward the ball (sorojax's cable side)
    xy = "0 0 -1 0 -1 0" if flip else "0 0 -1 0 1 0"
    shear = p["E"] / (2 * (1 + p["poisson"]))
    return f"""
      <body name="{name}base" pos="{x} 0 0" xyaxes="{xy}">
        <composite type="cable" prefix="{name}" curve="s" count="{n_seg + 1} 1 1"
                   size="{p["L"]}" initial="ball">
          <plugin plugin="mujoco.elasticity.cable">
            <config key="twist" value="{shear}"/>
            <config key="bend" value="{p["E"]}"/>
          </plugin>
          <joint kind="main" damping="{3 * p["eta"] * inertia / ds}"/>
          <geom type="capsule" size="{p["r"]}" mass="{p["rho"] * area * ds}"
                contype="2" conaffinity="1"/>
        </composite>
      </body>"""


def mjcf(p, n_seg, dt, impratio, kp=2e4):
    """The grasp as MJCF: floor, palm on a slide, two cable fingers, a free ball."""
    carried = p["m_palm"] + p["m_ball"] + 2 * p["rho"] * np.pi * p["r"] ** 2 * p["L"]
    kv = 2 * np.sqrt(kp * carried)
    tc = np.sqrt(p["m_ball"] / p["k"])
    joints = [f"J_{i}" for i in range(1, n_seg - 1)]
    motors = "\n".join(
        f'    <motor name="{f}{j}" joint="{f}{j}" gear="0 -{p["d"]} 0"/>'
        for f in "LR"
        for j in ["J_first", *joints, "J_last"]
    )
    return f"""
<mujoco model="grasp">
  <extension><plugin plugin="mujoco.elasticity.cable"/></extension>
  <option timestep="{dt}" integrator="implicitfast" cone="elliptic"
          impratio="{impratio}" gravity="0 0 {-p["g"]}"/>
  <default>
    <geom friction="{p["mu"]} 0.005 0.0001" solref="{tc} 1" condim="3"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0.3 0.3 0.01" contype="1" conaffinity="3"/>
    <body name="palm" pos="0 0 {p["palm_z"]}">
      <joint name="palm" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{p["m_palm"]}" diaginertia="1e-5 1e-5 1e-5"/>
      {_finger("L", -abs(p["finger_x"]), p, n_seg, False)}
      {_finger("R", abs(p["finger_x"]), p, n_seg, True)}
    </body>
    <body name="ball" pos="0 0 {p["R_ball"]}">
      <freejoint/>
      <geom type="sphere" size="{p["R_ball"]}" mass="{p["m_ball"]}"
            contype="1" conaffinity="2"/>
    </body>
  </worldbody>
  <actuator>
    <position name="palm" joint="palm" kp="{kp}" kv="{kv}"/>
{motors}
  </actuator>
</mujoco>"""


def mj_model(p, n_seg, dt, impratio):
    """Compiled model with the clamp springs (2 EI / ds at the palm's joints)."""
    m = mujoco.MjModel.from_xml_string(mjcf(p, n_seg, dt, impratio))
    EI = p["E"] * np.pi * p["r"] ** 4 / 4
    for f in "LR":
        m.jnt_stiffness[m.joint(f"{f}J_first").id] = 2 * EI / (p["L"] / n_seg)
    return m


def mj_controls(m, p, T, t1):
    """Per-step controls ``(n_step, nu)``: palm target, then every joint's tension."""
    dt = m.opt.timestep
    n = int(round(t1 / dt))
    t = np.arange(n) * dt  # the control held over step k starts at t_k
    h, rate = palm_height(t, p)
    act = m.actuator("palm")
    kp, kv = act.gainprm[0], -act.biasprm[2]
    U = np.empty((n, m.nu))
    U[:, 0] = h + kv / kp * rate
    U[:, 1:] = tension(t, T)[:, None]
    return U


def mj_rollout(m, U):
    """``(times, qpos)`` of one rollout from rest; the state after every step."""
    d = mujoco.MjData(m)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, s0, spec)
    state, _ = mujoco.rollout.rollout(m, d, s0, U[None])
    return state[0, :, 0], state[0, :, 1 : 1 + m.nq]


def mj_loop(m, U):
    """A Python loop of ``mj_step`` writing the controls each step."""
    d = mujoco.MjData(m)
    for u in U:
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
    return d


def mj_outcome(m, t, qpos, p):
    """Ball lift and slip [mm], the palm's largest tracking error, whether it held."""
    zb = qpos[:, m.jnt_qposadr[m.body("ball").jntadr[0]] + 2]
    zp = qpos[:, m.jnt_qposadr[m.joint("palm").id]]
    # MuJoCo resets a diverged simulation to its start: time must rise throughout
    finite = bool(np.all(np.isfinite(qpos)) and np.all(np.diff(t) > 0))
    if not finite:
        return dict(finite=False)
    z0 = p["R_ball"]  # the ball's start height
    k4 = np.searchsorted(t, T_LIFT - 1e-12)
    h, _ = palm_height(t, p)
    return dict(
        finite=True,
        lift_mm=1e3 * (zb[-1] - z0),
        slip_mm=1e3 * ((zp[-1] - 0.0) - (zb[-1] - zb[k4])),
        palm_tracking_max_mm=1e3 * float(np.max(np.abs(zp - h))),
        ball_height_mm={f"{s:.1f}": 1e3 * float(np.interp(s, t, zb))
                        for s in (0.3, 0.4, 0.6, 0.8, t[-1])},
    )  # fmt: skip


def cantilever_check(p, n_seg):
    """The MuJoCo finger (clamp spring included) against the rod's closed forms.

    Horizontal and clamped: tip sag under its own weight against w L^4 / (8 EI),
    and, without gravity, the tip under the cable's moment T d at 4 N against the
    exact circle (radius EI / (T d)). Settled by a heavy joint damping.
    """
    L, r = p["L"], p["r"]
    EI, w = p["E"] * np.pi * r**4 / 4, p["rho"] * np.pi * r**2 * L * p["g"] / L
    out = {}
    for case in ("weight", "moment"):
        g = -p["g"] if case == "weight" else 0.0
        xml = f"""<mujoco>
  <extension><plugin plugin="mujoco.elasticity.cable"/></extension>
  <option timestep="2e-4" integrator="implicitfast" gravity="0 0 {g}"/>
  <worldbody>{_finger("L", 0.0, p, n_seg, False).replace('xyaxes="0 0 -1 0 1 0"',
                                                       'xyaxes="1 0 0 0 1 0"')}
  </worldbody>
</mujoco>"""  # fmt: skip
        m = mujoco.MjModel.from_xml_string(xml)
        ds = L / n_seg
        m.jnt_stiffness[m.joint("LJ_first").id] = 2 * EI / ds
        m.dof_damping[:] *= 50.0  # settle fast: the statics are what is compared
        d = mujoco.MjData(m)
        M = 4.0 * p["d"]
        tip = m.body("LB_last").id
        for _ in range(10000):
            if case == "moment":
                d.xfrc_applied[tip, 3:] = (0.0, -M, 0.0)
            mujoco.mj_step(m, d)
        R = d.xmat[tip].reshape(3, 3)
        end = d.xpos[tip] + R[:, 0] * ds
        if case == "weight":
            out["self_weight_sag_over_euler_bernoulli"] = float(
                -end[2] / (w * L**4 / (8 * EI))
            )
        else:
            kap = M / EI
            exact = np.array([np.sin(kap * L), 0.0, (1 - np.cos(kap * L))]) / kap
            out["curled_tip_error_over_L"] = float(np.linalg.norm(end - exact) / L)
    return out


def mujoco_part(p, T, t1, n_seg, dts, impratio):
    """Timestep sweep; the chosen step's model, controls and physics."""
    sweep = []
    for dt in dts:
        m = mj_model(p, n_seg, dt, impratio)
        U = mj_controls(m, p, T, t1)
        t0 = time.perf_counter()
        t, qpos = mj_rollout(m, U)
        wall = time.perf_counter() - t0
        row = dict(dt=dt, steps=len(U), rollout_s=wall) | mj_outcome(m, t, qpos, p)
        sweep.append(row)
        print(f"MuJoCo dt {dt:.1e}: " + (
            f"lift {row['lift_mm']:.2f} mm, slip {row['slip_mm']:.2f} mm, "
            f"{wall:.2f} s" if row["finite"] else "not finite"))  # fmt: skip
    ref = sweep[int(np.argmin(dts))]
    ok = [
        r for r in sweep
        if r["finite"] and abs(r["lift_mm"] - ref["lift_mm"]) < 1.0
        and abs(r["slip_mm"] - ref["slip_mm"]) < 1.0
    ]  # fmt: skip
    best = max(ok, key=lambda r: r["dt"])
    # the same step with MuJoCo's default impratio 1: softer friction, more slip
    m = mj_model(p, n_seg, best["dt"], 1.0)
    soft = mj_outcome(m, *mj_rollout(m, mj_controls(m, p, T, t1)), p)
    m = mj_model(p, n_seg, best["dt"], impratio)
    res = dict(
        segments=n_seg, nv=m.nv, impratio=impratio, timestep_sweep=sweep,
        timestep=best["dt"],
        largest_finite_timestep=max(r["dt"] for r in sweep if r["finite"]),
        steps=best["steps"], physics={k: best[k] for k in best if k not in (
            "dt", "steps", "rollout_s")},
        physics_impratio_1=soft, cantilever_check=cantilever_check(p, n_seg),
    )  # fmt: skip
    return res, m, mj_controls(m, p, T, t1)


# ----------------------------------------------------------------------- sorojax
def sorojax_part(T, t1, solver="rosenbrock_euler", dt=2e-3, rtol=1e-3, atol=1e-6):
    """The first call of ``examples.grasp.grasp``; its outcome; a warm-run closure.

    ``dt`` None: adaptive steps at ``rtol``, ``atol``; else constant steps of ``dt``.
    """
    lk = ex.gripper()
    kw = dict(solver=solver, dt=dt, rtol=rtol, atol=atol)
    t0 = time.perf_counter()
    tr, ball, palm = ex.grasp(lk, T, t1, **kw)
    first = time.perf_counter() - t0
    t = np.asarray(tr.t)
    k4 = np.searchsorted(t, T_LIFT - 1e-12)
    res = dict(
        n_dof=int(lk.n_dof), solver=solver, dt=dt,
        rtol=None if dt else rtol, atol=None if dt else atol,
        steps=int(tr.num_steps), rejected_steps=int(tr.num_rejected_steps),
        first_call_s=first,
        physics=dict(
            lift_mm=1e3 * float(ball[-1] - ball[0]),
            slip_mm=1e3 * float((palm[-1] - palm[0]) - (ball[-1] - ball[k4])),
            ball_height_mm={f"{s:.1f}": 1e3 * float(np.interp(s, t, ball))
                            for s in (0.3, 0.4, 0.6, 0.8, t[-1])},
        ),
    )  # fmt: skip
    return res, lambda: ex.grasp(lk, T, t1, **kw)


_FRESH = """
import os, sys, time
sys.path.insert(0, {examples!r})
import jax
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_enable_compilation_cache", False)
import sorojax as sj
sj.set_runtime_flags()
import grasp as ex
lk = ex.gripper()
t0 = time.perf_counter()
jax.block_until_ready(ex.grasp(lk, {T!r}, {t1!r}))
print(time.perf_counter() - t0)
"""


def fresh_first_call(T, t1, repeats):
    """``examples.grasp.grasp``'s first call as a user meets it: a fresh process
    each, sorojax's default compile tiers (``SOROJAX_COMPILE`` unset), JAX's
    persistent cache off, the example's own settings. Seconds, one per process."""
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "SOROJAX_COMPILE"}
    code = _FRESH.format(examples=str(ROOT / "examples"), T=T, t1=t1)
    out = []
    for _ in range(repeats):
        r = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                           capture_output=True, text=True)  # fmt: skip
        out.append(float(r.stdout.split()[-1]))
    return out


def step_sweep(T, t1, solver, dts, ref):
    """sorojax's constant steps ``dts``: the largest whose ball ends within 1 mm.

    MuJoCo's step is chosen the same way (:func:`mujoco_part`), against its own
    finest; sorojax's against its adaptive reference ``ref`` (ROS34PW2 at rtol
    1e-4). Returns that step's row with a warm-run closure (``run``), and the
    sweep; None when no step is within 1 mm.
    """
    sweep, best = [], None
    for dt in sorted(dts, reverse=True):
        try:
            row, run = sorojax_part(T, t1, solver, dt)
        except RuntimeError as err:  # e.g. RESULTS.unstable_step
            sweep.append(dict(dt=dt, within_1mm=False, failed=str(err)[:200]))
            print(f"sorojax dt {dt:.1e}: failed ({str(err)[:80]})")
            continue
        ph = row["physics"]
        dev = {k: ph[k] - ref["physics"][k] for k in ("lift_mm", "slip_mm")}
        finite = bool(np.isfinite(ph["lift_mm"]) and np.isfinite(ph["slip_mm"]))
        within = finite and all(abs(v) < 1.0 for v in dev.values())
        sweep.append(dict(dt=dt, steps=row["steps"], lift_mm=ph["lift_mm"],
                          slip_mm=ph["slip_mm"], deviation_mm=dev,
                          within_1mm=within))  # fmt: skip
        print(f"sorojax dt {dt:.1e}: lift {ph['lift_mm']:.2f} mm, slip "
              f"{ph['slip_mm']:.2f} mm" + ("" if within else " (not within 1 mm)"))  # fmt: skip
        if within and best is None:
            best = dict(sweep[-1], run=run)
    if best is None:
        return None
    return best | dict(sweep=sweep)


def batch_part(p, m, T_grid, t1, dt, repeats):
    """``len(T_grid)`` grasps at once: one jit of a ``vmap`` of the constant-step
    grasp (lockstep: every case takes the same steps) against ``mujoco.rollout`` of
    the same tensions on all CPU threads. Warm medians; the compile apart."""
    import equinox as eqx
    import jax.numpy as jnp

    import sorojax as sj

    lk = ex.gripper()
    cm = lk.layout.links[3].cm_point

    def one(T):
        u = eqx.Partial(ex.inputs, tension=T)
        tr = sj.simulate(lk, t1, u=u, solver="rosenbrock_euler", dt0=dt, n_save=2,
                         max_steps=int(np.ceil(t1 / dt)) + 1, throw=False)  # fmt: skip
        ball = sj.forward_kinematics(lk, tr.q[-1])[cm, 2, 3]
        return ball - ex.R_BALL, tr.result._value

    run = jax.jit(jax.vmap(one), compiler_options=sj.compiler_options())
    Ts = jnp.asarray(T_grid)
    t0 = time.perf_counter()
    lift, code = jax.block_until_ready(run(Ts))
    first = time.perf_counter() - t0
    sj_t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(Ts))
        sj_t.append(time.perf_counter() - t0)
    n_thread = os.cpu_count() or 1
    datas = [mujoco.MjData(m) for _ in range(n_thread)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, datas[0], s0, spec)
    U = np.stack([mj_controls(m, p, float(T), t1) for T in T_grid])
    mj_t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, _ = mujoco.rollout.rollout(m, datas, s0[None], U)
        mj_t.append(time.perf_counter() - t0)
    zb = state[:, -1, 1 + m.jnt_qposadr[m.body("ball").jntadr[0]] + 2]
    n = len(T_grid)
    med = statistics.median
    return dict(
        cases=n, tensions=[float(T) for T in T_grid], dt=dt,
        sorojax_first_call_s=first, sorojax_warm_median_s=med(sj_t),
        sorojax_cases_per_s=n / med(sj_t),
        sorojax_failed=int(np.sum(np.asarray(code) != 0)),
        sorojax_lift_mm=[1e3 * float(x) for x in lift],
        mujoco_threads=n_thread, mujoco_rollout_median_s=med(mj_t),
        mujoco_cases_per_s=n / med(mj_t),
        mujoco_lift_mm=[1e3 * float(z - p["R_ball"]) for z in zb],
        ratio_of_medians=med(sj_t) / med(mj_t),
    )  # fmt: skip


def interleaved(run_sj, m, U, repeats, n_mj=5):
    """Warm times in rounds: MuJoCo, one sorojax run, MuJoCo again.

    Each MuJoCo block is ``n_mj`` rollouts and ``n_mj`` loops. The machine's load
    moves between rounds (the CPU is shared): each round's ratio is the sorojax run
    over the median of the rollouts just before and after it.
    """

    def mj_block():
        r, lp = [], []
        for _ in range(n_mj):
            t0 = time.perf_counter()
            mj_rollout(m, U)
            r.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            mj_loop(m, U)
            lp.append(time.perf_counter() - t0)
        return r, lp

    sj_t, roll, loop, ratios = [], [], [], []
    for k in range(repeats):
        r1, l1 = mj_block()
        t0 = time.perf_counter()
        run_sj()
        sj_t.append(time.perf_counter() - t0)
        r2, l2 = mj_block()
        roll, loop = roll + r1 + r2, loop + l1 + l2
        ratios.append(sj_t[-1] / statistics.median(r1 + r2))
        print(f"round {k + 1}: sorojax {sj_t[-1]:.2f} s, MuJoCo rollout "
              f"{statistics.median(r1 + r2):.3f} s: {ratios[-1]:.2f}x")  # fmt: skip
    med = statistics.median
    return dict(
        sorojax_warm_s=sj_t, sorojax_warm_median_s=med(sj_t),
        sorojax_warm_min_s=min(sj_t), mujoco_rollout_median_s=med(roll),
        mujoco_rollout_min_s=min(roll), mujoco_loop_median_s=med(loop),
        mujoco_loop_min_s=min(loop), round_ratios=ratios,
        ratio_median_of_rounds=med(ratios),
        ratio_of_medians_rollout=med(sj_t) / med(roll),
        ratio_of_medians_loop=med(sj_t) / med(loop),
        ratio_of_minima_rollout=min(sj_t) / min(roll),
    )  # fmt: skip


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--t1", type=float, default=1.0)
    ap.add_argument("--tension", type=float, default=4.0)
    ap.add_argument("--solver", default="rosenbrock_euler")
    ap.add_argument(
        "--dt",
        type=float,
        default=2e-3,
        help="constant step [s]; 0: adaptive steps at --rtol, --atol",
    )
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--atol", type=float, default=1e-6)
    ap.add_argument("--batch", type=int, default=64,
                    help="grasps over tensions 3-5 N in one vmap (0: skip)")  # fmt: skip
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--impratio", type=float, default=10.0)
    ap.add_argument("--dts", type=float, nargs="+",
                    default=[4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4])  # fmt: skip
    ap.add_argument("--sj-dts", type=float, nargs="*", default=[8e-3, 4e-3, 2e-3],
                    help="sorojax's constant steps swept for the largest within "
                    "1 mm of its adaptive reference (no values: no sweep)")  # fmt: skip
    a = ap.parse_args(argv)
    # MuJoCo's warnings (the sweep's diverging steps) printed, not logged to a file
    mujoco.set_mju_user_warning(lambda msg: print(f"MuJoCo: {msg}"))
    env = environment(mujoco_version=mujoco.__version__, cpu_model=_cpu_model())
    p = scene()
    mj, m, U = mujoco_part(p, a.tension, a.t1, a.segments, a.dts, a.impratio)
    dt = a.dt or None
    # a user's first call (fresh processes, default tiers), before this process
    # compiles anything of sorojax's
    fresh = fresh_first_call(a.tension, a.t1, a.repeats)
    # the accuracy reference: adaptive ROS34PW2 at rtol 1e-4 (one run)
    ref, _ = sorojax_part(a.tension, a.t1, "ros34pw2", None, 1e-4, 1e-7)
    sj_, run_sj = sorojax_part(a.tension, a.t1, a.solver, dt, a.rtol, a.atol)
    sj_["deviation_from_reference_mm"] = {
        k: sj_["physics"][k] - ref["physics"][k] for k in ("lift_mm", "slip_mm")
    }
    largest = None
    if dt is not None and a.sj_dts:
        largest = step_sweep(a.tension, a.t1, a.solver, a.sj_dts, ref)
    tm = interleaved(run_sj, m, U, a.repeats)
    sj_ |= dict(
        warm_median_s=tm["sorojax_warm_median_s"], warm_min_s=tm["sorojax_warm_min_s"],
        compile_s=sj_["first_call_s"] - tm["sorojax_warm_median_s"],
        warm_per_step_ms=1e3 * tm["sorojax_warm_median_s"] / sj_["steps"],
    )  # fmt: skip
    mj |= dict(
        rollout_median_s=tm["mujoco_rollout_median_s"],
        rollout_min_s=tm["mujoco_rollout_min_s"],
        loop_median_s=tm["mujoco_loop_median_s"], loop_min_s=tm["mujoco_loop_min_s"],
        rollout_per_step_ms=1e3 * tm["mujoco_rollout_median_s"] / mj["steps"],
    )  # fmt: skip
    if largest is not None:  # the largest step within 1 mm, timed the same way
        run_big = largest.pop("run")
        tb = interleaved(run_big, m, U, a.repeats)
        largest |= dict(
            warm_median_s=tb["sorojax_warm_median_s"],
            warm_per_step_ms=1e3 * tb["sorojax_warm_median_s"] / largest["steps"],
            mujoco_rollout_median_s=tb["mujoco_rollout_median_s"],
            round_ratios=tb["round_ratios"],
            ratio_median_of_rounds=tb["ratio_median_of_rounds"],
        )  # fmt: skip
    batch = None
    if a.batch:
        batch = batch_part(p, m, np.linspace(3.0, 5.0, a.batch), a.t1, dt or 2e-3,
                           a.repeats)  # fmt: skip
    res = dict(
        what=f"examples/grasp.py at T = {a.tension:g} N for {a.t1:g} s: sorojax "
        "against MuJoCo",
        t1=a.t1, tension=a.tension, scene=p, sorojax=sj_, sorojax_reference=ref,
        sorojax_largest_step=largest, mujoco=mj, timing=tm, batch=batch,
        sorojax_fresh_first_call_s=fresh,
        environment=env | {"load_average_at_end": list(os.getloadavg())},
    )  # fmt: skip
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=1))
    _table(res)
    print(f"wrote {OUT}")
    return res


def _cpu_model():
    """The CPU's model name (Linux), or None."""
    try:
        with open("/proc/cpuinfo") as f:
            return next(ln.split(":", 1)[1].strip() for ln in f if "model name" in ln)
    except (OSError, StopIteration):
        return None


def _table(res):
    s, m, t1 = res["sorojax"], res["mujoco"], res["t1"]
    n_s, n_m = s["steps"], m["steps"]
    how = f"dt {s['dt']:g} s" if s["dt"] else f"rtol {s['rtol']:g}"
    r = res["sorojax_reference"]
    rows = [
        (f"sorojax ({s['solver']}, {how})", n_s, s["warm_median_s"], s["compile_s"],
         s["physics"]),
        ("sorojax reference (ros34pw2, 1e-4)", r["steps"], r["first_call_s"], None,
         r["physics"]),
        (f"MuJoCo rollout (dt {m['timestep']:g} s)", n_m, m["rollout_median_s"],
         None, m["physics"]),
        (f"MuJoCo mj_step loop (dt {m['timestep']:g} s)", n_m, m["loop_median_s"],
         None, m["physics"]),
    ]  # fmt: skip
    print(f"\n{'':34s} {'steps':>6s} {'warm s':>7s} {'per sim s':>9s} "
          f"{'ms/step':>8s} {'compile s':>9s} {'lift mm':>8s} {'slip mm':>8s}")  # fmt: skip
    for name, n, w, c, ph in rows:
        cs = "-" if c is None else f"{c:.1f}"
        print(f"{name:34s} {n:6d} {w:7.3f} {w / t1:9.3f} {1e3 * w / n:8.3f} {cs:>9s} "
              f"{ph['lift_mm']:8.2f} {ph['slip_mm']:8.2f}")  # fmt: skip
    tm = res["timing"]
    print(
        f"sorojax warm / MuJoCo rollout: {tm['ratio_median_of_rounds']:.2f}x "
        f"(median of the rounds' ratios; {min(tm['round_ratios']):.2f}-"
        f"{max(tm['round_ratios']):.2f}x); the reference's row: its first call"
    )
    big = res.get("sorojax_largest_step")
    if big:
        print(
            f"sorojax at its largest step within 1 mm of its reference "
            f"({big['dt']:g} s, {big['steps']} steps; lift {big['lift_mm']:.2f}, "
            f"slip {big['slip_mm']:.2f} mm): {big['warm_median_s']:.3f} s, "
            f"{big['ratio_median_of_rounds']:.2f}x MuJoCo's rollout "
            f"({min(big['round_ratios']):.2f}-{max(big['round_ratios']):.2f}x)"
        )
    fresh = res["sorojax_fresh_first_call_s"]
    print(
        "sorojax's first call in a fresh process (the example as a user runs it: "
        "default compile tiers, cache off): "
        + ", ".join(f"{x:.1f}" for x in fresh)
        + f" s (median {statistics.median(fresh):.1f} s)"
    )
    b = res["batch"]
    if b:
        print(f"{b['cases']} grasps: sorojax vmap {b['sorojax_cases_per_s']:.1f} "
              f"cases/s ({b['sorojax_warm_median_s']:.2f} s, compile "
              f"{b['sorojax_first_call_s'] - b['sorojax_warm_median_s']:.1f} s), "
              f"MuJoCo rollout on {b['mujoco_threads']} threads "
              f"{b['mujoco_cases_per_s']:.1f} cases/s: "
              f"{b['ratio_of_medians']:.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
