"""cosseratbench: sorojax, PyElastica and MuJoCo on the benchmark's experiments.

The third-party rod benchmark cosseratbench (0.3) runs each solver through its own
adapter (sorojax's: ``sorojax/contrib/cosseratbench.py``, entry point in
pyproject.toml) on cantilever, catenary, pendulum, twist and the contact
experiments crossing, capstan and pile at their default parameters and
resolutions, and capstan's ``overhang``
variants (``--vary-solvers``, default sorojax), one run at a time (``-j 1``): the
benchmark times each run itself, after an untimed warm-up call of the same scene at 1e-3 of its duration
(so JAX compilation is not in the wall time). Needs the ``bench`` extra
(cosseratbench, pyelastica, mujoco)::

    .venv/bin/pip install -e ".[bench]"
    .venv/bin/python benchmarks/cosseratbench_run.py            # reuse saved runs
    .venv/bin/python benchmarks/cosseratbench_run.py --force    # rerun all (~45 min)
    .venv/bin/python benchmarks/cosseratbench_run.py --solvers sorojax --force
    .venv/bin/python benchmarks/cosseratbench_run.py --experiments pile --force

(a subset reruns its experiments; the tables and the summary cover every saved run,
and the figure is drawn again when one of its experiments ran)

Equivalent CLI run (without the table, the figure and the pruning)::

    cosseratbench run cantilever catenary pendulum twist crossing capstan pile \\
        -s sorojax -s pyelastica -s mujoco -o benchmarks/results/cosseratbench -j 1
    cosseratbench run capstan -v overhang -s sorojax -o benchmarks/results/cosseratbench

Writes ``benchmarks/results/cosseratbench/``: the benchmark's own layout
(``EXPERIMENT/default/experiment.json`` and ``.../SOLVER/result.json`` with metrics,
wall time and each adapter's settings), ``trajectory.npz`` files under 1 MB (the
twist's, ~4 MB each, are dropped after the figure is drawn; ``--keep-trajectories``
keeps them), ``summary.json`` (the table, sorojax's models, the machine),
``cosseratbench.md`` (the tables) and ``cosseratbench.png`` (final shapes against the
references, the pendulum's free end, the twisted rods' sideways growth).
"""

import argparse
import json
import os
import platform
import sys
import time
from importlib.metadata import version
from pathlib import Path

# warm timings at XLA's default level from the first call (sorojax.compile_mode)
os.environ.setdefault("SOROJAX_COMPILE", "full")

import numpy as np

OUT = Path(__file__).resolve().parent / "results" / "cosseratbench"
EXPERIMENTS = (
    "cantilever",
    "catenary",
    "pendulum",
    "twist",
    "crossing",
    "capstan",
    "pile",
)
FIGURE = ("cantilever", "catenary", "pendulum", "twist")
MIDDLE = {"crossing": 50}
"""Experiments also run at this resolution, by every solver, into ``OUT/middle``.
The crossing's lift is read at node ``n_nodes // 2``: at its default 51 elements
that node lies 1/102 of the rope (9.8 mm) off the middle, where the reference's
upper rope peaks on the lower one, so a solver exactly on the reference scores a
lift error of about 5.5e-3 there. At 50 elements a node sits at the middle."""

VARY = {"capstan": ("overhang",)}
"""Parameters swept (every value) for the ``--vary-solvers``."""
SOLVERS = ("sorojax", "pyelastica", "mujoco")
LABELS = {"sorojax": "sorojax", "pyelastica": "PyElastica", "mujoco": "MuJoCo"}
PACKAGES = {"sorojax": "sorojax", "pyelastica": "pyelastica", "mujoco": "mujoco"}
KEEP_BYTES = 1_000_000


def _run(experiments, solvers, vary_solvers, out: Path, force: bool) -> dict:
    """Run the tasks not saved yet, one at a time; seconds each took in all.

    The total of a task includes what the benchmark's ``wall_time`` leaves out:
    loading the solver, the untimed warm-up call (JAX and numba compilation) and
    scoring.
    """
    from cosseratbench import registry, runs

    tasks = runs.plan(
        [registry.load_experiment(e) for e in experiments],
        list(solvers),
        [],
        None,
        out,
        force=force,
    )
    for e in experiments:
        if e in VARY and vary_solvers:
            tasks += [
                t
                for t in runs.plan(
                    [registry.load_experiment(e)],
                    list(vary_solvers),
                    list(VARY[e]),
                    None,
                    out,
                    force=force,
                )
                if t.variant.key != "default"
            ]
    for e, n in MIDDLE.items():
        if e in experiments:
            tasks += runs.plan(
                [registry.load_experiment(e)],
                list(solvers),
                [],
                n,
                out / "middle",
                force=force,
            )
    totals = {}
    for task in tasks:
        start = time.perf_counter()
        runs.execute([task], jobs=1)
        key = f"{task.experiment}/{task.variant.key}/{task.solver}"
        if task.n_elements is not None:
            key = f"middle/{key}"
        totals[key] = time.perf_counter() - start
    return totals


def _results(out: Path, experiments, solvers, variant: str = "default") -> dict:
    found: dict = {}
    for e in experiments:
        for s in solvers:
            path = out / e / variant / s / "result.json"
            if path.exists():
                found[(e, s)] = json.loads(path.read_text())
    return found


def _totals(found: dict, out: Path, prefix: str, totals: dict) -> None:
    """Each result's total time incl. warm-up: this invocation's runs save theirs in
    ``total_seconds.json`` beside the result, the others read it from there."""
    for (e, s), summ in found.items():
        path = out / e / "default" / s / "total_seconds.json"
        if f"{prefix}{e}/default/{s}" in totals:
            total = {"total_seconds_incl_warm_up": totals[f"{prefix}{e}/default/{s}"]}
            path.write_text(json.dumps(total) + "\n")
        if path.exists():
            summ.update(json.loads(path.read_text()))


def _variants(out: Path) -> dict:
    """Saved variant runs: ``{(experiment, key, solver): result}`` (not defaults)."""
    found: dict = {}
    for e, names in VARY.items():
        for path in sorted(out.glob(f"{e}/*/*/result.json")):
            key, solver = path.parent.parent.name, path.parent.name
            if key != "default" and key.split("=")[0] in names:
                found[(e, key, solver)] = json.loads(path.read_text())
    return found


def variant_table(found: dict) -> str:
    """The markdown table of the variant runs: metrics, penetration, wall time."""
    if not found:
        return ""
    lines = [
        "| case | variant | solver | metrics | max penetration | wall time |",
        "|---|---|---|---|---|---|",
    ]
    for (e, key, s), summ in sorted(found.items()):
        if summ["outcome"] == "completed":
            metrics = ", ".join(f"{k} {_fmt(v)}" for k, v in summ["metrics"].items())
            pen = _fmt(summ["observations"].get("max_penetration"))
        else:
            metrics, pen = _cell(summ), ""
        lines.append(
            f"| {e} | {key} | {LABELS[s]} | {metrics} | {pen} | {_cell(summ)} |"
        )
    return "\n".join(lines)


def _fmt(x) -> str:
    if x is None:
        return "n/a"
    return f"{x:.2e}" if abs(x) < 0.01 or abs(x) >= 1000 else f"{x:.3g}"


def _cell(summary, metric=None) -> str:
    if summary is None:
        return "not run"
    if summary["outcome"] == "unsupported":
        return "unsupported"
    if summary["outcome"] == "diverged":
        at = summary.get("diverged_at")
        return "diverged" + (f" at {at:.3g} s" if at is not None else "")
    if metric is None:
        return f"{summary['wall_time']:.2f} s"
    return _fmt(summary["metrics"].get(metric))


CONTACT = ("crossing", "capstan", "pile")


def _observed(summary, name) -> str:
    if summary is None or summary["outcome"] != "completed":
        return _cell(summary)
    return _fmt(summary["observations"].get(name))


def _total(summary) -> str:
    if summary is None or "total_seconds_incl_warm_up" not in summary:
        return "n/a"
    return f"{summary['total_seconds_incl_warm_up']:.1f} s"


def _model(summary) -> str:
    if summary is None or not summary.get("settings"):
        return ""
    m = summary["settings"].get("model") or summary["settings"].get("model0", {})
    orders = ", ".join(f"{k} {v}" for k, v in m.get("orders", {}).items())
    div = m.get("divisions", 1)
    divs = f" x {div} divisions" if div > 1 else ""
    text = f"{orders}{divs}; {m.get('n_dof')} DoF; {m.get('method')}"
    c = summary["settings"].get("contact")
    if c:
        k = ", ".join(
            f"{name.split('_')[0]} k {v:.3g}"
            for name, v in c.items()
            if "stiff" in name
        )
        rods = any(name.startswith("rod_rod") for name in c)
        target = c.get(
            "target_penetration" if rods else "obstacle_target_penetration",
            c.get("target_penetration"),
        )
        text += f"; contact {k} (target penetration {target})"
    return text


def table(found, experiments, solvers) -> str:
    """The markdown table: one row per metric and one for the wall time."""
    head = "| case | metric | " + " | ".join(LABELS[s] for s in solvers) + " |"
    lines = [head, "|" + "---|" * (len(solvers) + 2)]
    for e in experiments:
        metrics = []
        for s in solvers:
            summ = found.get((e, s))
            if summ and summ["outcome"] == "completed":
                metrics = list(summ["metrics"])
                break
        for metric in metrics:
            cells = [_cell(found.get((e, s)), metric) for s in solvers]
            lines.append(f"| {e} | {metric} | " + " | ".join(cells) + " |")
        if e in CONTACT:
            for obs in ("max_penetration", "max_rod_overlap"):
                cells = [_observed(found.get((e, s)), obs) for s in solvers]
                if any(c not in ("n/a", "not run", "unsupported") for c in cells):
                    lines.append(f"| {e} | {obs} | " + " | ".join(cells) + " |")
        cells = [_cell(found.get((e, s))) for s in solvers]
        lines.append(f"| {e} | wall time (timed run) | " + " | ".join(cells) + " |")
        cells = [_total(found.get((e, s))) for s in solvers]
        lines.append(
            f"| {e} | total incl. warm-up, compile | " + " | ".join(cells) + " |"
        )
    lines.append("")
    lines.append("| case | sorojax model (Legendre orders per mode; DoF; method) |")
    lines.append("|---|---|")
    for e in experiments:
        lines.append(f"| {e} | {_model(found.get((e, 'sorojax')))} |")
    return "\n".join(lines)


def figure(out: Path, experiments, solvers) -> Path | None:
    """Final shapes against the references, the pendulum, the twisted rods."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from cosseratbench.experiments.twist import LEVELS, _sideways

    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    styles = {"sorojax": "-", "pyelastica": "--", "mujoco": ":"}
    colours = {"sorojax": "tab:blue", "pyelastica": "tab:orange", "mujoco": "tab:green"}
    drew = False
    for ax, e in zip(axes.flat, FIGURE, strict=True):
        if e not in experiments:
            ax.set_visible(False)
            continue
        exp = json.loads((out / e / "default" / "experiment.json").read_text())
        if exp.get("reference") and e in ("cantilever", "catenary"):
            ref = np.asarray(exp["reference"][0])
            ax.plot(ref[:, 0], ref[:, 2], color="0.6", lw=4, label="reference")
        for s in solvers:
            path = out / e / "default" / s / "trajectory.npz"
            if not path.exists():
                continue
            drew = True
            with np.load(path) as data:
                t = data["times"]
                rods = [
                    data[f"rod{i}"]
                    for i in range(sum(k[3:].isdigit() for k in data.files))
                ]
            kw = {"ls": styles[s], "color": colours[s]}
            if e in ("cantilever", "catenary"):
                ax.plot(
                    rods[0][-1, :, 0],
                    rods[0][-1, :, 2],
                    "o",
                    ms=3,
                    **kw,
                    label=LABELS[s],
                )
            elif e == "pendulum":
                # minus the linear theory's swing: a period error shows as a beat
                from cosseratbench.experiments.pendulum import (
                    pendulum,
                    reference_period,
                )

                period = reference_period(pendulum.scenario)
                x = rods[0][:, -1, 0]
                swing = x[0] * np.cos(2 * np.pi * t / period)
                ax.plot(t, (x - swing) * 1e6, **kw, label=LABELS[s])
            else:
                from cosseratbench.experiments.twist import twist

                scenario = twist.scenario
                for i, (rod, pos) in enumerate(zip(scenario.rods, rods, strict=True)):
                    side = _sideways(rod, pos)
                    ax.semilogy(
                        t,
                        np.maximum(side, 1e-12),
                        ls=styles[s],
                        color=plt.cm.viridis(i / (len(rods) - 1)),
                        label=f"{LABELS[s]}" if i == len(rods) - 1 else None,
                    )
        ax.set_title(e)
        if e in ("cantilever", "catenary"):
            ax.set_xlabel("x [m]")
            ax.set_ylabel("z [m]")
        elif e == "pendulum":
            ax.set_xlabel("t [s]")
            ax.set_ylabel("free end x - 20 mm cos(2 pi t / T_ref) [um]")
        else:
            ax.set_xlabel("t [s]")
            ax.set_ylabel("largest distance from the axis [m]")
            ax.set_ylim(1e-7, 1.0)
            ax.text(
                0.02,
                0.97,
                "twist / critical: "
                + ", ".join(f"{v:g}" for v in LEVELS)
                + "\n(dark to light)",
                transform=ax.transAxes,
                va="top",
                fontsize=8,
            )
        ax.legend(fontsize=8, loc="lower right" if e == "twist" else "best")
    if not drew:
        plt.close(fig)
        return None
    fig.suptitle(
        "cosseratbench 0.3, default scenes (final frame; pendulum and twist over time)"
    )
    fig.tight_layout()
    path = out / "cosseratbench.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _environment() -> dict:
    env = {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average": list(os.getloadavg()),
        "jobs": 1,
    }
    for name in ("cosseratbench", "sorojax", "pyelastica", "mujoco", "jax", "numpy"):
        try:
            env[f"{name}_version"] = version(name)
        except Exception:  # noqa: BLE001 - not installed
            env[f"{name}_version"] = None
    return env


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--experiments", nargs="+", default=list(EXPERIMENTS), choices=EXPERIMENTS
    )
    p.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    p.add_argument(
        "--vary-solvers",
        nargs="*",
        default=["sorojax"],
        choices=SOLVERS,
        help="solvers run on the VARY sweeps (none: no sweeps)",
    )
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--force", action="store_true", help="rerun runs already saved")
    p.add_argument("--keep-trajectories", action="store_true")
    p.add_argument(
        "--no-run",
        action="store_true",
        help="only rebuild the tables, summary and figure from the saved runs",
    )
    args = p.parse_args()

    args.out = args.out.resolve()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    env = _environment()
    here = Path.cwd()
    os.chdir(args.out)  # MuJoCo writes MUJOCO_LOG.TXT into the working folder
    try:
        totals = (
            {}
            if args.no_run
            else _run(
                args.experiments, args.solvers, args.vary_solvers, args.out, args.force
            )
        )
    finally:
        os.chdir(here)
    env["load_average_at_end"] = list(os.getloadavg())
    # None: nothing ran (--no-run)
    env["total_seconds"] = None if args.no_run else time.perf_counter() - start

    # the tables cover every experiment saved, this invocation's or an earlier one's;
    # the figure is drawn again only when this invocation ran one of its experiments
    # (the twist's trajectories are dropped after it is drawn)
    found = _results(args.out, EXPERIMENTS, SOLVERS)
    fig = args.out / "cosseratbench.png"
    if set(args.experiments) & set(FIGURE) or not fig.exists():
        fig = figure(args.out, args.experiments, SOLVERS)
    dropped = []
    if not args.keep_trajectories:
        for path in sorted(args.out.glob("*/*/*/trajectory.npz")):
            if path.stat().st_size > KEEP_BYTES:
                dropped.append(str(path.relative_to(args.out)))
                path.unlink()
    _totals(found, args.out, "", totals)
    variants = _variants(args.out)
    text = table(found, EXPERIMENTS, SOLVERS)
    if variants:
        text += "\n\n" + variant_table(variants)
    mids = list(MIDDLE)
    middle = _results(args.out / "middle", mids, SOLVERS)
    _totals(middle, args.out / "middle", "middle/", totals)
    if middle:
        n = ", ".join(f"{e} {MIDDLE[e]}" for e in mids)
        text += (
            f"\n\nAt a resolution with a node at the middle ({n} elements):\n\n"
            + table(middle, mids, SOLVERS)
        )
    print(text)
    (args.out / "cosseratbench.md").write_text(text + "\n")
    summary = {
        "environment": env,
        "results": [found[k] for k in sorted(found)],
        "variant_results": [variants[k] for k in sorted(variants)],
        "middle_results": [middle[k] for k in sorted(middle)],
        "dropped_trajectories": dropped,
        "figure": None if fig is None else fig.name,
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"\nwrote {args.out} ({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
