"""The console script's demo: solves the default scene and writes a PNG."""

import matplotlib

matplotlib.use("Agg")

from sorojax._cli import main  # noqa: E402


def test_demo_runs_and_writes_png(tmp_path, capsys):
    out = tmp_path / "demo.png"
    code = main(["demo", "-o", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "ndof = 7" in text and "converged" in text and "tip position" in text
    assert out.stat().st_size > 10_000, "PNG too small to hold a rendered figure"
