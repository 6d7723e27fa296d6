"""The source study's section 4 (figures 10-14) on the reference manipulator, through the FMU.

Five cases (shared/reference-manipulator.md, "The study cases"), each a set of
variants of the reference motion run through the FMU with fmpy
(:func:`stickslip.simulate.run`), the way a user does:

=============== ============================================== =====================
case            variants                                       quantity
=============== ============================================== =====================
step            fixed sub-steps 5e-5, 2e-5, H, H/2 s (H =      q'_3, stick phases
                --step-h, 2e-6 s)
friction        mu_3 = 0.1 vs 0.2 (kinetic = static)           eps
characteristic  constant mu = 0.2 vs decreasing mu(v) in       eps_3, stick phases
                joints 1 and 3 (mu_S 0.2, mu_C 0.12, v_S 0.01)
clearance       Delta_1 = Delta_3 = 0 vs pi/90 rad, 0.002 m    eps_1
slider          a_3 = 0.2 vs 0.4 m, h_1 = h_3 = 1e3            eps, N_normal[3]
=============== ============================================== =====================

Per case it writes ``<case>.csv`` (time and, per variant, the case's
columns named ``<variant>:<FMU variable>``) and ``<case>.png`` drawn like the
study: the quantity against time for every variant, and under it the stiction
phases of the flexible joints as thick bars (the study's "coefficient of
motion"). Then ``summary.json`` and ``summary.md``: max and final |eps|, number
and total length of the stiction phases (``n_stick``, ``t_stick``), max normal
loads, the case's own measures and whether each claim holds.

Stiction phases are rebuilt from the FMU's cumulative counters (:func:`stick_phases`),
so their number and total length are exactly ``n_stick`` and ``t_stick``, also for
phases that begin and end inside a communication step; their position is known
to one communication interval (1e-4 s by default).

Command line (the main job runs it after the reference run)::

    stickslip study [--out results/study] [--fixed-step H] [--step-h 2e-6]
        [--cases step,friction,...] [--end 2.0] [--interval 1e-4] [--fmu FILE] [--motion MOTION.toml]

An FMU with motor drives (inputs ``tau_m[i]``) is refused with one line: the cases prescribe
the drive positions q* of flexible drives, which it ignores while stepping.

``--motion`` runs every variant with a motion file (docs/motion.md) instead of the reference
motion; the claims are then checked on that motion, over the same time windows (the vibration
over 0-1.5 s, the middle of the motion 0.3-1.2 s), which were chosen for the reference motion.

Every case but the step case runs with the FMU's error-controlled sub-steps (its
defaults), unless ``--fixed-step H`` fixes them (h_min = h_max = H); the step case
always uses fixed sub-steps.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .fmu import DEFAULT_FMU, ROOT
from .motion import MOTION_TIME, RUN_TIME
from .simulate import run

FLEXIBLE = (1, 3)  # joints with a flexible drive and friction
DEFAULT_STEP_H = 2e-6  # s, the study's converged step: the finest fixed step of the step case
DEFAULT_INTERVAL = 1e-4  # s, communication interval: resolution of the stiction bars
COARSE_STEPS = (5e-5, 2e-5)  # s, the study's Fig. 10 (a), (b)
MOVING_MEAN = 0.05  # s, window of the moving mean that separates vibration from drift
MIDDLE = (0.3, 1.2)  # s, "middle of the motion" of the clearance case
CLEARANCE = (math.pi / 90.0, 0.002)  # Delta_1 (rad), Delta_3 (m) of Fig. 13 (b)
DECREASING = {"mu_s": 0.2, "mu_k": 0.12, "v_s": 0.01}  # mu(v) = mu_C + (mu_S - mu_C) exp(-|v|/v_S)
SLIDER_DAMPING = 1e3  # h_1 (N m s/rad), h_3 (N s/m) of Fig. 14

# Columns kept in every case's CSV (the quantities of the summary).
BASE_COLUMNS = (
    "eps",
    *(f"{g}[{j}]" for g in ("eps_joint", "stick", "n_stick", "t_stick", "N_normal") for j in FLEXIBLE),
)


@dataclass(frozen=True)
class Variant:
    """One run: a label for legends, a short key for CSV columns, FMU parameters."""

    label: str
    key: str
    parameters: dict


@dataclass(frozen=True)
class Panel:
    """One axes of a figure: ``quantity`` of the variants numbered in ``variants``."""

    quantity: str
    ylabel: str
    variants: tuple
    title: str = ""
    scale: float = 1.0  # plotted value = scale * FMU value (ylabel in the scaled unit)
    reference: tuple = ()  # (value in FMU units, label): a dashed horizontal line


@dataclass(frozen=True)
class Case:
    """One of the study's figures: its variants, what is plotted and whose stiction is barred."""

    name: str
    title: str  # the figure's title, naming the study's figure
    variants: tuple
    panels: tuple
    stick_joints: tuple = FLEXIBLE
    share_y: bool = True
    extra_columns: tuple = ()
    zoom: tuple = ()  # (t0, t1): a second row of stiction bars over this time span


def _letters(n):
    return [f"({chr(ord('a') + k)})" for k in range(n)]


def fixed_steps(h: float) -> dict:
    """The FMU parameters of fixed sub-steps of ``h`` seconds (h_min = h_max)."""
    return {"h_min": h, "h_max": h}


def study_cases(fixed_step: float | None = None, step_h: float = DEFAULT_STEP_H) -> dict:
    """The five cases: every variant with the FMU's error control, or with fixed
    sub-steps of ``fixed_step`` s; the step case with fixed sub-steps of 5e-5, 2e-5,
    ``step_h`` and ``step_h``/2 s."""
    base = {} if fixed_step is None else fixed_steps(fixed_step)
    steps = sorted({*COARSE_STEPS, step_h, step_h / 2.0}, reverse=True)
    step = tuple(Variant(f"h = {h:.0e} s", f"h={h:.0e}", fixed_steps(h)) for h in steps)
    friction = tuple(Variant(f"μ3 = {mu}", f"mu3={mu}", base | {"mu_k[3]": mu, "mu_s[3]": mu}) for mu in (0.1, 0.2))
    characteristic = (
        Variant("constant μ = 0.2", "constant", base),
        Variant(
            "decreasing μ(v): μS 0.2, μC 0.12, vS 0.01",
            "decreasing",
            base | {f"{p}[{j}]": v for j in FLEXIBLE for p, v in DECREASING.items()},
        ),
    )
    clearance = (
        Variant("Δ1 = Δ3 = 0", "no_clearance", base),
        Variant(
            "Δ1 = π/90 rad, Δ3 = 0.002 m", "clearance", base | {"Delta[1]": CLEARANCE[0], "Delta[3]": CLEARANCE[1]}
        ),
    )
    damped = base | {"h[1]": SLIDER_DAMPING, "h[3]": SLIDER_DAMPING}
    slider = tuple(Variant(f"a3 = {a} m", f"a3={a}", damped | {"slider_a[3]": a}) for a in (0.2, 0.4))

    def one_per_variant(quantity, ylabel, variants, scale=1.0, reference=lambda k: ()):
        return tuple(
            Panel(quantity, ylabel, (k,), f"{letter} {v.label}", scale, reference(k))
            for k, (letter, v) in enumerate(zip(_letters(len(variants)), variants, strict=True))
        )

    return {
        "step": Case(
            "step",
            "Fig. 10: influence of the sub-step h on q̇3",
            step,
            one_per_variant("qd[3]", "q̇3 [m/s]", step),
            stick_joints=(3,),
            extra_columns=("qd[3]",),
            zoom=(1.415, 1.495),
        ),
        "friction": Case(
            "friction",
            "Fig. 11: friction coefficient of joint 3 and positioning accuracy ε",
            friction,
            (Panel("eps", "ε [µm]", (0, 1), scale=1e6),),
        ),
        "characteristic": Case(
            "characteristic",
            "Fig. 12: constant vs decreasing friction characteristic, ε3",
            characteristic,
            one_per_variant("eps_joint[3]", "ε3 [µm]", characteristic, 1e6),
        ),
        "clearance": Case(
            "clearance",
            "Fig. 13: clearance in drives 1 and 3, ε1",
            clearance,
            one_per_variant(
                "eps_joint[1]", "ε1 [mrad]", clearance, 1e3, lambda k: (CLEARANCE[0], "Δ1 = π/90") if k else ()
            ),
            share_y=False,
        ),
        "slider": Case(
            "slider",
            f"Fig. 14: slider length a3 (h1 = h3 = {SLIDER_DAMPING:g}), ε and N3",
            slider,
            (Panel("eps", "ε [µm]", (0, 1), scale=1e6), Panel("N_normal[3]", "N3 [N]", (0, 1))),
            extra_columns=("F_friction[3]",),
        ),
    }


# ---------------------------------------------------------------------------
# runs and measures


_RUNS = {}


@functools.cache
def _start_values(fmu: str) -> dict:
    from fmpy import read_model_description

    return {v.name: v.start for v in read_model_description(fmu).modelVariables}


def _changed(parameters: dict, fmu) -> tuple:
    """The parameters whose value differs from the FMU's start value, sorted."""
    start = _start_values(str(fmu))
    return tuple(sorted((k, v) for k, v in parameters.items() if start.get(k) is None or float(start[k]) != v))


def simulate(
    variant: Variant,
    end: float = RUN_TIME,
    interval: float = DEFAULT_INTERVAL,
    fmu=DEFAULT_FMU,
    progress: str | None = None,
    motion=None,
):
    """(outputs as numpy arrays, wall seconds) of one variant. Runs that differ from the FMU's
    defaults in the same parameters are done once per process: the reference run appears in
    four cases. ``motion``: a loaded motion file (:func:`stickslip.motion.load_motion`), None
    for the reference motion."""
    key = (str(fmu), end, interval, _changed(variant.parameters, fmu), getattr(motion, "source", None))
    if key in _RUNS:
        return _RUNS[key], 0.0
    wall = time.perf_counter()
    if motion is None:
        result = run(fmu, end, interval, dict(variant.parameters), progress=progress)
    else:
        result = run(fmu, end, interval, dict(variant.parameters), motion, progress=progress)
    wall = time.perf_counter() - wall
    _RUNS[key] = {k: np.asarray(v, dtype=np.float64) for k, v in result.items()}
    return _RUNS[key], wall


def stick_phases(r: dict, joint: int) -> list:
    """Stiction phases of ``joint`` as [start, end] pairs (s), rebuilt from the cumulative
    counters: n_stick[j] counts the phases begun and t_stick[j] the time stuck, also inside a
    communication interval. In an interval where the joint was not stuck throughout, its
    stuck time dt is shared equally by the pieces that lie there: the end of a phase running
    at the interval's start (stick = 1 there), the phases begun and ended inside it, and the
    start of a phase still running at its end. Number and total length equal n_stick and
    t_stick; positions are exact to one interval."""
    t = r["time"]
    stick = r[f"stick[{joint}]"] > 0.5
    n = np.rint(r[f"n_stick[{joint}]"]).astype(int)
    ts = r[f"t_stick[{joint}]"]
    phases = [[t[0], t[0]]] if stick[0] else []
    for k in range(len(t) - 1):
        dn, dt = n[k + 1] - n[k], ts[k + 1] - ts[k]
        if dn == 0 and stick[k] == stick[k + 1]:
            if stick[k]:  # stuck throughout
                phases[-1][1] = t[k + 1]
            continue
        inner = max(0, dn - int(stick[k + 1]))  # phases begun and ended in the interval
        share = dt / (int(stick[k]) + inner + int(stick[k + 1]))
        if stick[k]:
            phases[-1][1] = t[k] + share
        for m in range(inner):
            mid = t[k] + (t[k + 1] - t[k]) * (m + 1) / (inner + 1)
            phases.append([mid - share / 2, mid + share / 2])
        if stick[k + 1]:
            phases.append([t[k + 1] - share, t[k + 1]])
    return phases


def vibration(t, x, window: float = MOVING_MEAN, end: float = MOTION_TIME) -> float:
    """Standard deviation of x about its centred moving mean over ``window`` seconds, for
    0 <= t <= end (samples whose window is complete): the vibration without the drift."""
    w = max(1, round(window / (t[1] - t[0])) | 1)
    mean = np.convolve(x, np.ones(w) / w, mode="valid")
    centre = slice(w // 2, w // 2 + len(mean))
    keep = t[centre] <= end + 1e-12
    return float(np.std(x[centre][keep] - mean[keep]))


def measures(r: dict) -> dict:
    """The numbers of one run: max and final |eps|, and per flexible joint j max and final
    |eps_j|, n_stick, t_stick, max N_normal, max |F_friction|, the vibration of eps_j
    (:func:`vibration`), mean |eps_j| over the run and over the middle of the motion with
    the extreme deviations from it there (relative)."""
    t = r["time"]
    out = {"max_eps": float(np.max(np.abs(r["eps"]))), "final_eps": float(abs(r["eps"][-1]))}
    middle = (t >= MIDDLE[0] - 1e-12) & (t <= MIDDLE[1] + 1e-12)
    for j in FLEXIBLE:
        e = np.abs(r[f"eps_joint[{j}]"])
        m = float(np.mean(e[middle])) if middle.any() else float("nan")
        out[f"joint{j}"] = {
            "max_abs_eps": float(np.max(e)),
            "final_abs_eps": float(e[-1]),
            "n_stick": round(r[f"n_stick[{j}]"][-1]),
            "t_stick": float(r[f"t_stick[{j}]"][-1]),
            "max_N_normal": float(np.max(r[f"N_normal[{j}]"])),
            "max_abs_F_friction": float(np.max(np.abs(r[f"F_friction[{j}]"]))),
            "vibration": vibration(t, r[f"eps_joint[{j}]"]),
            "mean_abs_eps": float(np.mean(e)),
            "mean_abs_eps_middle": m,
            "middle_deviation": [float(np.min(e[middle]) / m - 1), float(np.max(e[middle]) / m - 1)]
            if middle.any()
            else [float("nan")] * 2,
        }
    return out


# ---------------------------------------------------------------------------
# the claims, as numbers


@dataclass
class Claim:
    """One claim of the study with our numbers in ``text``, and whether it holds."""

    text: str
    holds: bool


def differences(r: dict, ref: dict, joint: int = 3) -> dict:
    """How run ``r`` differs from ``ref`` (same communication points): max |delta qd_j|
    relative to max |qd_j| of ref, max |delta eps| (m), and, where both have the same number
    of stiction phases of joint j, the largest shift of a phase's start or end (s)."""
    qd = f"qd[{joint}]"
    out = {
        "max_dqd_rel": float(np.max(np.abs(r[qd] - ref[qd])) / np.max(np.abs(ref[qd]))),
        "max_deps": float(np.max(np.abs(r["eps"] - ref["eps"]))),
    }
    a, b = stick_phases(r, joint), stick_phases(ref, joint)
    out["max_phase_shift"] = float(np.max(np.abs(np.array(a) - np.array(b)))) if len(a) == len(b) else None
    return out


def claims(case: Case, runs: list, m: list) -> list:
    """The study's claim for ``case`` checked on the runs and measures ``m`` of its variants
    (in the order of :func:`study_cases`). The step case compares every variant with the
    finest: the study's convergence claim is that the second finest reproduces it (max |eps|
    within 1 %, stick-phase counts within +-1); the same bound on the coarser steps is ours
    (the study's coarse steps gave a different stick-slip pattern)."""
    if case.name == "step":
        ref, out = m[-1], []
        for v, x, r in zip(case.variants, m, runs, strict=True):
            if x is ref:
                continue
            rel = abs(x["max_eps"] - ref["max_eps"]) / ref["max_eps"]
            dn = max(abs(x[f"joint{j}"]["n_stick"] - ref[f"joint{j}"]["n_stick"]) for j in FLEXIBLE)
            d = differences(r, runs[-1])
            shift = "n/a" if d["max_phase_shift"] is None else f"{1e6 * d['max_phase_shift']:.0f} µs"
            out.append(
                Claim(
                    f"{v.label} vs {case.variants[-1].label}: max |ε| differs by {rel:.1e} (≤ 1e-2), "
                    f"stick-phase counts by {dn} (≤ 1); max |Δq̇3| = {d['max_dqd_rel']:.1e} of "
                    f"max |q̇3|, max |Δε| = {d['max_deps']:.1e} m, "
                    f"joint-3 phase boundaries moved ≤ {shift}",
                    rel <= 0.01 and dn <= 1,
                )
            )
        return out
    a, b = m
    if case.name == "friction":
        return [
            Claim(
                f"max ε with μ3 = 0.2 ({b['max_eps']:.3e} m) > with μ3 = 0.1 ({a['max_eps']:.3e} m)",
                b["max_eps"] > a["max_eps"],
            )
        ]
    if case.name == "characteristic":
        na, nb = a["joint3"]["n_stick"], b["joint3"]["n_stick"]
        va, vb = a["joint3"]["vibration"], b["joint3"]["vibration"]
        return [
            Claim(f"stick phases in joint 3: decreasing {nb} > constant {na}", nb > na),
            Claim(
                f"vibration of ε3 (std about its {1e3 * MOVING_MEAN:.0f} ms moving mean, 0-{MOTION_TIME} s): "
                f"decreasing {vb:.3e} m > constant {va:.3e} m",
                vb > va,
            ),
        ]
    if case.name == "clearance":
        ma, mb = a["joint1"]["mean_abs_eps"], b["joint1"]["mean_abs_eps"]
        lo, hi = b["joint1"]["middle_deviation"]
        return [
            Claim(f"mean |ε1| with clearance {mb:.3e} rad ≥ 100 × without ({ma:.3e} rad)", mb >= 100 * ma),
            Claim(
                f"mean |ε1| with clearance is of the order of Δ1 = {CLEARANCE[0]:.4f} rad "
                f"(0.5 Δ1 … 1.5 Δ1): {mb / CLEARANCE[0]:.2f} Δ1",
                0.5 <= mb / CLEARANCE[0] <= 1.5,
            ),
            Claim(
                f"|ε1| over {MIDDLE[0]}-{MIDDLE[1]} s stays within ±25 % of its mean there "
                f"({b['joint1']['mean_abs_eps_middle']:.3e} rad): {100 * lo:+.1f} % … {100 * hi:+.1f} %",
                -0.25 <= lo and hi <= 0.25,
            ),
        ]
    if case.name == "slider":
        return [
            Claim(
                f"peak N3 with a3 = 0.4 ({b['joint3']['max_N_normal']:.1f} N) < with 0.2 "
                f"({a['joint3']['max_N_normal']:.1f} N)",
                b["joint3"]["max_N_normal"] < a["joint3"]["max_N_normal"],
            ),
            Claim(
                f"peak |F_friction3| with a3 = 0.4 ({b['joint3']['max_abs_F_friction']:.1f} N) < with 0.2 "
                f"({a['joint3']['max_abs_F_friction']:.1f} N)",
                b["joint3"]["max_abs_F_friction"] < a["joint3"]["max_abs_F_friction"],
            ),
            Claim(
                f"max ε with a3 = 0.4 ({b['max_eps']:.3e} m) < with 0.2 ({a['max_eps']:.3e} m)",
                b["max_eps"] < a["max_eps"],
            ),
        ]
    raise KeyError(case.name)


def run_case(
    case: Case,
    end: float = RUN_TIME,
    interval: float = DEFAULT_INTERVAL,
    fmu=DEFAULT_FMU,
    progress: bool = False,
    motion=None,
) -> dict:
    """Runs every variant of ``case``; returns {"runs": [...], "measures": [...], "claims": [...],
    "wall": [...]} (wall 0 for a run reused from an earlier case)."""
    runs, walls = [], []
    for k, v in enumerate(case.variants):
        label = f"  {case.name} {k + 1}/{len(case.variants)} ({v.label})"
        # simulate.run's progress bar on a terminal only: in a log, the line per variant below says enough
        r, wall = simulate(
            v, end, interval, fmu, progress=label if progress and sys.stderr.isatty() else None, motion=motion
        )
        if progress:
            print(
                f"{label}: " + (f"{wall:.1f} s wall" if wall else "reused") + f", max ε {np.max(r['eps']):.3e} m, "
                "n_stick " + ", ".join(str(int(r[f"n_stick[{j}]"][-1])) for j in FLEXIBLE),
                flush=True,
            )
        runs.append(r)
        walls.append(wall)
    m = [measures(r) for r in runs]
    return {"runs": runs, "measures": m, "claims": claims(case, runs, m), "wall": walls}


# ---------------------------------------------------------------------------
# output


def write_case_csv(case: Case, runs: list, path: Path) -> None:
    """time, then per variant the case's columns as ``<key>:<name>`` (9 significant digits)."""
    names = list(dict.fromkeys([p.quantity for p in case.panels] + list(case.extra_columns) + list(BASE_COLUMNS)))
    data = [runs[0]["time"]]
    header = ["time"]
    for v, r in zip(case.variants, runs, strict=True):
        for n in names:
            header.append(f"{v.key}:{n}")
            data.append(r[n])
    np.savetxt(path, np.column_stack(data), delimiter=",", header=",".join(header), comments="", fmt="%.9g")


def _note(quantity: str, m: dict) -> str:
    """The numbers printed in a one-variant panel."""
    if quantity.startswith("eps_joint["):
        j = m[f"joint{quantity[-2]}"]
        unit = "rad" if quantity[-2] == "1" else "m"
        return (
            f"max |ε{quantity[-2]}| = {j['max_abs_eps']:.3e} {unit}, mean |ε{quantity[-2]}| = "
            f"{j['mean_abs_eps']:.3e} {unit}, vibration {j['vibration']:.2e} {unit}"
        )
    return f"max ε = {m['max_eps']:.4e} m, final ε = {m['final_eps']:.4e} m"


def plot_case(case: Case, runs: list, m: list, path: Path) -> None:
    """The study's way: quantity against time (one panel per entry of ``case.panels``), and
    under it one row of thick bars per variant and stuck joint (the coefficient of motion)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    rows = [(k, j) for k in range(len(case.variants)) for j in case.stick_joints]
    bar_height = 0.22 * len(rows) + 0.35
    heights = [2.2 if len(case.panels) < 3 else 1.45] * len(case.panels) + [bar_height] * (1 + bool(case.zoom))
    fig, axes = plt.subplots(
        len(heights), 1, figsize=(10, sum(heights) + 1.3), gridspec_kw={"height_ratios": heights}, layout="constrained"
    )
    n = len(case.panels)
    panels = axes[:n]
    for ax in axes[1 : n + 1]:
        ax.sharex(axes[0])
    for ax in axes[:n]:
        ax.tick_params(labelbottom=False)
    for ax, p in zip(panels, case.panels, strict=True):
        for k in p.variants:
            r = runs[k]
            ax.plot(
                r["time"],
                p.scale * r[p.quantity],
                color=colors[k],
                lw=0.9,
                label=f"{_letters(len(case.variants))[k]} {case.variants[k].label}",
            )
        if p.reference:
            ax.axhline(p.scale * p.reference[0], color="0.3", ls="--", lw=0.9, label=p.reference[1])
        ax.set_ylabel(p.ylabel)
        ax.grid(True, alpha=0.3)
        if p.title:
            ax.set_title(p.title, loc="left", fontsize=9, color=colors[p.variants[0]])
            ax.set_title(_note(p.quantity, m[p.variants[0]]), loc="right", fontsize=8)
        if not p.title or p.reference:
            ax.legend(loc="lower right" if p.reference else "best", fontsize=8)
    for quantity in {p.quantity for p in case.panels} if case.share_y else ():
        same = [ax for ax, p in zip(panels, case.panels, strict=True) if p.quantity == quantity]
        lo = min(ax.get_ylim()[0] for ax in same)
        hi = max(ax.get_ylim()[1] for ax in same)
        for ax in same:
            ax.set_ylim(lo, hi)
    t = runs[0]["time"]
    for ax, span in zip(axes[n:], [(t[0], t[-1]), case.zoom], strict=False):  # no zoom: one axis
        for row, (k, j) in enumerate(rows):
            # an edge as wide as a line keeps phases of a few µs visible
            ax.broken_barh(
                [(a, b - a) for a, b in stick_phases(runs[k], j)],
                (row - 0.32, 0.64),
                facecolors=colors[k],
                edgecolors=colors[k],
                linewidth=0.7,
            )
        ax.set_yticks(range(len(rows)))
        ax.set_yticklabels(
            [f"{_letters(len(case.variants))[k]} joint {j}: {m[k][f'joint{j}']['n_stick']}" for k, j in rows],
            fontsize=8,
        )
        ax.set_ylim(len(rows) - 0.5, -0.5)
        ax.set_xlim(*span)
        ax.grid(True, axis="x", alpha=0.3)
    axes[n].set_title("stiction phases (thick bars; count after the label)", loc="left", fontsize=8)
    if case.zoom:
        axes[n + 1].set_title(f"the same, {case.zoom[0]:g}-{case.zoom[1]:g} s", loc="left", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(case.title, fontsize=11)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summary_markdown(results: dict, settings: dict) -> str:
    stepping = (
        "error-controlled sub-steps"
        if settings["fixed_step"] is None
        else f"fixed sub-steps of {settings['fixed_step']:g} s"
    )
    lines = [
        f"# Study results ({stepping}, communication interval {settings['interval']:g} s, {settings['end']:g} s)",
        "",
    ]
    for name, res in results.items():
        lines += [
            f"## {name}",
            "",
            "| variant | max ε [m] | final ε [m] | n_stick 1, 3 | t_stick 1, 3 [s] | max N 1, 3 [N] "
            "| max \\|ε1\\|, \\|ε3\\| | vibration ε3 [m] | wall [s] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for v, m, w in zip(res["variants"], res["measures"], res["wall"], strict=True):
            j1, j3 = m["joint1"], m["joint3"]
            lines.append(
                f"| {v} | {m['max_eps']:.4e} | {m['final_eps']:.4e} | {j1['n_stick']}, {j3['n_stick']} "
                f"| {j1['t_stick']:.4f}, {j3['t_stick']:.4f} | {j1['max_N_normal']:.0f}, "
                f"{j3['max_N_normal']:.0f} | {j1['max_abs_eps']:.3e}, {j3['max_abs_eps']:.3e} "
                f"| {j3['vibration']:.3e} | {w:.1f} |"
            )
        lines.append("")
        lines += [f"- {'holds' if c['holds'] else 'DOES NOT HOLD'}: {c['text']}" for c in res["claims"]]
        lines.append("")
    return "\n".join(lines)


def motor_refusal(fmu) -> str | None:
    """Why the study cannot run on the FMU ``fmu``: its cases prescribe the drive positions q*
    of the flexible drives, which an FMU with motor drives ignores (None for another FMU, or
    one fmpy cannot read: the run reports that)."""
    from fmpy import read_model_description

    from .motion import motor_joints

    try:
        motors = motor_joints(read_model_description(str(fmu)))
    except Exception:  # noqa: BLE001
        return None
    if not motors:
        return None
    return (
        f"{fmu} has motor drives on joints {', '.join(map(str, motors))} (driven by the inputs tau_m[i]): the "
        f"study's cases prescribe the drive positions q* of flexible drives; use an FMU without motor drives"
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default=str(ROOT / "results" / "study"))
    p.add_argument(
        "--fixed-step",
        type=float,
        default=None,
        help="fixed sub-steps of this length for every case but the step case (default: the FMU's error control)",
    )
    p.add_argument(
        "--step-h",
        type=float,
        default=DEFAULT_STEP_H,
        help="finest fixed sub-step of the step case, which also runs half of it (default 2e-6 s)",
    )
    p.add_argument("--cases", default=",".join(study_cases()), help="comma-separated subset")
    p.add_argument(
        "--end",
        type=float,
        default=None,
        help=f"stop time, s (default {RUN_TIME:g}; with --motion the motion file's stop time)",
    )
    p.add_argument("--interval", type=float, default=DEFAULT_INTERVAL, help="communication interval (s)")
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument(
        "--motion",
        metavar="MOTION.toml",
        help="run the cases with this motion file (docs/motion.md) "
        "instead of the reference motion; the claims are checked over the reference motion's windows",
    )


def main(a: argparse.Namespace) -> int:
    """``stickslip study``: the five cases, their CSVs, figures and summary."""
    all_cases = study_cases(a.fixed_step, a.step_h)
    chosen = [c.strip() for c in a.cases.split(",") if c.strip()]
    unknown = [c for c in chosen if c not in all_cases]
    if unknown:
        raise SystemExit(f"stickslip study: unknown case(s) {unknown}; choose from {list(all_cases)}")
    refusal = motor_refusal(a.fmu)
    if refusal:
        raise SystemExit(f"stickslip study: {refusal}")
    motion, end = None, RUN_TIME if a.end is None else a.end
    if a.motion is None:
        from .motion import reference_motion_refusal

        refusal = reference_motion_refusal(a.fmu)
        if refusal:
            raise SystemExit(f"stickslip study: {refusal}")
    else:
        from .motion import MotionError
        from .simulate import motion_of

        try:
            motion = motion_of(a.motion, a.fmu)
        except MotionError as e:
            raise SystemExit(f"stickslip study: {e}") from None
        end = motion.stop_time if a.end is None else a.end
        print(f"motion: {motion.describe()}", flush=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    settings = {"fixed_step": a.fixed_step, "step_h": a.step_h, "interval": a.interval, "end": end, "fmu": a.fmu}
    if a.motion is not None:
        settings["motion"] = a.motion
    summary, failed = {}, []
    start = time.perf_counter()
    for n, name in enumerate(chosen, 1):
        case = all_cases[name]
        print(f"[{n}/{len(chosen)}] {name}: {len(case.variants)} runs ...", flush=True)
        res = run_case(case, end, a.interval, a.fmu, progress=True, motion=motion)
        write_case_csv(case, res["runs"], out / f"{name}.csv")
        plot_case(case, res["runs"], res["measures"], out / f"{name}.png")
        ok = all(c.holds for c in res["claims"])
        failed += [] if ok else [name]
        reused = sum(1 for w in res["wall"] if w == 0.0)
        print(
            f"[{n}/{len(chosen)}] {name}: {sum(res['wall']):.1f} s wall"
            f"{f' ({reused} reused)' if reused else ''}; max ε "
            + ", ".join(f"{m['max_eps']:.3e}" for m in res["measures"])
            + " m; stick phases j3 "
            + ", ".join(str(m["joint3"]["n_stick"]) for m in res["measures"])
            + f"; claim {'holds' if ok else 'DOES NOT HOLD'}",
            flush=True,
        )
        summary[name] = {
            "variants": [v.label for v in case.variants],
            "parameters": [v.parameters for v in case.variants],
            "measures": res["measures"],
            "stick_phases": [{f"joint{j}": stick_phases(r, j) for j in FLEXIBLE} for r in res["runs"]],
            "claims": [{"text": c.text, "holds": c.holds} for c in res["claims"]],
            "wall": res["wall"],
        }
    total = time.perf_counter() - start
    settings["wall"] = total
    (out / "summary.json").write_text(
        json.dumps({"settings": settings, "cases": summary}, indent=1, ensure_ascii=False), encoding="utf-8"
    )
    (out / "summary.md").write_text(summary_markdown(summary, settings), encoding="utf-8")
    print(
        f"study: {len(chosen)} cases in {total:.1f} s wall; wrote {out}/<case>.csv, <case>.png, "
        f"summary.json, summary.md" + (f"; claims NOT holding: {failed}" if failed else "; every claim holds")
    )
    return 0
