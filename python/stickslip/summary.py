"""DIR/summary.png and DIR/summary.md of a sweep: each metric against each swept parameter,
and how strongly each parameter moves each metric.

Sensitivity: |Spearman rank correlation| between a parameter and a metric over the variants
whose status is ``ok`` (1: the metric grows or falls monotonically with the parameter, 0: no
monotonic relation). With a grid the other parameters vary too, so it measures the
parameter's share of the variation over the whole sweep.

Convergence (a sweep run with ``--check-convergence``, :mod:`stickslip.convergence`): a
metric of a checked variant is *not converged* when its ``<metric>_spread`` exceeds the
threshold. summary.md counts them per metric, lists the worst variants and marks them in
the list of every variant; summary.png draws them as orange crosses. They stay in the
statistics and the sensitivity table, which say how many of their rows are not converged.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

SHOWN_ROWS = 64  # summary.md lists every variant up to this many
WORST_ROWS = 20  # summary.md lists this many of the least converged variants


def checked(rows) -> bool:
    """Whether the rows come from a sweep with --check-convergence."""
    return "convergence_status" in rows.columns


def above(rows, metric: str, threshold: float):
    """A boolean Series: the rows whose spread of ``metric`` exceeds ``threshold`` (False where
    not checked)."""
    import pandas as pd

    from .convergence import spread_name

    col = spread_name(metric)
    if col not in rows.columns:
        return pd.Series(False, index=rows.index)
    return rows[col].astype(float) > threshold


def not_converged_metrics(row, metrics, threshold: float) -> list:
    """The metrics of one row (a pandas Series) whose spread exceeds ``threshold``."""
    from .convergence import spread_name

    return [m for m in metrics if spread_name(m) in row.index and float(row[spread_name(m)]) > threshold]


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


def plot(rows, spec, metrics: list, path: Path, threshold: float | None = None) -> None:
    """summary.png: :func:`figure`, saved."""
    fig = figure(rows, spec, metrics, threshold)  # it chooses the Agg backend before pyplot loads
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=80)
    plt.close(fig)


def figure(rows, spec, metrics: list, threshold: float | None = None):
    """The summary figure (a matplotlib Figure, on the Agg backend): a metric per row, a
    parameter per column, each variant with status ok a point; the last column ranks the
    parameters by |Spearman ρ| with the row's metric."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = rows[rows["status"] == "ok"]
    params = spec.parameters
    shown = varying_metrics(ok, metrics) or metrics[:1]
    rho = sensitivity(ok, params, shown)
    extra = 1 if len(params) > 1 else 0
    # A fixed layout, not matplotlib's constrained one: with a metric per row and a parameter per
    # column the panels of a column share their x axis and those of a row their y axis, so only
    # the outer panels carry tick labels, and margins fixed in inches hold them. (The constrained
    # layout measured every panel's ticks: 24 of the 49 s a 16 x 9 figure of 1000 variants took.)
    width, height = 2.6 * (len(params) + extra) + 0.6, 1.9 * len(shown) + 1.0
    fig, axes = plt.subplots(len(shown), len(params) + extra, squeeze=False, figsize=(width, height))
    fig.subplots_adjust(
        left=1.0 / width,
        right=1.0 - 0.15 / width,
        bottom=0.75 / height,
        top=1.0 - 0.75 / height,
        wspace=0.35 if extra else 0.15,
        hspace=0.35,
    )
    for r in range(len(shown)):
        for c in range(len(params)):
            if r > 0:
                axes[r][c].sharex(axes[0][c])
            if c > 0:
                axes[r][c].sharey(axes[r][0])
            axes[r][c].label_outer()
    # At most 4 ticks a side, small values with a power of ten: a panel is 2.6 inches wide, and
    # the default's 6 labels of a clearance (0.0000, 0.0002, …) ran into each other. Shared axes
    # share their locator and formatter, so the first row and column set them for all.
    for ax in [*axes[0][: len(params)], *(axes[r][0] for r in range(len(shown)))]:
        ax.locator_params(nbins=4)
        ax.ticklabel_format(style="sci", scilimits=(-3, 4))
    from .convergence import DEFAULT_THRESHOLD

    threshold = DEFAULT_THRESHOLD if threshold is None else threshold
    flagged_any = False
    for r, m in enumerate(shown):
        bad = above(ok, m, threshold)
        flagged_any |= bool(bad.any())
        for c, p in enumerate(params):
            ax = axes[r][c]
            good = ok[~bad]
            ax.scatter(
                good[p],
                good[m],
                s=6 if p in spec.sample else 14,
                alpha=0.5 if p in spec.sample else 0.8,
                lw=0,
                color="tab:blue",
            )
            if bad.any():
                ax.scatter(
                    ok.loc[bad, p],
                    ok.loc[bad, m],
                    s=28,
                    marker="x",
                    lw=1.2,
                    color="tab:orange",
                    zorder=3,
                    label=f"not converged (spread > {threshold:g})",
                )
            if p in spec.grid:
                means = ok.groupby(p)[m].mean()
                ax.plot(means.index, means.to_numpy(), color="tab:red", lw=1.2, marker="o", ms=3, label="mean")
            value = rho.loc[m, p]
            # y given: the title stays at the top edge, where matplotlib would otherwise look for
            # tick labels above the axes on every draw (3.4 s of a 10 x 9 figure's 6 s).
            ax.set_title(f"|ρ| = {value:.2f}" if not math.isnan(value) else "", fontsize=8, loc="right", y=1.0)
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
                ax.set_title("sensitivity |Spearman ρ|", fontsize=8, y=1.0)
    counts = ", ".join(f"{n} {s}" for s, n in rows["status"].value_counts().items())
    title = f"{len(rows)} variants ({counts}); points: variants with status ok" + (
        "; red: mean per grid value" if spec.grid else ""
    )
    if checked(rows):
        n_checked = int((ok["convergence_status"] == "checked").sum())
        title += f"\n{n_checked} checked for convergence; orange x: that metric not converged (spread > {threshold:g})"
    fig.suptitle(title, fontsize=10, y=1.0 - 0.12 / height, va="top")
    if flagged_any:
        from matplotlib.lines import Line2D

        fig.legend(
            handles=[
                Line2D([], [], ls="", marker="x", color="tab:orange", label=f"not converged (spread > {threshold:g})")
            ],
            loc="lower right",
            fontsize=8,
        )
    return fig


def _fmt(x) -> str:
    if isinstance(x, str):
        return x.replace("|", "\\|").replace("\n", " ")
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    return f"{x:.4g}"


def _table(header, rows) -> list:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return out + ["| " + " | ".join(_fmt(x) for x in r) + " |" for r in rows]


def markdown(
    rows,
    spec,
    metrics: list,
    seconds: float | None = None,
    threshold: float | None = None,
    convergence: dict | None = None,
) -> str:
    from .convergence import DEFAULT_THRESHOLD

    threshold = DEFAULT_THRESHOLD if threshold is None else threshold
    ok = rows[rows["status"] == "ok"]
    params = spec.parameters
    check = checked(rows)
    lines = [
        f"# Sweep: {len(rows)} of {len(spec)} variants",
        "",
        f"Reference motion {spec.motion!s}, {spec.stop_time:g} s in communication steps of "
        f"{spec.communication_step:g} s; FMU {spec.fmu}.",
        "",
    ]
    lines += ["| status | variants |", "|---|---|"] + [
        f"| {s} | {n} |" for s, n in rows["status"].value_counts().items()
    ]
    busy = rows["wall_s"].sum()
    lines += [
        "",
        f"Compute time: {busy:.1f} s summed over the variants"
        + (f" and {rows['convergence_wall_s'].sum():.1f} s over their convergence check runs" if check else "")
        + (f", {seconds:.1f} s wall for the variants run now" if seconds else "")
        + ".",
        "",
    ]
    lines += ["## Parameters", ""]
    lines += _table(
        ["name", "swept as"],
        [[p, "grid " + ", ".join(f"{v:g}" for v in spec.grid[p])] for p in spec.grid]
        + [[p, f"{d.kind} ({d.a:g}, {d.b:g}), n = {spec.n}, seed {spec.seed}"] for p, d in spec.sample.items()],
    )
    shown = varying_metrics(ok, metrics)
    if check:
        lines += convergence_section(rows, params, metrics, threshold, convergence)
    if len(ok):
        lines += ["", "## Metrics over the ok variants", ""]
        if check:
            lines += [f"Not-converged values (spread > {threshold:g}) are included; the last column counts them.", ""]
        lines += _table(
            ["metric", "min", "median", "max"] + (["not converged"] if check else []),
            [
                [m, ok[m].min(), ok[m].median(), ok[m].max()]
                + ([str(int(above(ok, m, threshold).sum()))] if check else [])
                for m in metrics
            ],
        )
    if len(ok) >= 3 and shown:
        rho = sensitivity(ok, params, shown)
        lines += ["", "## Sensitivity: |Spearman rank correlation| over the ok variants", ""]
        if check:
            lines += [
                f"Over all {len(ok)} ok variants, the not-converged values (spread > {threshold:g}) "
                "included: the column `not converged` counts them per metric (of the checked ones; "
                "the unchecked variants may hold more in the same proportion).",
                "",
            ]
        lines += _table(
            ["metric"] + params + ["strongest"] + (["not converged"] if check else []),
            [
                [m]
                + [rho.loc[m, p] for p in params]
                + [rho.loc[m].astype(float).idxmax() if rho.loc[m].notna().any() else "–"]
                + ([str(int(above(ok, m, threshold).sum()))] if check else [])
                for m in shown
            ],
        )
    if len(rows) <= SHOWN_ROWS:
        cols = ["max_eps", "final_eps", *[m for m in shown if m not in ("max_eps", "final_eps")][:6]]
        lines += ["", "## Every variant", ""]
        if check:
            lines += [
                f"`converged`: **no** names the metrics whose spread exceeds {threshold:g} (marked ⚠ in "
                "the columns shown); `–`: not checked; otherwise the check run's status.",
                "",
            ]
        lines += _table(
            ["run"] + params + ["status"] + cols + (["converged"] if check else []),
            [
                [str(int(r["run"]))]
                + [r[p] for p in params]
                + [r["status"]]
                + [_mark(r, c, threshold) if check else r[c] for c in cols]
                + ([_converged_cell(r, metrics, threshold)] if check else [])
                for _, r in rows.iterrows()
            ],
        )
    bad = rows[rows["status"] != "ok"]
    if len(bad):
        lines += ["", f"## Variants not ok ({len(bad)}; the first 20)", ""]
        lines += _table(
            ["run", *params, "status", "message"],
            [
                [str(int(r["run"]))] + [r[p] for p in params] + [r["status"], r["message"] or ""]
                for _, r in bad.head(20).iterrows()
            ],
        )
    return "\n".join(lines) + "\n"


def _mark(row, metric: str, threshold: float) -> str:
    """A metric's value, with ⚠ when its spread exceeds the threshold."""
    from .convergence import spread_name

    text = _fmt(row[metric])
    col = spread_name(metric)
    return text + " ⚠" if col in row.index and float(row[col]) > threshold else text


def _converged_cell(row, metrics, threshold: float) -> str:
    from .convergence import CHECKED

    status = row["convergence_status"]
    if status != CHECKED:
        return "–" if status in (None, "not selected", "not run") or status != status else f"check {status}"
    bad = not_converged_metrics(row, metrics, threshold)
    return "**no**: " + ", ".join(bad) if bad else "yes"


def convergence_section(rows, params, metrics, threshold: float, convergence: dict | None) -> list:
    """summary.md's section on the convergence check: what was checked and how, how many
    checked variants have each metric above the threshold, the worst variants, the failed
    check runs."""
    from .convergence import CHECKED, describe, spread_name

    convergence = convergence or {}
    status = rows["convergence_status"].fillna("lost")
    done = rows[status == CHECKED]
    lines = [
        "",
        "## Convergence",
        "",
        f"Each checked variant ran a second time with {describe(convergence.get('rerun') or {}) or '?'} "
        f"({convergence.get('method', '?')}); a metric's spread is |x_tight − x| / max(|x_tight|, |x|), "
        f"and a metric is **not converged** where it exceeds {threshold:g} ({100 * threshold:g} %). "
        f"Fraction checked: {convergence.get('fraction', float('nan')):g} "
        f"({convergence.get('checked', '?')} of {len(rows)} variants, chosen by the SPEC's seed). "
        "What it means and what can still be concluded: docs/convergence.md.",
        "",
    ]
    lines += ["| check | variants |", "|---|---|"] + [f"| {s} | {n} |" for s, n in status.value_counts().items()]
    bad_any = [not_converged_metrics(r, metrics, threshold) for _, r in done.iterrows()]
    n_bad = sum(1 for b in bad_any if b)
    lines += [
        "",
        f"**{n_bad} of {len(done)} checked variants** have at least one metric not converged (spread > {threshold:g}).",
        "",
    ]
    if len(done):
        per = []
        for m in metrics:
            s = done[spread_name(m)].astype(float)
            if s.notna().any() and (done[m] != 0).any():  # not e.g. the stick count of a rigid joint
                worst = int(done.loc[s.idxmax(), "run"]) if s.max() > 0 else None
                per.append(
                    [m, str(int((s > threshold).sum())), s.median(), s.max(), str(worst) if worst is not None else "–"]
                )
        lines += _table(
            ["metric", f"checked variants above {threshold:g}", "median spread", "max spread", "run of the max"], per
        )
        left = [m for m in metrics if not (done[m] != 0).any()]
        if left:
            lines += ["", f"({', '.join(left)}: 0 in every checked variant, left out.)"]
    if n_bad:
        spread_cols = [spread_name(m) for m in metrics if spread_name(m) in done.columns]
        worst = done.assign(_max=done[spread_cols].astype(float).max(axis=1))
        worst = worst[worst["_max"] > threshold].sort_values("_max", ascending=False).head(WORST_ROWS)
        lines += ["", f"### Not converged: the worst {len(worst)} variants", ""]
        lines += _table(
            ["run", *params, "metrics above the threshold (spread)", "max spread"],
            [
                [str(int(r["run"]))]
                + [r[p] for p in params]
                + [
                    ", ".join(
                        f"{m} {float(r[spread_name(m)]):.3g}" for m in not_converged_metrics(r, metrics, threshold)
                    ),
                    r["_max"],
                ]
                for _, r in worst.iterrows()
            ],
        )
    failed = rows[~status.isin([CHECKED, "not selected", "not run", "lost"])]
    if len(failed):
        lines += ["", f"### Check runs that failed ({len(failed)}; the first 20; their main rows are kept)", ""]
        lines += _table(
            ["run", *params, "check status", "message"],
            [
                [str(int(r["run"]))]
                + [r[p] for p in params]
                + [r["convergence_status"], r["convergence_message"] or ""]
                for _, r in failed.head(20).iterrows()
            ],
        )
    return lines


def write(
    rows,
    spec,
    metrics: list,
    out: Path,
    seconds: float | None = None,
    threshold: float | None = None,
    convergence: dict | None = None,
) -> None:
    out = Path(out)
    (out / "summary.md").write_text(markdown(rows, spec, metrics, seconds, threshold, convergence), encoding="utf-8")
    plot(rows, spec, metrics, out / "summary.png", threshold)
