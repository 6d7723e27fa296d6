#!/usr/bin/env python3
"""Plot a reference-simulation CSV written by `simulate_reference`.

Usage:  python scripts/plot_reference.py results/reference.csv results/

Expected CSV: one header row, comma separated, columns (1-based joint index i):
    time, q[i], qd[i], stick[i] (0/1), eps_joint[i], eps, x_E[1..3],
    F_friction[i], N_normal[i], and energy columns (any name containing
    "energy" or starting with "E_", e.g. E_kin, E_pot, E_total).
Only `time` and `q[i]` are required; the number of joints n is taken from the
q[i] columns. Every figure is written only if its columns are present.

Writes into OUTDIR:
    reference_q.png         q[i](t), one subplot per joint
    reference_eps.png       eps(t) and eps_joint[i](t)
    reference_stick.png     qd[i](t) and the stiction chart
    reference_energy.png    energy columns (if any)
    reference_friction.png  |F_friction[i]| and N_normal[i] (if present)
In the per-joint subplots, stiction phases (stick[i] == 1) are drawn as thick
horizontal bars under the curve, like the "coefficient of motion" c_m chart
of the source study.
"""

import argparse
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import FixedLocator, MaxNLocator

STICK_COLOR = "tab:red"
INDEXED = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*\[\s*(\d+)\s*\]\s*$")


def read_csv(path):
    """Return (header list, dict name -> float array); Booleans written as true/false (as
    some masters do) become 1/0, any other cell that is not a number NaN."""
    try:
        table = pd.read_csv(path, skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise SystemExit(f"{path}: empty file") from None
    if table.empty:
        raise SystemExit(f"{path}: header but no data rows")
    header = [str(h).strip() for h in table.columns]
    cols = {
        h: pd.to_numeric(table[c], errors="coerce").to_numpy(dtype=float)
        for h, c in zip(header, table.columns, strict=True)
    }
    return header, cols


def indexed(header, base):
    """{index: column name} for columns named base[i]."""
    out = {}
    for h in header:
        m = INDEXED.match(h)
        if m and m.group(1) == base:
            out[int(m.group(2))] = h
    return dict(sorted(out.items()))


def runs(mask):
    """Index ranges [start, stop) where mask is True."""
    m = np.concatenate(([False], np.asarray(mask, bool), [False]))
    d = np.diff(m.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def stick_segments(t, stick):
    """(start, width) pairs in time for the phases where stick > 0.5.

    A phase covering samples k0..k1-1 is drawn from t[k0] to t[k1] (the next
    sample) so one-sample phases stay visible; the last one ends at t[-1]."""
    segs = []
    for k0, k1 in runs(np.nan_to_num(stick) > 0.5):
        t1 = t[k1] if k1 < len(t) else t[-1]
        width = max(t1 - t[k0], 0.0)
        if width == 0.0:  # single last sample: give it a minimal visible width
            width = (t[-1] - t[0]) * 1e-3 if len(t) > 1 else 1.0
        segs.append((t[k0], width))
    return segs


def padded_limits(y):
    y = y[np.isfinite(y)]
    if y.size == 0:
        return 0.0, 1.0
    lo, hi = float(y.min()), float(y.max())
    span = hi - lo
    if span <= 0:
        span = max(abs(hi), 1.0) * 0.1
    return lo, span


def plot_with_stick_bar(ax, t, y, stick, color, label):
    """Plot y(t) and, below it, a thick bar wherever stick == 1."""
    ax.plot(t, y, color=color, lw=1.2, label=label)
    lo, span = padded_limits(y)
    if stick is None:
        ax.set_ylim(lo - 0.05 * span, lo + 1.05 * span)
        return
    # reserve a strip under the curve for the stiction bar
    bar_y, bar_h = lo - 0.25 * span, 0.12 * span
    ax.set_ylim(lo - 0.32 * span, lo + 1.05 * span)
    segs = stick_segments(t, stick)
    if segs:
        ax.broken_barh(segs, (bar_y, bar_h), facecolors=STICK_COLOR, edgecolor="none")
    # ticks only over the data range, not over the bar strip
    ticks = MaxNLocator(5).tick_values(lo, lo + span)
    tol = 1e-9 * span
    ax.yaxis.set_major_locator(FixedLocator(ticks[(ticks >= lo - tol) & (ticks <= lo + span + tol)]))
    frac = float(np.mean(np.nan_to_num(stick) > 0.5))
    ax.set_title(
        f"stick: {100 * frac:.0f} % of samples, {len(segs)} phases", loc="right", fontsize=8, color=STICK_COLOR, pad=2
    )


def joint_figure(t, joints, cols, names, sticks, title, ylabel_fmt, fname, top=None):
    """One subplot per joint (+ optional top subplot); returns the saved path."""
    nrows = len(joints) + (1 if top else 0)
    fig, axes = plt.subplots(
        nrows, 1, sharex=True, figsize=(10, 1.9 * nrows + 1.2), squeeze=False, layout="constrained"
    )
    axes = axes[:, 0]
    k0 = 0
    if top:
        top(axes[0])
        k0 = 1
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, i in zip(axes[k0:], joints, strict=True):
        st = cols[sticks[i]] if i in sticks else None
        plot_with_stick_bar(ax, t, cols[names[i]], st, colors[(i - 1) % len(colors)], names[i])
        ax.set_ylabel(ylabel_fmt.format(i=i))
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    fig.align_ylabels(axes)
    fig.suptitle(title + ("   (red bars: stiction, stick[i] = 1)" if sticks and joints else ""))
    fig.savefig(fname, dpi=110)
    plt.close(fig)
    return fname


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("outdir", type=Path)
    args = ap.parse_args(argv)

    header, cols = read_csv(args.csv)
    tname = next((h for h in header if h.lower() in ("time", "t")), None)
    if tname is None:
        raise SystemExit(f"{args.csv}: no 'time' column (header: {header})")
    t = cols[tname]
    q, qd = indexed(header, "q"), indexed(header, "qd")
    stick, epsj = indexed(header, "stick"), indexed(header, "eps_joint")
    ffr, nn = indexed(header, "F_friction"), indexed(header, "N_normal")
    if not q:
        raise SystemExit(f"{args.csv}: no q[i] columns (header: {header})")
    joints = list(q)
    n = len(joints)
    args.outdir.mkdir(parents=True, exist_ok=True)
    written = []

    # --- q[i](t) ---------------------------------------------------------------
    written.append(
        joint_figure(
            t, joints, cols, q, stick, f"Joint coordinates q[i] (n = {n})", "q[{i}]", args.outdir / "reference_q.png"
        )
    )

    # --- eps, eps_joint[i] -------------------------------------------------------
    if "eps" in cols or epsj:
        top = None
        if "eps" in cols:

            def top(ax):
                ax.plot(t, cols["eps"], color="k", lw=1.2)
                lo, span = padded_limits(cols["eps"])
                ax.set_ylim(lo - 0.05 * span, lo + 1.05 * span)
                ax.set_ylabel("eps")
                ax.grid(True, alpha=0.3)

        written.append(
            joint_figure(
                t,
                list(epsj),
                cols,
                epsj,
                stick,
                "eps and eps_joint[i]",
                "eps_joint[{i}]",
                args.outdir / "reference_eps.png",
                top=top,
            )
        )

    # --- stiction chart (c_m-like) --------------------------------------------------
    if stick:
        has_qd = bool(qd)
        fig, axes = plt.subplots(
            2 if has_qd else 1,
            1,
            sharex=True,
            squeeze=False,
            layout="constrained",
            figsize=(10, (3.2 if has_qd else 0) + 0.55 * len(stick) + 1.6),
            gridspec_kw={"height_ratios": [3.2, 0.55 * len(stick) + 0.4]} if has_qd else None,
        )
        axes = axes[:, 0]
        if has_qd:
            ax = axes[0]
            for name in qd.values():
                ax.plot(t, cols[name], lw=1.1, label=name)
            ax.axhline(0.0, color="k", lw=0.6)
            ax.set_ylabel("qd[i]")
            ax.legend(loc="upper right", fontsize=8, ncol=min(len(qd), 6))
            ax.grid(True, alpha=0.3)
        ax = axes[-1]
        for row, name in enumerate(stick.values()):
            segs = stick_segments(t, cols[name])
            if segs:
                ax.broken_barh(segs, (row - 0.35, 0.7), facecolors=STICK_COLOR, edgecolor="none")
        ax.set_yticks(range(len(stick)))
        ax.set_yticklabels([f"joint {i}" for i in stick])
        ax.set_ylim(len(stick) - 0.5, -0.5)  # joint 1 on top
        ax.set_xlim(t[0], t[-1])
        ax.grid(True, axis="x", alpha=0.3)
        ax.set_xlabel("time [s]")
        ax.set_title("stiction phases (bar: stick[i] = 1)", fontsize=10)
        fig.suptitle("Joint velocities and stick-slip phases")
        fname = args.outdir / "reference_stick.png"
        fig.savefig(fname, dpi=110)
        plt.close(fig)
        written.append(fname)

    # --- energy ----------------------------------------------------------------------
    energy = [h for h in header if re.search(r"energy", h, re.I) or h.startswith("E_")]
    if energy:
        fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
        for h in energy:
            ax.plot(t, cols[h], lw=1.2, label=h)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("energy [J]")
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.set_title("Energy")
        fname = args.outdir / "reference_energy.png"
        fig.savefig(fname, dpi=110)
        plt.close(fig)
        written.append(fname)

    # --- friction vs normal force --------------------------------------------------
    fj = [i for i in joints if i in ffr or i in nn]
    if fj:
        fig, axes = plt.subplots(
            len(fj), 1, sharex=True, squeeze=False, figsize=(10, 1.9 * len(fj) + 1.2), layout="constrained"
        )
        for ax, i in zip(axes[:, 0], fj, strict=True):
            if i in nn:
                ax.plot(t, cols[nn[i]], color="0.5", lw=1.0, label=nn[i])
            if i in ffr:
                ax.plot(t, np.abs(cols[ffr[i]]), color="tab:blue", lw=1.1, label=f"|{ffr[i]}|")
            ax.set_ylabel(f"joint {i}")
            ax.legend(loc="upper right", fontsize=8)
            ax.grid(True, alpha=0.3)
        axes[-1, 0].set_xlabel("time [s]")
        fig.suptitle("Friction force magnitude and normal force per joint")
        fname = args.outdir / "reference_friction.png"
        fig.savefig(fname, dpi=110)
        plt.close(fig)
        written.append(fname)

    print(f"plot_reference: {len(t)} samples, n = {n} joints, t = [{t[0]:g}, {t[-1]:g}] s")
    for f in written:
        print(f"  wrote {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
