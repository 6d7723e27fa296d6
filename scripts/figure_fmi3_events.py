#!/usr/bin/env python3
"""docs/figures/fmi3_events.png: the reference run through the FMI 3.0 FMU with early return.

The 2 s reference motion (inputs set at the 1 ms communication points only) through
target/fmu/StickSlipManipulator-fmi3.fmu with earlyReturnAllowed and eventModeUsed: the link
velocities qd of joints 1 and 3 and their stiction phases, sampled at every sub-step through the
intermediate-update callback, with the instants where fmi3DoStep returned early (every
stick→slip and slip→stick event), and the communication points where the FMI 2.0 FMU's run
(``stickslip.simulate.run``, 1 ms) first shows the event in ``stick`` or ``n_stick``.
The whole run and two close-ups per joint. Prints what it found. docs/fmi3.md explains the figure.

    python scripts/figure_fmi3_events.py [--fmu3 F] [--fmu2 F] [--out PNG]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave

from stickslip.motion import RUN_TIME, reference_inputs
from stickslip.simulate import run as run_fmi2

ROOT = Path(__file__).resolve().parents[1]
H, JOINTS = 1e-3, (1, 3)
# per joint, two close-ups of its events (s)
WINDOWS = {1: ((0.0190, 0.0215), (1.4715, 1.4910)), 3: ((0.0665, 0.0875), (1.4545, 1.4585))}


def drive(t: float) -> list[float]:
    """q_star, qd_star, qdd_star of the reference motion at t, as the FMI 3.0 arrays take them."""
    q, qd, qdd = reference_inputs(t)
    return [*q, *qd, *qdd]


def run_fmi3(fmu: str):
    """(samples: time, qd[1..4], stick[1..4] at every sub-step and step end; early-return times)."""
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inputs, rows, returns = [vr["q_star"], vr["qd_star"], vr["qdd_star"]], [], []
    with tempfile.TemporaryDirectory() as unzipped:
        s = FMU3Slave(
            guid=md.guid, unzipDirectory=extract(fmu, unzipped), modelIdentifier=md.coSimulation.modelIdentifier
        )

        def sample(t):  # allowed inside the callback (Intermediate Update Mode) and between steps
            rows.append([t, *s.getFloat64([vr["qd"]], 4), *s.getBoolean([vr["stick"]], 4)])

        s.instantiate(eventModeUsed=True, earlyReturnAllowed=True, intermediateUpdate=lambda env, t, *_: sample(t))
        s.enterInitializationMode(startTime=0.0)
        s.setFloat64(inputs, drive(0.0))
        s.exitInitializationMode()
        s.updateDiscreteStates()  # Event Mode after initialization with eventModeUsed
        s.enterStepMode()
        sample(0.0)
        t, k, n = 0.0, 0, round(RUN_TIME / H)
        while k < n:
            if t == k * H:  # inputs at the communication points; the FMU holds them in between
                s.setFloat64(inputs, drive(t))
            event, _, early, last = s.doStep(t, (k + 1) * H - t)
            if early:
                returns.append(last)
                if event:
                    s.enterEventMode()
                    s.updateDiscreteStates()
                    s.enterStepMode()
                t = last
            else:
                k, t = k + 1, (k + 1) * H
                sample(t)
        s.terminate()
        s.freeInstance()
    return np.array(rows), np.array(returns)


def learned_fmi2(r: dict, joint: int) -> np.ndarray:
    """The FMI 2.0 run's communication points where joint's stick or n_stick changed."""
    seen = np.column_stack([r[f"stick[{joint}]"], r[f"n_stick[{joint}]"]])
    return np.array(r["time"])[1:][np.any(np.diff(seen, axis=0) != 0, axis=1)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fmu3", default=str(ROOT / "target/fmu/StickSlipManipulator-fmi3.fmu"))
    p.add_argument("--fmu2", default=str(ROOT / "target/fmu/StickSlipManipulator.fmu"))
    p.add_argument("--out", default=str(ROOT / "docs/figures/fmi3_events.png"))
    a = p.parse_args()
    rows, returns = run_fmi3(a.fmu3)
    t, fmi2 = rows[:, 0], run_fmi2(a.fmu2)
    fig, axes = plt.subplots(2, 3, figsize=(14, 6.4), gridspec_kw={"width_ratios": (2, 1, 1)})
    for row, j in zip(axes, JOINTS, strict=True):
        qd, stick = rows[:, j], rows[:, 4 + j] > 0.5
        # the early returns at which this joint's phase changed, and where the FMI 2.0 run shows them
        after = stick[np.searchsorted(t, returns, side="right") - 1]
        mine = returns[stick[np.searchsorted(t, returns, side="left") - 1] != after]
        learned = learned_fmi2(fmi2, j)
        edges = np.flatnonzero(np.diff(np.r_[0, stick.astype(int), 0]))  # stuck from k0 to the event at k1
        spans = list(zip(edges[::2], edges[1::2], strict=True))
        delays = [learned[learned >= x - 1e-12].min() - x for x in mine]
        print(
            f"joint {j}: {len(mine)} early returns; the FMI 2.0 run shows them at {len(learned)} communication "
            f"points, {1e3 * min(delays):.3f} to {1e3 * max(delays):.3f} ms later"
        )
        for ax, (lo, hi) in zip(row, [(0.0, RUN_TIME), *WINDOWS[j]], strict=True):
            for k0, k1 in spans:
                ax.axvspan(t[k0], t[min(k1, len(t) - 1)], color="0.85", label="stuck" if k0 == spans[0][0] else None)
            ax.plot(t, qd, lw=0.9, color="C0", label="qd at every sub-step (FMI 3.0, intermediate update)")
            if lo > 0.0:
                ax.plot(fmi2["time"], fmi2[f"qd[{j}]"], ".", color="k", ms=4, label="qd at 1 ms (FMI 2.0)")
            for i, x in enumerate(mine):
                ax.axvline(x, color="C3", lw=1.0, label="early return (FMI 3.0)" if i == 0 else None)
            top = np.full(len(learned), 0.96)
            ax.plot(learned, top, "v", color="C2", ms=6, transform=ax.get_xaxis_transform(), label="FMI 2.0 sees it")
            inside = qd[(t >= lo) & (t <= hi)]
            pad = 0.08 * (np.ptp(inside) or 1e-3)
            ax.set(xlim=(lo, hi), ylim=(inside.min() - pad, inside.max() + 2 * pad))
            ax.set_ylabel(f"qd[{j}] / {'m/s' if j == 3 else 'rad/s'}")
    for ax in axes[1]:
        ax.set_xlabel("time / s")
    fig.legend(*axes[0, 1].get_legend_handles_labels(), loc="lower center", ncol=5, fontsize=9)
    print(f"{len(returns)} early returns in all, at {', '.join(f'{x:.6f}' for x in returns)} s")
    fig.suptitle("Reference run through the FMI 3.0 FMU with earlyReturnAllowed: the whole run and the events close up")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=100)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
