"""The sweep's summary figure (stickslip.summary.figure) on the Monte Carlo's scales: drive
stiffnesses of 1e6 and clearances of 1e-4 rad, no FMU needed. Its tick labels must be
readable: with matplotlib's default six ticks a clearance column's labels (0.0000, 0.0002, …)
ran into each other."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

matplotlib = pytest.importorskip("matplotlib")


def _rows(n: int = 200) -> tuple:
    rng = np.random.default_rng(1)
    parameters = {
        "k[1]": rng.normal(1.0e6, 2.0e4, n),
        "Delta[1]": rng.uniform(0.0, 1.0e-3, n),
        "Delta[3]": rng.uniform(0.0, 1.0e-4, n),
        "mu_k[1]": rng.uniform(0.18, 0.20, n),
    }
    metrics = {
        "max_eps": 1e-3 + parameters["Delta[1]"] + rng.normal(0.0, 1e-5, n),
        "max_N_normal[1]": 1.3e4 + rng.normal(0.0, 300.0, n),
        "W_drive": 110.0 + 500.0 * (parameters["mu_k[1]"] - 0.19) + rng.normal(0.0, 2.0, n),
    }
    rows = pd.DataFrame({"run": np.arange(n), **parameters, "status": "ok", **metrics})
    spec = SimpleNamespace(parameters=list(parameters), sample=dict.fromkeys(parameters), grid={})
    return rows, spec, list(metrics)


def _overlaps(labels) -> list:
    """Pairs of visible, non-empty tick labels whose drawn boxes intersect."""
    boxes = [(t.get_text(), t.get_window_extent()) for t in labels if t.get_visible() and t.get_text()]
    return [(a, b) for i, (a, x) in enumerate(boxes) for b, y in boxes[i + 1 :] if x.overlaps(y)]


def test_the_outer_tick_labels_do_not_run_into_each_other():
    from stickslip.summary import figure

    rows, spec, metrics = _rows()
    fig = figure(rows, spec, metrics)
    try:
        fig.canvas.draw()
        axes = np.array(fig.axes).reshape(len(metrics), len(spec.parameters) + 1)
        for c, p in enumerate(spec.parameters):
            ax = axes[-1][c]
            labels = ax.get_xticklabels()
            assert sum(bool(t.get_text()) for t in labels) >= 2, p
            assert _overlaps(labels) == [], (p, _overlaps(labels))
        for r, m in enumerate(metrics):
            labels = axes[r][0].get_yticklabels()
            assert _overlaps(labels) == [], (m, _overlaps(labels))
        # The inner panels carry no tick labels of their own (shared axes, label_outer).
        assert not any(t.get_visible() and t.get_text() for t in axes[0][1].get_xticklabels())
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_plot_writes_the_figure(tmp_path):
    from stickslip.summary import plot

    rows, spec, metrics = _rows(50)
    plot(rows, spec, metrics, tmp_path / "summary.png")
    assert (tmp_path / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
