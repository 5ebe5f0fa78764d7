"""Draw the README's peer-speed and gradient-cost charts from the benchmark results.

Run from the repository root: ``.venv/bin/python docs/img/charts.py``. It reads
``benchmarks/results/peers.json`` (``benchmarks/peers.py``) and
``benchmarks/results/gradients.json`` (``benchmarks/gradients.py``) and
``benchmarks/results/sweeps_sizes_{cpu,gpu}.json`` (``benchmarks/sweeps.py --sizes``)
and writes ``docs/img/peers.png``, ``docs/img/gradients.png`` and
``docs/img/sweeps.png``; it computes nothing itself.
"""

import json
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
OUT = pathlib.Path(__file__).resolve().parent


def peers() -> None:
    """Warm wall time of 5 s of the damped rod in each code, from one run."""
    d = json.loads((RESULTS / "peers.json").read_text())
    rows = {r["code"]: r["warm_median_s"] for r in d["damped"]}
    names = ["sorojax", "PyElastica", "SoRoMoX", "SoRoSim\n(published)"]
    times = [rows["sorojax"], rows["pyelastica"], rows["soromox"], 1.5]
    fig, ax = plt.subplots(figsize=(5, 2.6))
    bars = ax.barh(names[::-1], times[::-1], color=["0.6", "C1", "C2", "C0"])
    for b, t in zip(bars, times[::-1], strict=True):
        ax.text(t * 1.02, b.get_y() + b.get_height() / 2, f"{t:.2f} s", va="center")
    ax.set_xlim(0, max(times) * 1.2)
    ax.set_xlabel("warm wall time for 5 s simulated [s]")
    ax.set_title("damped soft rod, 12 DoF (PyElastica: 40 elements)", fontsize=9)
    fig.savefig(OUT / "peers.png", dpi=110, bbox_inches="tight")


def gradients() -> None:
    """Warm time of a forward computation and of its gradient."""
    d = json.loads((RESULTS / "gradients.json").read_text())
    cases = [
        ("statics, 30 DoF\n(7 parameters)", d["statics"]),
        ("dynamics 1 s, 12 DoF\n(2 parameters)", d["dynamics_1s"]),
        ("dynamics 5 s, 12 DoF\n(2 parameters)", d["dynamics_5s"]),
    ]
    fig, ax = plt.subplots(figsize=(5.5, 2.8))
    y = range(len(cases))
    fwd = [c["forward"]["warm_s"] * 1e3 for _, c in cases]
    grad = [c["gradient"]["warm_s"] * 1e3 for _, c in cases]
    ax.barh([i + 0.2 for i in y], fwd, 0.4, label="forward", color="C0")
    ax.barh([i - 0.2 for i in y], grad, 0.4, label="reverse-mode gradient", color="C3")
    for i, (f, g) in enumerate(zip(fwd, grad, strict=True)):
        ax.text(g * 1.02, i - 0.2, f"{g / f:.1f}x", va="center", fontsize=8)
    ax.set_yticks(list(y), [n for n, _ in cases])
    ax.invert_yaxis()
    ax.set_xlim(0, max(grad) * 1.2)
    ax.set_xlabel("warm time [ms]")
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(OUT / "gradients.png", dpi=110, bbox_inches="tight")


def sweeps() -> None:
    """``sorojax.sweep`` throughput against batch size, on the CPU and on the GPU."""
    fig, ax = plt.subplots(figsize=(5.5, 3.4))
    labels = {"cpu": "2-core CPU", "gpu": "NVIDIA H200"}
    for dev, style in (("gpu", "-"), ("cpu", "--")):
        rows = json.loads((RESULTS / f"sweeps_sizes_{dev}.json").read_text())["rows"]
        for name, color in (("statics", "C0"), ("dynamics", "C1")):
            r = [x for x in rows if x["workload"] == name]
            ax.loglog(
                [x["n"] for x in r],
                [x["sweep_per_s"] for x in r],
                "o" + style,
                color=color,
                ms=3,
                label=f"{name}, {labels[dev]}",
            )
    ax.set_xlabel("cases per sweep")
    ax.set_ylabel("cases / s")
    ax.set_title("four-cable arm: statics, and 0.5 s of dynamics", fontsize=9)
    ax.legend(fontsize=8)
    fig.savefig(OUT / "sweeps.png", dpi=110, bbox_inches="tight")


if __name__ == "__main__":
    peers()
    gradients()
    sweeps()
