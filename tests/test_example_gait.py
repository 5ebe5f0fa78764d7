"""examples/crawler_gait.py: the crawler moves, and its gait is tuned by gradient.

Slow (its rollouts' programs take ~1 min to compile at -O0): run with ``-m slow``.
"""

import importlib.util
import pathlib

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.slow
def test_crawler_gait_gradient_and_grid(tmp_path):
    spec = importlib.util.spec_from_file_location(
        "crawler_gait", EXAMPLES / "crawler_gait.py"
    )
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    out = ex.main(
        ["--out", str(tmp_path), "--cycles", "1", "--grid", "3", "--ascent-steps", "3"]
    )
    assert (tmp_path / "crawler_gait.png").stat().st_size > 10_000
    v0, g0, fd = out["start"]
    # forward-mode derivative through the contact rollout vs central differences
    # (constant steps: a smooth function; h = 1e-4 of the scale)
    np.testing.assert_allclose(g0, fd, rtol=1e-3, atol=1e-6)
    # anisotropic friction ratchets it forward
    assert np.max(out["grid"]) > 0
    # the ascents never go down: from the start, and from the grid's best cell
    assert out["ascent"][1] >= v0
    # (when no trial step improves on the grid's cell the ascent ends where it
    # started: the same value from another program, equal to round-off)
    best = out["best_grid"][2]
    assert out["refined"][1] >= best - 1e-12 * abs(best)
