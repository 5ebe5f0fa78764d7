"""Learning through the simulator: an MLP policy that moves a cable-driven arm's tip.

What this example teaches: how to wrap a model as a :class:`sorojax.Environment`,
roll a policy out with ``jax.lax.scan`` over ``Environment.step``, differentiate a
loss through whole rollouts (analytic policy gradients: no reinforcement-learning
estimator, the simulator's exact derivatives) and train an equinox model on them
with optax's Adam.

The four-cable tapered arm of ``cable_manipulator.py`` (hanging under gravity,
material damping) becomes an environment (control period 50 ms, tensions held over
a period and clipped at zero). An equinox MLP maps the observation (coordinates,
velocities, tip position, target) to the four tensions (softplus: never negative).
The loss is the mean squared tip distance to the target over a 1 s episode (later
periods weighted more) plus a small effort term, averaged over a batch of targets
(``jax.vmap``); ``jax.value_and_grad`` gives its gradient with respect to the MLP's
weights, and ``optax.adam`` turns the gradients into steps (optax is in sorojax's
``learn`` extra: ``pip install sorojax[learn]``).

Targets are reachable by construction: the equilibrium tip positions of random
tension vectors (one batched statics solve). The trained policy is evaluated on
held-out targets against two PD controllers on the lateral tip position (the law of
``cable_manipulator.py``): with the *exact* feedforward tensions of each target (an
oracle: the tensions that generated it) and without feedforward (pretension only).

Run::

    python examples/learn_reach.py [--iterations 150] [--batch 64] [--out DIR]
"""

import argparse
import functools
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import optax  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import cable_manipulator  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

ETA = 3e4  # material damping [Pa s], as cable_manipulator.py
PERIOD = 0.05  # control period [s]
EPISODE = 20  # periods per episode (1 s)
T_MAX = 12.0  # tensions of the random targets: uniform in [0, T_MAX] N
KP, KD, PRETENSION = 20.0, 20.0, 1.0  # the PD law of cable_manipulator.py


def make_env(order: int = 0) -> sj.Environment:
    """The arm as an environment (constant ROS34PW2 steps of one period)."""
    arm = cable_manipulator(order=order, eta=ETA)
    return sj.Environment(arm, period=PERIOD, dt=PERIOD)


def random_tensions(key, n: int):
    """``n`` random tension sets ``(n, 4)`` [N]: two random cables of four pull."""
    k1, k2 = jax.random.split(key)
    T = T_MAX * jax.random.uniform(k1, (n, 4))
    keep = jax.vmap(lambda k: jax.random.permutation(k, jnp.array([1.0, 1, 0, 0])))(
        jax.random.split(k2, n)
    )
    return T * keep


def targets_of(env: sj.Environment, T):
    """Reachable targets ``(n, 3)`` [m]: the equilibrium tips under tensions ``T``.

    One vmapped statics program for every set (the training pool and the held-out
    targets in one call: one trace and compile, not two).
    """

    def tip(T_i):
        sol = sj.solve_statics(env.linkage, u=T_i, throw=False)
        return sj.tip_pose(env.linkage, sol.q)[:3, 3], sol.result._value

    tips, results = sj.jit(jax.vmap(tip))(T)  # run once: -O0 tier
    if np.any(np.asarray(results) != 0):
        raise RuntimeError("a target's statics solve failed")
    return tips


class Policy(eqx.Module):
    """MLP: (q, qd, tip, target - tip) -> tensions >= 0 [N]."""

    mlp: eqx.nn.MLP
    scale: float = eqx.field(static=True)

    def __init__(self, n_dof: int, key, width: int = 64, depth: int = 2):
        self.mlp = eqx.nn.MLP(
            2 * n_dof + 6, 4, width, depth, activation=jnp.tanh, key=key
        )
        self.scale = T_MAX / 2

    def __call__(self, env, state, target):
        """Tensions [N] for ``state`` of ``env`` and a target tip position [m]."""
        tip = env.tip_position(state)
        obs = jnp.concatenate([state.q, 0.1 * state.qd, tip, 10.0 * (target - tip)])
        return self.scale * jax.nn.softplus(self.mlp(obs))


def episode(env, policy, s0, target):
    """Tip positions after each period under ``policy`` (a scan over steps)."""

    def body(s, _):
        s1 = env.step(s, policy(env, s, target))
        return s1, (env.tip_position(s1), s1.u, s1.result)

    _, (tips, u, results) = jax.lax.scan(body, s0, None, length=EPISODE)
    return tips, u, results


WEIGHTS = jnp.linspace(0.2, 1.0, EPISODE) ** 2  # later periods count more


def loss_fn(policy, env, s0, targets):
    """Weighted mean squared tip distance [m^2] (+ effort) over a batch of targets."""
    tips, u, _ = jax.vmap(lambda t: episode(env, policy, s0, t))(targets)
    d2 = jnp.sum((tips - targets[:, None]) ** 2, axis=-1)
    return jnp.mean(d2 * WEIGHTS[None]) / jnp.mean(WEIGHTS) + 1e-7 * jnp.mean(u**2)


def pd_policy(env, state, target, T_ff, feedforward):
    """The PD law of cable_manipulator.py (lateral tip position) as a policy.

    ``feedforward``: 1.0 adds the target's exact tensions ``T_ff``, 0.0 only the
    pretension (an array, so both variants share one compiled program).
    """

    def split(f):
        return jnp.stack([f[1], f[0], -f[1], -f[0]])

    tip, v = env.tip_position(state), env.tip_velocity(state)
    f = KP * (target[:2] - tip[:2]) - KD * v[:2]
    base = feedforward * T_ff + (1.0 - feedforward) * PRETENSION * jnp.ones(4)
    return jnp.maximum(base + split(f) / 2, 0.0)


def evaluate(env, s0, targets, T_ff, policy=None, feedforward=None):
    """Final tip error [m] per target, and tip paths.

    Under ``policy``, else the PD law with ``feedforward`` (a scalar or one value
    per target).
    """

    def one(target, T, ff):
        if policy is not None:
            tips, _, res = episode(env, policy, s0, target)
        else:
            tips, _, res = episode(
                env, lambda e, s, t: pd_policy(e, s, t, T, ff), s0, target
            )
        return jnp.linalg.norm(tips[-1] - target), tips, jnp.max(res)

    ff = jnp.broadcast_to(0.0 if feedforward is None else feedforward, len(targets))
    err, tips, res = jax.jit(jax.vmap(one), compiler_options=sj.compiler_options())(
        targets, T_ff, ff
    )
    if np.any(np.asarray(res) != 0):
        raise RuntimeError("an evaluation episode failed")
    return np.asarray(err), np.asarray(tips)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=150, help="Adam steps")
    ap.add_argument("--batch", type=int, default=64, help="targets per step")
    ap.add_argument("--held-out", type=int, default=64, help="evaluation targets")
    ap.add_argument("--lr", type=float, default=3e-3, help="Adam learning rate")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    out = pathlib.Path(args.out)
    png = out / "learn_reach.png"
    if png.exists() and not args.overwrite:
        raise SystemExit(f"{png} exists; pass --overwrite to replace it.")
    sj.enable_compilation_cache()
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    env = make_env()
    s0 = env.reset(jax.random.key(0))
    key = jax.random.key(args.seed)
    k_pol, k_train, k_test = jax.random.split(key, 3)
    # a pool of training targets, resampled per step (one statics batch)
    pool_T = random_tensions(k_train, 16 * args.batch)
    test_T = random_tensions(k_test, args.held_out)
    tips = np.asarray(targets_of(env, np.concatenate([pool_T, test_T])))
    # split on the host (a slice of a JAX array would compile an operation each)
    pool, test_targets = (jnp.asarray(a) for a in np.split(tips, [len(pool_T)]))
    policy = Policy(env.linkage.n_dof, k_pol)
    # the MLP's arrays are trained; its structure (activation, sizes) stays static
    params, static = eqx.partition(policy, eqx.is_array)
    optimiser = optax.adam(args.lr)
    opt_state = optimiser.init(params)

    @functools.partial(jax.jit, compiler_options=sj.compiler_options())
    def train_step(params, opt_state, key):
        idx = jax.random.choice(key, pool.shape[0], (args.batch,), replace=False)
        loss, grads = jax.value_and_grad(
            lambda p: loss_fn(eqx.combine(p, static), env, s0, pool[idx])
        )(params)
        updates, opt_state = optimiser.update(grads, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, loss

    losses, t_compile = [], None
    keys = jax.random.split(jax.random.key(args.seed + 1), args.iterations)
    t_train = time.perf_counter()
    for k in range(args.iterations):
        params, opt_state, loss = train_step(params, opt_state, keys[k])
        losses.append(float(loss))
        if k == 0:
            t_compile = time.perf_counter() - t_train
    t_train = time.perf_counter() - t_train
    policy = eqx.combine(params, static)

    err_mlp, tips_mlp = evaluate(env, s0, test_targets, test_T, policy=policy)
    # both PD variants in one batch: one compiled program
    n_test = len(test_targets)
    err_pd2, tips_pd2 = evaluate(
        env,
        s0,
        jnp.concatenate([test_targets, test_targets]),
        jnp.concatenate([test_T, test_T]),
        feedforward=jnp.repeat(jnp.array([1.0, 0.0]), n_test),
    )
    err_ff, tips_ff, err_pd = err_pd2[:n_test], tips_pd2[:n_test], err_pd2[n_test:]
    hanging = np.asarray(env.tip_position(s0))
    spread = float(
        np.median(np.linalg.norm(np.asarray(test_targets) - hanging, axis=1))
    )
    res = {
        "n_dof": env.linkage.n_dof,
        "iterations": args.iterations,
        "batch": args.batch,
        "loss_first": losses[0],
        "loss_last": float(np.mean(losses[-10:])),
        "losses": np.asarray(losses),
        "target_distance_median_m": spread,
        "mlp_error_median_m": float(np.median(err_mlp)),
        "mlp_error_p90_m": float(np.quantile(err_mlp, 0.9)),
        "pd_ff_error_median_m": float(np.median(err_ff)),
        "pd_error_median_m": float(np.median(err_pd)),
        "train_seconds": t_train,
        "first_step_seconds": t_compile,
        "seconds": time.perf_counter() - start,
    }
    print(
        f"{res['n_dof']} DoF arm, {args.iterations} Adam steps x {args.batch} "
        f"targets: loss {res['loss_first']:.2e} -> {res['loss_last']:.2e} m^2; "
        f"training {t_train:.1f} s (first step incl. compile {t_compile:.1f} s)"
    )
    print(
        f"held-out targets ({args.held_out}, median {1e3 * spread:.0f} mm from the "
        f"hanging tip), tip error after {EPISODE * PERIOD:.1f} s, median: MLP "
        f"{1e3 * res['mlp_error_median_m']:.1f} mm (90th pct "
        f"{1e3 * res['mlp_error_p90_m']:.1f}), PD + exact feedforward "
        f"{1e3 * res['pd_ff_error_median_m']:.1f} mm, PD "
        f"{1e3 * res['pd_error_median_m']:.1f} mm"
    )
    _plot(res, test_targets, tips_mlp, tips_ff, err_mlp, err_ff, err_pd, png)
    print(f"wrote {png}")
    return res


def _plot(res, targets, tips_mlp, tips_ff, err_mlp, err_ff, err_pd, path):
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    ax[0].semilogy(res["losses"])
    ax[0].set_xlabel("Adam step")
    ax[0].set_ylabel("loss [m$^2$]")
    ax[0].set_title(f"training ({res['batch']} targets per step)")
    targets = np.asarray(targets)
    for i in range(min(8, len(targets))):
        (line,) = ax[1].plot(*tips_mlp[i, :, :2].T, lw=1)
        ax[1].plot(*tips_ff[i, :, :2].T, ":", lw=1, color=line.get_color())
        ax[1].plot(*targets[i, :2], "x", color=line.get_color())
    ax[1].set_xlabel("x [m]")
    ax[1].set_ylabel("y [m]")
    ax[1].set_aspect("equal")
    ax[1].set_title("tip paths: MLP (solid), PD + feedforward (dotted)")
    bins = np.logspace(-5, -0.5, 30)
    for e, name in (
        (err_mlp, "MLP"),
        (err_ff, "PD + exact feedforward"),
        (err_pd, "PD"),
    ):
        ax[2].hist(np.maximum(e, 1e-5), bins=bins, histtype="step", label=name)
    ax[2].set_xscale("log")
    ax[2].set_xlabel(f"tip error after {EPISODE * PERIOD:.1f} s [m]")
    ax[2].set_ylabel("held-out targets")
    ax[2].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
