"""What ``stickslip identify`` writes into its DIR: identify.json, report.md, the identified model
(identified.toml, and identified.urdf for a URDF arm) and one figure per held-out run
(heldout_<run>.png: measured torques against the identified, catalogue and per-joint models').
Everything is first written into a temporary directory beside DIR and moved into place at the
end, so DIR never holds half a result."""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

from ..fit.report import _finite, _jsonable, _safe


def write(result: dict, out: Path) -> None:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        from .model_file import write_model

        internal = result["_internal"]
        eq = internal["equations"]
        theta = internal["estimates"].theta
        toml, urdf = write_model(
            internal["unzipdir"], tmp, pi=theta[: eq.inertial], settings=result["model_settings"], name="identified"
        )
        result["model_file"] = str(out / Path(toml).name)
        result["urdf_file"] = str(out / Path(urdf).name) if urdf else None
        figures = _figures(result, tmp)
        public = {k: v for k, v in result.items() if not k.startswith("_")}
        (tmp / "identify.json").write_text(
            json.dumps(_finite(public), indent=2, allow_nan=False, default=_jsonable) + "\n"
        )
        (tmp / "report.md").write_text(report_md(result, figures))
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def report_md(result: dict, figures: list) -> str:
    m = result["method"]
    lines = [
        "# Identification report",
        "",
        f"{m['samples']} torque samples of {len(m['experiments'])} run(s) ({', '.join(m['experiments'])}); friction "
        f"`{m['friction']}`, armature {'estimated' if m['armature'] else 'not estimated'}, prior {m['prior']:g}; "
        f"semidefinite least squares {m['solver']['status']}; {result['wall_s']:.1f} s.",
        "",
        f"**{'Trusted' if result['trusted'] else 'NOT TRUSTED: see the warnings'}.** The identified model: "
        f"`{Path(result.get('model_file', 'identified.toml')).name}`"
        + (f" with `{Path(result['urdf_file']).name}`" if result.get("urdf_file") else "")
        + "; build its FMU with `bash scripts/build_fmu.sh --model "
        + f"{result.get('model_file', 'identified.toml')} --out identified.fmu`.",
        "",
        "## Validation: held-out torques",
        "",
        "Relative rms error rms(τ̂ − τ)/rms(τ) of each held-out run's measured torques, predicted from its "
        "measured motion through the same derivative filter.",
        "",
    ]
    for run, rows in result["validation"].items():
        models = list(next(iter(rows.values())))
        lines += [f"### {run}", "", "| joint | " + " | ".join(models) + " |", "|---|" + "---|" * len(models)]
        for i, row in rows.items():
            lines.append(f"| {i} | " + " | ".join(f"{row[k]:.4f}" for k in models) + " |")
        lines.append("")
    lines += [
        "## Base parameters",
        "",
        "The combinations of the standard parameters the torques identify (β = π_b + K π_d; "
        "docs/calibration.md), by weighted least squares, with the larger of the classical and the "
        "Newey-West standard error; and the physically consistent model's value of each.",
        "",
        "| # | combination | estimate | standard error | relative | consistent model |",
        "|---|---|---|---|---|---|",
    ]
    for k, b in enumerate(result["base_parameters"], start=1):
        rel = b["std_error"] / abs(b["value"]) if b["value"] else math.inf
        lines.append(
            f"| {k} | `{b['combination']}` | {b['value']:.6g} | {b['std_error']:.3g} | {rel:.2e} | "
            f"{b['consistent_value']:.6g} |"
        )
    if result["unidentifiable"]:
        lines += [
            "",
            "Act on no measured torque (the catalogue's values stand): " + ", ".join(result["unidentifiable"]) + ".",
        ]
    lines += ["", "## The identified model", "", "| parameter | identified | catalogue |", "|---|---|---|"]
    for name, value in result["model"].items():
        lines.append(f"| `{name}` | {value:.6g} | {result['catalogue'][name]:.6g} |")
    lines += [
        "",
        "Smallest eigenvalue of each link's pseudo-inertia (> 0: a physical body): "
        + ", ".join(f"{x:.3g}" for x in result["pseudo_inertia_min_eigenvalue"]),
        "",
        "Written into the model file as FMU parameters: " + (", ".join(result["model_settings"]) or "none") + ".",
        "",
        "## Warnings",
        "",
    ]
    lines += [f"- {w}" for w in result["warnings"]] or ["none"]
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def _figures(result: dict, out: Path) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figures = []
    for run, (t, predicted) in result["_internal"]["series"].items():
        joints = sorted(predicted)
        fig, axes = plt.subplots(len(joints), 1, figsize=(9, 1.9 * len(joints) + 0.6), sharex=True, squeeze=False)
        for ax, i in zip(axes[:, 0], joints, strict=True):
            s = predicted[i]
            time = t[s["index"]]
            ax.plot(time, s["measured"], color="0.2", lw=1.2, label="measured")
            for name, style in (("identified", "-"), ("catalogue", ":"), ("per joint", "--")):
                if name in s:
                    err = result["validation"][run][str(i)][name]
                    ax.plot(time, s[name], style, lw=1.0, label=f"{name} ({100 * err:.1f} %)")
            ax.set_ylabel(f"τ[{i}]")
            ax.legend(fontsize=7, loc="upper right", ncol=4)
        axes[-1, 0].set_xlabel("t (s)")
        fig.suptitle(f"held-out run {run}: measured torques and the models' predictions (relative rms)")
        fig.tight_layout()
        name = f"heldout_{_safe(run)}.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        figures.append(name)
    return figures


__all__ = ["report_md", "write"]
