"""What a fit writes into its DIR: fit.json, report.md, fit_<experiment>.png, correlation.png
and fitted.toml. Everything is first written into a temporary directory beside DIR and moved
into place at the end, so DIR never holds half a result."""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .runner import Payload, run


def write(result: dict, spec, out: Path) -> None:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        public = {k: v for k, v in result.items() if not k.startswith("_")}
        (tmp / "fit.json").write_text(json.dumps(_finite(public), indent=2, allow_nan=False, default=_jsonable) + "\n")
        figures = _plots(result, spec, tmp)
        (tmp / "fitted.toml").write_text(fitted_toml(result, spec, out))
        (tmp / "report.md").write_text(report_md(result, spec, figures))
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def write_failure(record: dict, spec, out: Path, trace: str | None = None) -> None:
    """A fit that did not finish: fit.json (``record``: the verdict FAILED, why, every start with
    its cost or the reason it has none) and report.md, with the traceback of an unexpected failure
    in error.log; no fitted.toml and no figures, since there is no answer to replay."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        (tmp / "fit.json").write_text(json.dumps(_finite(record), indent=2, allow_nan=False, default=_jsonable) + "\n")
        lines = [
            "# Fit report",
            "",
            f"FMU `{spec.fmu.name}`, {len(spec.experiments)} experiment(s); {record['n_evaluations']} FMU runs in "
            f"{record['wall_s']:.1f} s.",
            "",
            f"**Verdict: {record['verdict']}.**",
            "",
            "## Starts",
            "",
            "| start | cost at start | cost | status | why it ended so |",
            "|---|---|---|---|---|",
        ]
        for st in record["starts"]:
            cost = f"{st['cost']:.6g}" if st["cost"] is not None else "–"
            at = f"{st['cost_at_start']:.6g}" if st["cost_at_start"] is not None else "–"
            lines.append(f"| {st['origin']} | {at} | {cost} | {st['status']} | {st['message'] or '–'} |")
        if record["parameters"]:
            lines += ["", "## The best start's parameters (no standard errors: its uncertainty failed)", ""]
            lines += [f"- `{n}` = {p['value']:.8g}" for n, p in record["parameters"].items()]
        lines += ["", "## Method", ""] + [f"- {note}" for note in record["method"]["equation_error_stage"]]
        if trace:
            (tmp / "error.log").write_text(trace)
            lines += ["", "The traceback is in error.log; please report it with the SPEC."]
        (tmp / "report.md").write_text("\n".join(lines) + "\n")
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _finite(x):
    """NaN and infinities (a standard error of a parameter the data do not determine) as null."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)) and not math.isfinite(x):
        return None
    return x


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    raise TypeError(f"not JSON: {type(x).__name__}")


def fitted_toml(result: dict, spec, out=None) -> str:
    """The estimates as a [parameters] table, the fit's error_tolerance in [settings], each
    experiment's known values in [known.<name>]; the comment at the top gives the command that
    replays an experiment with them (its inputs, known values and start state, as the fit ran
    it: stickslip simulate --spec)."""
    tol = result["method"]["error_tolerance"]  # the SPEC's, or the tighter one the fit ended at
    settings = {} if tol is None else {"error_tolerance": tol}
    here = Path(out) / "fitted.toml" if out is not None else Path("fitted.toml")
    replays = Path(out) / "replay" if out is not None else Path("replay")
    source = spec.source if Path(spec.source).is_file() else "SPEC.toml"  # a SPEC given as a dict has no file
    lines = ["# The fitted parameters (stickslip fit). To replay a fitted experiment with them:"]
    horizon = result["method"].get("horizon_s")
    ahead = f" --horizon {horizon!r}" if horizon is not None else ""
    for e in spec.experiments:
        lines.append(
            f"#   stickslip simulate --spec {source} --experiment '{e.name}' --fitted {here}{ahead} --out {replays}"
        )
    lines += [
        "# (held-out runs: a SPEC of their experiments, without [estimate], in place of the fit's).",
        "# [parameters]: the estimates (full precision) with their standard errors;",
        "# [settings]: what the fit ran the FMU with; [known.<experiment>]: each experiment's given values.",
        "[parameters]",
    ]
    for name, p in result["parameters"].items():
        lines.append(f'"{name}" = {p["value"]!r}  # ± {p["std_error"]:.3g} (1 standard error)')
    if settings:
        lines += ["", "[settings]"] + [f'"{n}" = {v!r}' for n, v in settings.items()]
    fitted_start = {}
    for p in (result.get("start_state") or {}).values():
        fitted_start.setdefault(p["experiment"], []).append(p)
    for name, rows in fitted_start.items():
        lines += ["", f'[start."{name}"]  # the start state the fit found for the joints moving at its first sample']
        lines += [f'"{p["variable"]}" = {p["value"]!r}  # ± {p["std_error"]:.3g} (read {p["read"]!r})' for p in rows]
    for e in spec.experiments:
        if e.parameters:
            lines += ["", f'[known."{e.name}"]'] + [f'"{n}" = {_toml_value(v)}' for n, v in e.parameters.items()]
    return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else repr(float(v))


def report_md(result: dict, spec, figures: list) -> str:
    m = result["method"]
    shooting_word = "" if m.get("stage") == "equation-error" else " shooting"
    lines = [
        "# Fit report",
        "",
        f"FMU `{spec.fmu.name}`, {len(spec.experiments)} experiment(s), {m['samples']} samples; "
        f"{m['shooting']}{shooting_word}, loss `{m['loss']}`; {result['n_evaluations']} FMU runs in "
        f"{result['wall_s']:.1f} s; {'converged' if result['converged'] else 'NOT converged'}.",
        "",
        f"**Verdict: {result['verdict']}.**",
        "",
        "| parameter | estimate | standard error | relative | classical / sandwich SE | 95 % profile interval "
        "| initial | bounds | at bound |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, p in result["parameters"].items():
        rel = p["std_error"] / abs(p["value"]) if p["value"] else math.inf
        prof = p.get("profile")
        interval = f"[{prof['interval_95'][0]:.6g}, {prof['interval_95'][1]:.6g}]" if prof else "– (quadratic)"
        lines.append(
            f"| `{name}` | {p['value']:.8g} | {p['std_error']:.3g} | {rel:.2e} | "
            f"{p['std_error_classical']:.3g} / {p['std_error_sandwich']:.3g} | {interval} | {p['initial']:.6g} | "
            f"[{p['bounds'][0]:g}, {p['bounds'][1]:g}] | {'yes' if p['at_bound'] else 'no'} |"
        )
    lines += [
        "",
        "The standard error is the largest of the classical σ̂²(JᵀJ)⁻¹ one, the sandwich one (residuals "
        "correlated in time) and, for a profiled parameter, the profile interval's half-width / 1.96; joined in "
        "root sum of squares by the FMU's numerical error where it exceeds that (the estimate's move between the "
        "last two error tolerances) and by the distance to other minima of similar cost (NOT UNIQUE).",
    ]
    if result.get("start_state"):
        lines += [
            "",
            "Start state, estimated with the parameters (joints moving at an experiment's first sample, whose "
            "reading through the derivative filter at the record's edge is uncertain):",
            "",
            "| start unknown | estimate | standard error | read | bounds | at bound |",
            "|---|---|---|---|---|---|",
        ]
        for name, p in result["start_state"].items():
            lines.append(
                f"| `{name}` | {p['value']:.8g} | {p['std_error']:.3g} | {p['read']:.8g} | "
                f"[{p['bounds'][0]:.8g}, {p['bounds'][1]:.8g}] | {'yes' if p['at_bound'] else 'no'} |"
            )
    lines += [
        "",
        f"Cost {result['cost']:.6g}; rms normalized residual {result['rms_normalized_residual']:.4g} "
        "(1 when the residuals are the stated noise).",
    ]
    lines += ["", "Residual rms per channel: " + ", ".join(f"`{k}` {v:.3g}" for k, v in result["residual_rms"].items())]
    gof = result["goodness_of_fit"]
    lines += [
        "",
        "## Goodness of fit",
        "",
        f"χ² = {gof['chi_square']:.6g} for {gof['degrees_of_freedom']} degrees of freedom (reduced "
        f"{gof['reduced_chi_square']:.4g}, p = {gof['p_value']:.2g}), with each channel's σ = sqrt(sigma² + "
        "resolution²/12). Per channel: the residual variance in units of that σ, its white part "
        "(mean(Δr²)/2, sample-to-sample noise) and slow part (the rest: structure, or an encoder's rounding "
        "held through a stiction phase, up to the allowance).",
        "",
        "| channel | samples | variance | white | slow | allowance | lag-1 autocorrelation | χ² p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, c in gof["channels"].items():
        lines.append(
            f"| `{name}` | {c['n']} | {c['variance']:.4g} | {c['white']:.4g} | {c['slow']:.3g} | "
            f"{c['allowance']:.3g} | {c['rho']:.3f} | {c['p_value']:.2g} |"
        )
    lines += ["", "## Warnings", ""]
    lines += [f"- {w}" for w in result["warnings"]] or ["none"]
    names = result["correlation"]["names"]
    lines += [
        "",
        "## Correlation",
        "",
        "| | " + " | ".join(f"`{n}`" for n in names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for n, row in zip(names, result["correlation"]["matrix"], strict=True):
        lines.append(f"| `{n}` | " + " | ".join(_corr(c) for c in row) + " |")
    lines += [
        "",
        "## Starts",
        "",
        "Single-shooting cost at each start, after the multiple-shooting continuation, and at its end "
        "(single shooting goes on from the better of the first two).",
        "",
        "| start | cost at start | last multiple-shooting stage | after continuation | cost | status |",
        "|---|---|---|---|---|---|",
    ]

    def number(x):
        return f"{x:.6g}" if x is not None else "–"

    for s in result["starts"]:
        lines.append(
            f"| {s['origin']} | {number(s.get('cost_at_start'))} | {number(s['multiple_shooting_cost'])} | "
            f"{number(s.get('cost_after_continuation'))} | {number(s['cost'])} | {s['status']} |"
        )
    lines += ["", "## Method", ""]
    lines += [f"- Experiment {name!r} starts {how}." for name, how in m.get("start", {}).items()]
    lines += [f"- Experiment {name!r}: derivative filter {how}." for name, how in m.get("derivatives", {}).items()]
    lines += [f"- {note}" for note in m["equation_error_stage"]]
    if m.get("stage") == "equation-error":
        lines.append(
            '- The answer is the equation-error stage\'s (`[options] stage = "equation-error"`): its standard '
            "errors are its least squares' own (residuals as independent); the FMU ran once at it for the residuals "
            "and figures. The correlations between parameters are not computed (shown as 0)."
        )
    else:
        lines.append(
            f"- Jacobian: forward differences of step {m['diff_step']:g} (of each normalized range); with a 3x step "
            f"the standard errors change by at most {100 * m['std_error_change_with_3x_step']:.1f} %."
        )
    for check in m["error_tolerance_checks"]:
        lines.append(
            f"- error_tolerance {check['error_tolerance']:g}: a Gauss-Newton step at a tenfold tighter tolerance moves "
            f"the estimates by up to {check['shift_at_tenfold_tighter_se']:.2g} standard errors"
            + ("; refitted there" if check.get("refitted") else "")
        )
    for name, noise in m["noise"].items():
        if noise["resolution"]:
            how = "detected from the samples' levels" if noise["resolution_detected"] else "given"
            lines.append(
                f"- `{name}`: encoder resolution {noise['resolution']:.6g} ({how}), sigma {noise['sigma']:.3g}"
            )
    lines.append(
        f"- Noise scale σ̂² = {m['sigma_scale']:.4g} "
        + ("(absolute sigmas: 1)" if m["absolute_sigma"] else "(from the residuals; the sigmas are relative)")
    )
    for name, rows in result.get("dropped_rows", {}).items():
        lines.append(f"- Experiment {name!r}: rows dropped for NaN samples (drop_nan): lines {rows}")
    if result["failed_runs"]["count"]:
        lines.append(f"- Runs the FMU refused or discarded during the fit: {result['failed_runs']['by_status']}")
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def _corr(c) -> str:
    return f"{c:+.3f}" if c is not None and math.isfinite(c) else "–"


def _plots(result: dict, spec, out: Path) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..fmu import content_hash
    from .replay import figure

    figures = []
    data = Path(spec.fmu).read_bytes()
    digest = content_hash(data)
    values = {n: p["value"] for n, p in result["parameters"].items()}
    if result["method"]["error_tolerance"] is not None:
        values["error_tolerance"] = result["method"]["error_tolerance"]
    md = spec.model_description
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    payloads = result["_internal"].get("payloads")
    for k, e in enumerate(spec.experiments):
        start = payloads[k].start if payloads else None
        horizon = result["_internal"].get("segments")
        res = run(
            digest,
            Payload(e.name, e.time, e.motion, e.torques, outputs, dict(e.parameters), start),
            values,
            horizon[k] if horizon else None,
            fmu_data=data,
        )
        name = f"fit_{_safe(e.name)}.png"
        columns = {o: res.values[:, j] for j, o in enumerate(outputs)}
        figure(e, columns, md, out / name, f"experiment {e.name}: measured and fitted, residuals")
        figures.append(name)
    names = result["correlation"]["names"]
    corr = np.array([[np.nan if c is None else c for c in row] for row in result["correlation"]["matrix"]])
    fig, ax = plt.subplots(figsize=(1.2 + 0.9 * len(names), 1.0 + 0.8 * len(names)))
    im = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_yticks(range(len(names)), names)
    for a in range(len(names)):
        for b in range(len(names)):
            ax.text(b, a, _corr(corr[a, b]), ha="center", va="center", fontsize=8)
    fig.colorbar(im, ax=ax, shrink=0.8)
    ax.set_title("correlation of the estimates")
    fig.tight_layout()
    fig.savefig(out / "correlation.png", dpi=110)
    plt.close(fig)
    figures.append("correlation.png")
    return figures


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)
