#!/usr/bin/env python3
"""Plot a URDF arm's run through its FMU (`stickslip simulate --motion ...` CSV).

Usage:  python scripts/plot_urdf_arm.py RUN.csv OUTDIR --fmu ARM.fmu [--name PREFIX]
            [--loads 1,2] [--summary SUMMARY.json]

The FMU's modelDescription gives the joints' URDF names and which drives are
flexible (those with a stiffness parameter `k[i]`); without `--fmu` the flexible
joints are those whose lag eps_joint[i] is not identically zero.

Writes into OUTDIR (PREFIX defaults to the CSV's stem):
    PREFIX_lag.png     the joint lag eps_joint[i] = q*_i - q_i of every flexible
                       joint, one axis each (rad), stiction phases as red bars
    PREFIX_eps.png     the end-point error eps = |x_E(q) - x_E(q*)| (mm), its own axis
    PREFIX_stick.png   the joint velocities qd[i] of the flexible joints and their
                       stiction chart (bar: stick[i] = 1)
    PREFIX_loads.png   per joint of --loads (default 1, 2): the bearing normal load
                       N_normal[i] and the joint reaction at its reaction point, in the
                       URDF child link frame of the joint (axial force |f_z|, radial
                       force |f_xy|, bending moment |n_xy|), and the friction |F_friction|
and, with --summary, a JSON file of per-joint numbers (stiction phases and time,
largest lag, largest eps, largest normal load) that the main job prints.
"""

import argparse
import json
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))
from plot_reference import STICK_COLOR, indexed, plot_with_stick_bar, read_csv, stick_segments


def fmu_joints(fmu):
    """({index: URDF joint name}, set of flexible joint indices) from the FMU's modelDescription:
    the names as motion files read them (stickslip.motion.fmu_joints), the flexible joints
    those with a stiffness k[i]."""
    from fmpy import read_model_description

    from stickslip.motion import fmu_joints as joint_names

    md = read_model_description(str(fmu))
    flexible = {int(m.group(1)) for v in md.modelVariables if (m := re.fullmatch(r"k\[(\d+)\]", v.name))}
    return joint_names(md)[1], flexible


def label(i, names):
    return f"joint {i} ({names[i]})" if i in names else f"joint {i}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--fmu", type=Path, help="the FMU the CSV came from (joint names, flexible drives)")
    ap.add_argument("--name", help="file name prefix (default: the CSV's stem)")
    ap.add_argument("--loads", default="1,2", help="joints whose normal loads and reactions are plotted (default 1,2)")
    ap.add_argument("--summary", type=Path, help="write per-joint numbers as JSON here")
    args = ap.parse_args(argv)

    header, cols = read_csv(args.csv)
    if "time" not in cols:
        raise SystemExit(f"{args.csv}: no 'time' column")
    t = cols["time"]
    q, qd, stick = indexed(header, "q"), indexed(header, "qd"), indexed(header, "stick")
    epsj, nn, ffr = indexed(header, "eps_joint"), indexed(header, "N_normal"), indexed(header, "F_friction")
    if not q or not epsj:
        raise SystemExit(f"{args.csv}: no q[i] / eps_joint[i] columns: not an FMU run of this project")
    names, flexible = fmu_joints(args.fmu) if args.fmu else ({}, set())
    if not flexible:
        flexible = {i for i, c in epsj.items() if np.any(cols[c] != 0.0)}
    flex = sorted(flexible)
    if not flex:
        raise SystemExit(f"{args.csv}: no flexible joint (every eps_joint[i] is zero)")
    prefix = args.name or args.csv.stem
    args.outdir.mkdir(parents=True, exist_ok=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    written = []

    def save(fig, suffix):
        path = args.outdir / f"{prefix}_{suffix}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    # --- joint lag of the flexible joints, each on its own axis -----------------------
    fig, axes = plt.subplots(
        len(flex), 1, sharex=True, squeeze=False, figsize=(10, 1.9 * len(flex) + 1.2), layout="constrained"
    )
    for ax, i in zip(axes[:, 0], flex, strict=True):
        st = cols[stick[i]] if i in stick else None
        plot_with_stick_bar(ax, t, cols[epsj[i]], st, colors[(i - 1) % len(colors)], epsj[i])
        ax.set_ylabel(f"eps_joint[{i}] [rad]")
        ax.set_title(label(i, names), loc="left", fontsize=9, pad=2)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    fig.align_ylabels(axes[:, 0])
    fig.suptitle(f"{prefix}: joint lag q* - q of the flexible joints   (red bars: stiction, stick[i] = 1)")
    save(fig, "lag")

    # --- end-point error --------------------------------------------------------------
    if "eps" in cols:
        fig, ax = plt.subplots(figsize=(10, 3.2), layout="constrained")
        ax.plot(t, cols["eps"] * 1e3, color="k", lw=1.2)
        ax.set_ylabel("eps [mm]")
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
        ax.set_title(
            f"{prefix}: end-point error eps = |x_E(q) - x_E(q*)|, the drives' deflection under gravity "
            f"included   (max {np.nanmax(cols['eps']) * 1e3:.4f} mm)",
            fontsize=10,
        )
        save(fig, "eps")

    # --- stiction chart of the flexible joints ------------------------------------------
    sj = [i for i in flex if i in stick]
    if sj:
        fig, axes = plt.subplots(
            2,
            1,
            sharex=True,
            figsize=(10, 3.2 + 0.55 * len(sj) + 1.6),
            layout="constrained",
            gridspec_kw={"height_ratios": [3.2, 0.55 * len(sj) + 0.4]},
        )
        ax = axes[0]
        for i in sj:
            if i in qd:
                ax.plot(t, cols[qd[i]], lw=1.1, color=colors[(i - 1) % len(colors)], label=f"qd[{i}]")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel("qd[i] [rad/s]")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax = axes[1]
        for row, i in enumerate(sj):
            segs = stick_segments(t, cols[stick[i]])
            if segs:
                ax.broken_barh(segs, (row - 0.35, 0.7), facecolors=STICK_COLOR, edgecolor="none")
        ax.set_yticks(range(len(sj)))
        ax.set_yticklabels([label(i, names) for i in sj], fontsize=8)
        ax.set_ylim(len(sj) - 0.5, -0.5)
        ax.set_xlim(t[0], t[-1])
        ax.grid(True, axis="x", alpha=0.3)
        ax.set_xlabel("time [s]")
        ax.set_title("stiction phases of the flexible joints (bar: stick[i] = 1)", fontsize=10)
        fig.suptitle(f"{prefix}: velocities and stick-slip of the flexible joints")
        save(fig, "stick")

    # --- normal loads and reactions ---------------------------------------------------------
    load_joints = [int(x) for x in args.loads.split(",") if x.strip()]
    load_joints = [i for i in load_joints if i in q]
    if load_joints:
        fig, axes = plt.subplots(
            len(load_joints),
            2,
            sharex=True,
            squeeze=False,
            figsize=(12, 2.6 * len(load_joints) + 1.0),
            layout="constrained",
        )
        for row, i in enumerate(load_joints):
            f = [cols.get(f"f[{i},{k}]") for k in (1, 2, 3)]
            n = [cols.get(f"n[{i},{k}]") for k in (1, 2, 3)]
            ax = axes[row, 0]
            if i in nn:
                ax.plot(t, cols[nn[i]], color="k", lw=1.2, label=f"N_normal[{i}]")
            if all(c is not None for c in f):
                ax.plot(t, np.abs(f[2]), lw=1.0, label="axial |f_z|")
                ax.plot(t, np.hypot(f[0], f[1]), lw=1.0, label="radial |f_xy|")
            ax.set_ylabel("force [N]")
            ax.set_title(label(i, names), loc="left", fontsize=9, pad=2)
            ax.legend(loc="upper right", fontsize=8)
            ax.grid(True, alpha=0.3)
            ax = axes[row, 1]
            if all(c is not None for c in n):
                ax.plot(t, np.hypot(n[0], n[1]), lw=1.1, color="tab:purple", label="bending |n_xy|")
                ax.plot(t, np.abs(n[2]), lw=1.0, color="tab:green", label="axial |n_z| (drive + friction)")
            if i in ffr:
                ax.plot(t, np.abs(cols[ffr[i]]), lw=1.0, color="tab:red", label=f"|F_friction[{i}]|")
            ax.set_ylabel("moment [N m]")
            ax.legend(loc="upper right", fontsize=8)
            ax.grid(True, alpha=0.3)
        for ax in axes[-1]:
            ax.set_xlabel("time [s]")
        fig.suptitle(
            f"{prefix}: bearing normal loads and joint reactions (at the reaction point, "
            "URDF child link frame: z = joint axis)"
        )
        save(fig, "loads")

    summary = {
        "csv": str(args.csv),
        "samples": len(t),
        "t_end": float(t[-1]),
        "eps_max_m": float(np.nanmax(cols["eps"])) if "eps" in cols else None,
        "joints": {},
    }
    for i in flex:
        segs = stick_segments(t, cols[stick[i]]) if i in stick else []
        summary["joints"][str(i)] = {
            "name": names.get(i),
            "stick_phases_in_samples": len(segs),
            "n_stick_final": float(cols[f"n_stick[{i}]"][-1]) if f"n_stick[{i}]" in cols else None,
            "t_stick_final_s": float(cols[f"t_stick[{i}]"][-1]) if f"t_stick[{i}]" in cols else None,
            "lag_max_abs_rad": float(np.nanmax(np.abs(cols[epsj[i]]))),
            "N_normal_max_N": float(np.nanmax(cols[nn[i]])) if i in nn else None,
            "F_friction_max_abs": float(np.nanmax(np.abs(cols[ffr[i]]))) if i in ffr else None,
        }
    if args.summary:
        args.summary.write_text(json.dumps(summary, indent=1), encoding="utf-8")
        written.append(args.summary)

    print(
        f"plot_urdf_arm: {len(t)} samples, t = [{t[0]:g}, {t[-1]:g}] s, flexible joints {flex}; "
        f"eps max {summary['eps_max_m']:.3e} m"
    )
    for i in flex:
        j = summary["joints"][str(i)]
        print(
            f"  {label(i, names)}: {j['n_stick_final']:.0f} stiction phases "
            f"({j['t_stick_final_s']:.3f} s stuck), max |q* - q| {j['lag_max_abs_rad']:.3e} rad, "
            f"max N_normal {j['N_normal_max_N']:.1f} N, max |F_friction| {j['F_friction_max_abs']:.3f} N m"
        )
    for f in written:
        print(f"  wrote {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
