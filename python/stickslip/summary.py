"""DIR/summary.png and DIR/summary.md of a sweep: each metric against each swept parameter,
and how strongly each parameter moves each metric.

Sensitivity: |Spearman rank correlation| between a parameter and a metric over the variants
whose status is ``ok`` (1: the metric grows or falls monotonically with the parameter, 0: no
monotonic relation). With a grid the other parameters vary too, so it measures the
parameter's share of the variation over the whole sweep.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

SHOWN_ROWS = 64  # summary.md lists every variant up to this many


def varying_metrics(ok, metrics) -> list:
    """The metrics that are not the same in every ok row (e.g. not the stick count of a rigid joint)."""
    return [m for m in metrics if ok[m].notna().any() and ok[m].nunique(dropna=True) > 1]


def sensitivity(ok, parameters, metrics):
    """|Spearman rho| of every (metric, parameter) over the ok rows (a DataFrame, metric x parameter)."""
    import pandas as pd

    ranks = ok[list(parameters) + list(metrics)].rank()
    out = pd.DataFrame(index=list(metrics), columns=list(parameters), dtype=float)
    for m in metrics:
        for p in parameters:
            x, y = ranks[p].to_numpy(), ranks[m].to_numpy()
            keep = np.isfinite(x) & np.isfinite(y)
            if keep.sum() < 3 or np.std(x[keep]) == 0 or np.std(y[keep]) == 0:
                continue
            out.loc[m, p] = abs(float(np.corrcoef(x[keep], y[keep])[0, 1]))
    return out


def plot(rows, spec, metrics: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = rows[rows["status"] == "ok"]
    params = spec.parameters
    shown = varying_metrics(ok, metrics) or metrics[:1]
    rho = sensitivity(ok, params, shown)
    extra = 1 if len(params) > 1 else 0
    fig, axes = plt.subplots(len(shown), len(params) + extra, squeeze=False,
                             figsize=(2.6 * (len(params) + extra) + 0.6, 1.9 * len(shown) + 1.0),
                             layout="constrained")
    for r, m in enumerate(shown):
        for c, p in enumerate(params):
            ax = axes[r][c]
            ax.scatter(ok[p], ok[m], s=6 if p in spec.sample else 14, alpha=0.5 if p in spec.sample else 0.8,
                       lw=0, color="tab:blue")
            if p in spec.grid:
                means = ok.groupby(p)[m].mean()
                ax.plot(means.index, means.to_numpy(), color="tab:red", lw=1.2, marker="o", ms=3, label="mean")
            value = rho.loc[m, p]
            ax.set_title(f"|ρ| = {value:.2f}" if not math.isnan(value) else "", fontsize=8, loc="right")
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
            if r == len(shown) - 1:
                ax.set_xlabel(p, fontsize=9)
            if c == 0:
                ax.set_ylabel(m, fontsize=9)
        if extra:
            ax = axes[r][-1]
            ranking = rho.loc[m].fillna(0.0).sort_values()
            ax.barh(range(len(ranking)), ranking.to_numpy(), color="tab:gray")
            ax.set_yticks(range(len(ranking)))
            ax.set_yticklabels(ranking.index, fontsize=7)
            ax.set_xlim(0, 1)
            ax.tick_params(labelsize=7)
            if r == 0:
                ax.set_title("sensitivity |Spearman ρ|", fontsize=8)
    counts = ", ".join(f"{n} {s}" for s, n in rows["status"].value_counts().items())
    fig.suptitle(f"{len(rows)} variants ({counts}); points: variants with status ok"
                 + ("; red: mean per grid value" if spec.grid else ""), fontsize=10)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _fmt(x) -> str:
    if isinstance(x, str):
        return x.replace("|", "\\|").replace("\n", " ")
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    return f"{x:.4g}"


def _table(header, rows) -> list:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return out + ["| " + " | ".join(_fmt(x) for x in r) + " |" for r in rows]


def markdown(rows, spec, metrics: list, seconds: float | None = None) -> str:
    ok = rows[rows["status"] == "ok"]
    params = spec.parameters
    lines = [f"# Sweep: {len(rows)} of {len(spec)} variants", "",
             f"Reference motion {spec.motion!s}, {spec.stop_time:g} s in communication steps of "
             f"{spec.communication_step:g} s; FMU {spec.fmu}.", ""]
    lines += ["| status | variants |", "|---|---|"] + [f"| {s} | {n} |" for s, n in rows["status"].value_counts().items()]
    busy = rows["wall_s"].sum()
    lines += ["", f"Compute time: {busy:.1f} s summed over the variants"
              + (f", {seconds:.1f} s wall for the variants run now" if seconds else "") + ".", ""]
    lines += ["## Parameters", ""] + _table(
        ["name", "swept as"],
        [[p, "grid " + ", ".join(f"{v:g}" for v in spec.grid[p])] for p in spec.grid]
        + [[p, f"{d.kind} ({d.a:g}, {d.b:g}), n = {spec.n}, seed {spec.seed}"] for p, d in spec.sample.items()])
    shown = varying_metrics(ok, metrics)
    if len(ok):
        lines += ["", "## Metrics over the ok variants", ""] + _table(
            ["metric", "min", "median", "max"],
            [[m, ok[m].min(), ok[m].median(), ok[m].max()] for m in metrics])
    if len(ok) >= 3 and shown:
        rho = sensitivity(ok, params, shown)
        lines += ["", "## Sensitivity: |Spearman rank correlation| over the ok variants", ""] + _table(
            ["metric"] + params + ["strongest"],
            [[m] + [rho.loc[m, p] for p in params]
             + [rho.loc[m].astype(float).idxmax() if rho.loc[m].notna().any() else "–"] for m in shown])
    if len(rows) <= SHOWN_ROWS:
        cols = ["max_eps", "final_eps"] + [m for m in shown if m not in ("max_eps", "final_eps")][:6]
        lines += ["", "## Every variant", ""] + _table(
            ["run"] + params + ["status"] + cols,
            [[str(int(r["run"]))] + [r[p] for p in params] + [r["status"]] + [r[c] for c in cols]
             for _, r in rows.iterrows()])
    bad = rows[rows["status"] != "ok"]
    if len(bad):
        lines += ["", f"## Variants not ok ({len(bad)}; the first 20)", ""] + _table(
            ["run"] + params + ["status", "message"],
            [[str(int(r["run"]))] + [r[p] for p in params] + [r["status"], r["message"] or ""]
             for _, r in bad.head(20).iterrows()])
    return "\n".join(lines) + "\n"


def write(rows, spec, metrics: list, out: Path, seconds: float | None = None) -> None:
    out = Path(out)
    (out / "summary.md").write_text(markdown(rows, spec, metrics, seconds), encoding="utf-8")
    plot(rows, spec, metrics, out / "summary.png")
