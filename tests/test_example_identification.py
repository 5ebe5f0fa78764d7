"""examples/system_identification.py: E, damping and tip mass from a noisy tip path.

The example's ``main(argv)`` runs in this process on a short record (1.5 s, 31
samples, constant step 20 ms): one compiled program (tip trajectory and its
forward-mode Jacobian) serves the data, every step of the Levenberg-Marquardt fit
(optimistix's solver, stepped from Python), the uncertainty and the checks below.
"""

import math

import numpy as np
import pytest
from test_examples import _load  # one loader for the example scripts

QUICK = ["--t1", "1.5", "--samples", "31", "--dt", "0.02"]


def test_identification_recovers_parameters_within_noise(tmp_path, examples_optimised):
    """Recovered E, eta, m_tip vs truth; the Jacobian vs central differences.

    References: (1) the true parameters. With Gaussian noise the Gauss-Newton
    estimate of the log parameters is ~N(truth, (J^T J)^-1) (residuals in units of
    the noise), so each recovered value must lie within 4 of its estimated standard
    deviations (two-sided tail 6e-5; the seed is fixed, measured 0.4, 2.3 and 0.7);
    the integration error of the 20 ms step (~2e-4 m, 4 % of the noise, against the
    data's quarter step) biases it by far less. The standard deviations must be
    below 5 % (the record determines all three; measured 1.2-2.0 %), and the start
    was 30-50 % off. (2) At the optimum the residual RMS in noise units is
    sqrt((N - 3) / N) ~ 1 with spread 1 / sqrt(2 N) = 0.09 (N = 62): within 0.35.
    (3) The Jacobian: central differences of the same compiled trajectory (constant
    steps: a smooth function of the parameters) with step 1e-4 in log p; truncation
    ~(1e-4)^2 times the third derivative (measured 7e-9 of the column's largest
    entry), rounding ~1e-15 m / 1e-4: tolerance 1e-6 of the column's largest entry.
    A second run must refuse to overwrite the PNG. The example's trajectory program
    compiles at XLA's default level (``examples_optimised``): the data, the fit's
    steps and the checks run it some 15 times.
    """
    ex = _load("system_identification")
    res = ex.main([*QUICK, "--out", str(tmp_path)])

    assert res["converged"], f"LM stopped after {res['steps']} steps unconverged"
    for name in ex.NAMES:
        start = abs(res["initial"][name] / res["true"][name] - 1)
        assert 0.3 - 1e-9 < start < 0.5 + 1e-9, f"{name}: start {start:.0%} off"
        err = math.log(res["recovered"][name] / res["true"][name])
        std = res["rel_std"][name]
        assert std < 0.05, f"{name}: standard deviation {std:.2%} (unidentifiable?)"
        assert abs(err) < 4 * std, (
            f"{name}: recovered {res['recovered'][name]:.5g} vs true "
            f"{res['true'][name]:.5g} ({err:+.2%}, 1-sigma {std:.2%})"
        )
    assert abs(res["residual_rms"] - 1) < 0.35, f"residual RMS {res['residual_rms']}"

    x, ts, dt, h = res["log_p"], res["ts"], res["dt"], 1e-4
    _, J = (np.asarray(a) for a in ex.tip_and_jacobian(x, ts, dt))
    for i, name in enumerate(ex.NAMES):
        e = h * np.eye(3)[i]
        plus = np.asarray(ex.tip_and_jacobian(x + e, ts, dt)[0])
        minus = np.asarray(ex.tip_and_jacobian(x - e, ts, dt)[0])
        fd = (plus - minus) / (2 * h)
        scale = np.abs(J[..., i]).max()
        err = np.abs(J[..., i] - fd).max() / scale
        assert err < 1e-6, f"d(tip)/d(log {name}): forward mode vs central {err:.1e}"

    png = tmp_path / "system_identification.png"
    size = png.stat().st_size
    assert size > 10_000
    with pytest.raises(SystemExit, match="overwrite"):
        ex.main([*QUICK, "--out", str(tmp_path)])
    assert png.stat().st_size == size
