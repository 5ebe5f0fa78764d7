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

Data-parallel training over processes: :func:`make_train_step` splits each batch
evenly over the processes of a ``jax.distributed`` run (``--processes N
--process-id P --port PORT``, one command per process, on one machine); each
process differentiates its share's summed loss over the whole batch size, and
``sorojax.process_sum`` adds the shares' losses and gradients, so every process
applies the same Adam update (in one process the step is one compiled program).
``--checkpoint FOLDER`` saves the step, the weights, Adam's state and the losses
every ``--checkpoint-every`` steps (:func:`train`); a run with the same folder and
arguments resumes from the last save.

Run::

    python examples/learn_reach.py [--iterations 150] [--batch 64] [--out DIR]
        [--checkpoint FOLDER] [--processes N --process-id P --port PORT]
"""

import argparse
import functools
import json
import os
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


def episode(env, policy, s0, target, periods=EPISODE):
    """Tip positions after each period under ``policy`` (a scan over steps)."""

    def body(s, _):
        s1 = env.step(s, policy(env, s, target))
        return s1, (env.tip_position(s1), s1.u, s1.result)

    _, (tips, u, results) = jax.lax.scan(body, s0, None, length=periods)
    return tips, u, results


def loss_fn(policy, env, s0, targets, batch=None, periods=EPISODE):
    """Summed loss of ``targets`` over ``batch`` (default: their number) [m^2].

    A target's loss is its weighted mean squared tip distance over the episode
    (later periods weighted more) plus a small effort term; with ``batch`` the
    size of the whole batch, the losses of its shares add up to its mean loss.
    """
    weights = np.linspace(0.2, 1.0, periods) ** 2  # later periods count more
    tips, u, _ = jax.vmap(lambda t: episode(env, policy, s0, t, periods))(targets)
    d2 = jnp.sum((tips - targets[:, None]) ** 2, axis=-1)
    per_target = jnp.mean(d2 * weights[None], axis=1) / np.mean(weights)
    per_target = per_target + 1e-7 * jnp.mean(u**2, axis=(1, 2))
    return jnp.sum(per_target) / (len(targets) if batch is None else batch)


def make_train_step(env, s0, static, optimiser, pool, batch, periods=EPISODE):
    """One Adam step on ``batch`` targets drawn from ``pool``, data-parallel.

    Every process draws the same batch (the same key) and differentiates the loss
    of its own share (``batch / jax.process_count()`` targets; the summed loss
    over the whole batch size); ``sorojax.process_sum`` adds the shares' losses
    and gradients, and every process applies the same update. In one process
    this is one compiled program (gradient and update).

    Args:
        env: the environment.
        s0: the initial state of every episode.
        static: the policy's non-array part (``eqx.partition``).
        optimiser: an optax optimiser.
        pool: candidate targets ``(n_pool, 3)`` [m].
        batch: targets per step, a multiple of the number of processes.
        periods: control periods per episode.

    Returns:
        ``train_step(params, opt_state, key) -> (params, opt_state, loss)``,
        ``loss`` the batch's mean loss before the update [m^2].

    Raises:
        ValueError: ``batch`` is not a multiple of the number of processes.
    """
    n_proc, rank = jax.process_count(), jax.process_index()
    if batch % n_proc:
        raise ValueError(
            f"batch = {batch} does not split evenly over {n_proc} processes; give "
            f"a multiple of {n_proc}."
        )
    share = batch // n_proc
    options = sj.compiler_options(long_run=True)  # one program, run many times

    def share_grads(params, key, start):
        idx = jax.random.choice(key, pool.shape[0], (batch,), replace=False)
        mine = pool[jax.lax.dynamic_slice_in_dim(idx, start, share)]
        return jax.value_and_grad(
            lambda p: loss_fn(eqx.combine(p, static), env, s0, mine, batch, periods)
        )(params)

    def update(params, opt_state, grads):
        updates, opt_state = optimiser.update(grads, opt_state, params)
        return optax.apply_updates(params, updates), opt_state

    if n_proc == 1:

        @functools.partial(jax.jit, compiler_options=options)
        def train_step(params, opt_state, key):
            loss, grads = share_grads(params, key, 0)
            return *update(params, opt_state, grads), loss

        return train_step

    grads_jit = jax.jit(share_grads, compiler_options=options)
    update_jit = jax.jit(update, compiler_options=options)

    def train_step(params, opt_state, key):
        # the only communication: the losses and gradients, summed on every process
        loss, grads = sj.process_sum(grads_jit(params, key, rank * share))
        return *update_jit(params, opt_state, grads), loss

    return train_step


def train(
    train_step,
    params,
    opt_state,
    keys,
    checkpoint=None,
    run=None,
    every=10,
    max_steps=None,
):
    """Run ``train_step`` once per key, saving and resuming from ``checkpoint``.

    With ``checkpoint`` (a folder) the step index, ``params``, ``opt_state`` and
    the losses are saved every ``every`` steps and at the end, as plain NumPy
    (``state.npz``, written to a temporary file and moved into place, so a killed
    run leaves the last whole save); ``run.json`` records ``run`` (the run's
    arguments, a JSON-able dict). A folder whose ``run.json`` holds other
    arguments is refused and left untouched; otherwise the run resumes after the
    last saved step. In a run of several processes process 0 writes, and every
    process reads (one machine or a shared file system).

    Args:
        train_step: ``(params, opt_state, key) -> (params, opt_state, loss)``.
        params: the starting weights (their structure is the saved ones').
        opt_state: the starting optimiser state (likewise).
        keys: one key per step; their number is the run's number of steps.
        checkpoint: a folder, or None (no saving).
        run: the run's arguments, checked against the folder's.
        every: steps between saves.
        max_steps: stop after computing this many steps (None: all): an
            interrupted run, to be resumed.

    Returns:
        ``(params, opt_state, losses, computed)``: the losses of every step done
        so far (loaded ones included) and how many steps this call computed.

    Raises:
        ValueError: the folder holds another run, or a state that does not fit.
    """
    losses, start = [], 0
    path = None
    write = jax.process_index() == 0
    if checkpoint is not None:
        folder = pathlib.Path(checkpoint)
        meta = {"run": run or {}, "steps": len(keys)}
        info = folder / "run.json"
        if info.exists():
            saved = json.loads(info.read_text())
            if saved != meta:
                raise ValueError(
                    f"checkpoint folder {str(folder)!r} holds another run (saved "
                    f"{saved}, this run {meta}); its files were left unchanged. "
                    "Give a new --checkpoint folder, or delete this one to start "
                    "over."
                )
        elif write:
            folder.mkdir(parents=True, exist_ok=True)
            _write_atomic(info, lambda f: f.write(json.dumps(meta, indent=1).encode()))
        path = folder / "state.npz"
        if path.exists():
            params, opt_state, losses, start = _load_state(path, params, opt_state)
    computed = 0
    stop = len(keys) if max_steps is None else min(len(keys), start + max_steps)
    for k in range(start, stop):
        params, opt_state, loss = train_step(params, opt_state, keys[k])
        losses.append(float(loss))
        computed += 1
        if path is not None and write and ((k + 1) % every == 0 or k + 1 == stop):
            _save_state(path, k + 1, params, opt_state, losses)
    return params, opt_state, losses, computed


def _write_atomic(path, write):
    """Write ``path`` through a temporary sibling moved into place when complete."""
    tmp = path.with_name(f".{path.name}.partial")
    with open(tmp, "wb") as f:
        write(f)
    os.replace(tmp, path)


def _save_state(path, step, params, opt_state, losses):
    arrays = {"step": np.asarray(step), "losses": np.asarray(losses)}
    for name, tree in (("params", params), ("opt", opt_state)):
        for i, leaf in enumerate(jax.tree.leaves(tree)):
            arrays[f"{name}_{i}"] = np.asarray(leaf)
    _write_atomic(path, lambda f: np.savez(f, **arrays))


def _load_state(path, params, opt_state):
    with np.load(path) as data:
        step, losses = int(data["step"]), [float(x) for x in data["losses"]]
        trees = []
        for name, tree in (("params", params), ("opt", opt_state)):
            leaves, treedef = jax.tree.flatten(tree)
            saved = [data[f"{name}_{i}"] for i in range(len(leaves))
                     if f"{name}_{i}" in data]  # fmt: skip
            shapes = [np.shape(x) for x in leaves]
            if [a.shape for a in saved] != shapes:
                raise ValueError(
                    f"{str(path)!r}: the saved {name} do not fit this run's "
                    "(another policy or optimiser); give a new --checkpoint folder."
                )
            trees.append(jax.tree.unflatten(
                treedef,
                [jnp.asarray(a, dtype=jnp.asarray(x).dtype)
                 for a, x in zip(saved, leaves, strict=True)],
            ))  # fmt: skip
    return trees[0], trees[1], losses, step


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
    ap.add_argument("--checkpoint", default=None, help="folder: save and resume")
    ap.add_argument("--checkpoint-every", type=int, default=10, help="steps")
    ap.add_argument("--processes", type=int, default=1, help="data-parallel")
    ap.add_argument("--process-id", type=int, default=0)
    ap.add_argument("--port", type=int, default=12345, help="process 0's port")
    args = ap.parse_args(argv)
    if args.processes > 1:  # before any JAX computation
        sj.initialize_processes(
            f"localhost:{args.port}", args.processes, args.process_id
        )
    out = pathlib.Path(args.out)
    png = out / "learn_reach.png"
    if png.exists() and not args.overwrite and jax.process_index() == 0:
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

    train_step = make_train_step(env, s0, static, optimiser, pool, args.batch)
    timed = []

    def timed_step(*a):  # the first step's time includes the compile
        t = time.perf_counter()
        result = jax.block_until_ready(train_step(*a))
        timed.append(time.perf_counter() - t)
        return result

    keys = jax.random.split(jax.random.key(args.seed + 1), args.iterations)
    run = {k: vars(args)[k] for k in ("iterations", "batch", "lr", "seed")}
    t_train = time.perf_counter()
    params, opt_state, losses, computed = train(
        timed_step, params, opt_state, keys, args.checkpoint, run,
        every=args.checkpoint_every,
    )  # fmt: skip
    t_train = time.perf_counter() - t_train
    t_compile = timed[0] if timed else 0.0
    if jax.process_index() > 0:  # process 0 evaluates and plots
        return {"losses": np.asarray(losses), "steps_computed": computed}
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
        "steps_computed": computed,
        "processes": jax.process_count(),
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
        f"targets ({computed} computed here, {jax.process_count()} process(es)): "
        f"loss {res['loss_first']:.2e} -> {res['loss_last']:.2e} m^2; "
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
