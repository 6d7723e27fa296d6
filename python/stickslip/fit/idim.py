"""The equation-error stage (Gautier's inverse dynamic identification model, IDIM-LS):
friction and drive parameters from the measured motion itself, without a simulation.

Along each experiment whose flexible joints' positions q are all measured:

1. q, q̇, q̈ of the flexible joints by a Savitzky-Golay fit of the encoders (cubic, about
   ±3 ms); the rigid joints' q, q̇, q̈ are their commands (exact).
2. The engine's own inverse dynamics and joint reactions at those states
   (``target/release/inverse_dynamics`` on the FMU's ``resources/model.toml``): per joint the
   generalized force τ_s (3.9) and the friction's lever load L_s, such that the Coulomb part
   is μ·L_s ((3.11)-(3.15)).
3. In the slip phases of joint s (|q̇_s| well above the derivative's noise) its equation of
   motion (3.9)-(3.10) read backwards,

       τ_s = k_s (q*_s − q_s − σΔ_s) δ + h_s (q̇*_s − q̇_s)
             − [μ_k (1 − e) + μ_s e] L_s sgn q̇_s − b_s q̇_s,     e = exp(−|q̇_s|/v_s)

   is linear in k, h, μ_k, μ_s (for v_s > 0) and the viscous b: a linear least squares over
   the slip samples gives those of them that are estimated (the others fixed at their
   initial values). With v_s = 0, μ_s is bounded by the stick phases instead: while joint s
   holds, |F^d − τ_s| ≤ μ_s L_s (3.16), so the largest ratio seen (its 99th percentile) is the
   estimate of μ_s.

The result is a start for the output-error stage, not the estimate: filtered derivatives
bias it, and a stiff drive's deflection is a small difference of two encoders.
"""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from ..fmu import ROOT

INVERSE_DYNAMICS = ROOT / "target" / "release" / "inverse_dynamics"
LINEAR = ("k", "h", "mu_k", "mu_s", "b_v")  # parameters the slip equation is linear in
# The parameters inverse dynamics and the lever loads depend on: masses and contact geometry.
RIGID_BODY = ("m", "slider_a", "slider_b", "slider_c", "d_A", "d_B", "d_C", "l_A", "l_B")


def joint_of(name: str):
    """("mu_k", 3) of "mu_k[3]", or None."""
    m = re.fullmatch(r"([A-Za-z_]+)\[(\d+)\]", name)
    return (m.group(1), int(m.group(2))) if m else None


def estimate(spec, unzipdir: str, flexible: list, initial: dict, start_values: dict) -> tuple:
    """(θ dict of the estimated parameters this stage could estimate, notes)."""
    from scipy.signal import savgol_filter

    notes = []
    targets = {}
    for e in spec.estimates:
        j = joint_of(e.name)
        if j and j[0] in LINEAR and j[1] in flexible:
            targets.setdefault(j[1], []).append(j[0])
    if not targets:
        return {}, ["equation-error stage: no estimated parameter enters a flexible joint's slip equation linearly"]
    if not INVERSE_DYNAMICS.is_file():
        return {}, [f"equation-error stage skipped: {INVERSE_DYNAMICS} not built (cargo build --release)"]
    model = Path(unzipdir) / "resources" / "model.toml"
    rows = {i: [] for i in targets}
    stuck = {i: [] for i in targets}
    for ex in spec.experiments:
        measured = {c.output: c.values for c in ex.channels}
        if any(f"q[{i}]" not in measured for i in flexible):
            notes.append(f"equation-error stage: experiment {ex.name!r} does not measure every flexible joint's q")
            continue
        known = {**start_values, **initial, **ex.parameters}
        t = ex.time
        dt = float(np.median(np.diff(t)))
        window = min(len(t) - (1 - len(t) % 2), max(5, 2 * round(0.003 / dt) + 1))
        cmd = np.array([np.concatenate(ex.motion(float(tk), 0.0)) for tk in t])  # q*, q*', q*''
        n = cmd.shape[1] // 3
        q, qd, qdd = cmd[:, :n].copy(), cmd[:, n : 2 * n].copy(), cmd[:, 2 * n :].copy()
        for i in flexible:
            y = measured[f"q[{i}]"]
            q[:, i - 1] = savgol_filter(y, window, 3, mode="interp")
            qd[:, i - 1] = savgol_filter(y, window, 3, deriv=1, delta=dt, mode="interp")
            qdd[:, i - 1] = savgol_filter(y, window, 3, deriv=2, delta=dt, mode="interp")
        loads = _inverse_dynamics(model, q, qd, qdd, known, ex.name)
        noise = min(c.sigma for c in ex.channels if c.output.startswith("q["))
        v_noise = 10.0 * noise / (dt * (window // 2))  # well above the filtered slope's noise
        for i, names in targets.items():
            s = i - 1
            k, h, delta = known.get(f"k[{i}]", 0.0), known.get(f"h[{i}]", 0.0), known.get(f"Delta[{i}]", 0.0)
            stretch = cmd[:, s] - q[:, s]
            engaged = np.abs(stretch) >= delta
            deflection = np.where(engaged, stretch - np.sign(stretch) * delta, 0.0)
            rate = cmd[:, n + s] - qd[:, s]
            tau, load = loads["tau"][:, s], loads["load"][:, s]
            v = qd[:, s]
            vs = known.get(f"v_s[{i}]", 0.0)
            e = np.exp(-np.abs(v) / vs) if vs > 0 else np.zeros_like(v)
            sgn = np.sign(v)
            features = {
                "k": deflection,
                "h": rate,
                "mu_k": -load * sgn * (1.0 - e),
                "mu_s": -load * sgn * e,
                "b_v": -v,
            }
            if vs <= 0:
                features.pop("mu_s")
            slip = np.abs(v) > v_noise
            free = [x for x in names if x in features]
            fixed = [x for x in features if x not in free]
            values = {
                "k": k,
                "h": h,
                "mu_k": known.get(f"mu_k[{i}]", 0.0),
                "mu_s": known.get(f"mu_s[{i}]", 0.0),
                "b_v": known.get(f"b_v[{i}]", 0.0),
            }
            y = tau - sum(features[x] * values[x] for x in fixed)
            rows[i].append((np.column_stack([features[x] for x in free])[slip], y[slip], free))
            drive = k * deflection + h * rate
            hold = (np.abs(v) < 0.3 * v_noise) & (load > 0)
            stuck[i].append(np.abs(drive - tau)[hold] / load[hold])
    theta = {}
    for i, parts in rows.items():
        if not parts:
            continue
        free = parts[0][2]
        A = np.vstack([p[0] for p in parts])
        y = np.concatenate([p[1] for p in parts])
        if len(y) < 3 * len(free) or not free:
            notes.append(f"equation-error stage: joint {i}: {len(y)} slip samples, too few for {free}")
        elif free:
            col = np.linalg.norm(A, axis=0)
            col[col == 0] = 1.0
            sol, *_ = np.linalg.lstsq(A / col, y, rcond=None)
            sol = sol / col
            resid = y - A @ sol
            notes.append(
                f"equation-error stage: joint {i}: {len(y)} slip samples, "
                + ", ".join(f"{x}[{i}] = {v:.6g}" for x, v in zip(free, sol, strict=True))
                + f", residual rms {np.sqrt(np.mean(resid**2)):.3g}"
            )
            theta.update({f"{x}[{i}]": float(v) for x, v in zip(free, sol, strict=True)})
        ratios = np.concatenate(stuck[i]) if stuck[i] else np.empty(0)
        if f"mu_s[{i}]" in {e.name for e in spec.estimates} and f"mu_s[{i}]" not in theta and len(ratios) > 10:
            theta[f"mu_s[{i}]"] = float(np.percentile(ratios, 99))
            notes.append(
                f"equation-error stage: joint {i}: mu_s[{i}] >= {theta[f'mu_s[{i}]']:.4g} from "
                f"{len(ratios)} stuck samples (99th percentile of |F_d - tau|/L)"
            )
    return theta, notes


def _inverse_dynamics(model: Path, q, qd, qdd, known: dict, name: str) -> dict:
    """tau[i] and load[i] at every state, by the engine (``inverse_dynamics``), with the
    experiment's known parameters and the initial values applied (``--set``)."""
    n = q.shape[1]
    header = [f"q[{i}]" for i in range(1, n + 1)] + [f"qd[{i}]" for i in range(1, n + 1)]
    header += [f"qdd[{i}]" for i in range(1, n + 1)]
    with tempfile.TemporaryDirectory(prefix="stickslip-idim-") as tmp:
        states, out = Path(tmp) / "states.csv", Path(tmp) / "loads.csv"
        np.savetxt(states, np.hstack([q, qd, qdd]), delimiter=",", header=",".join(header), comments="", fmt="%.17g")
        sets = [a for k, v in known.items() if (joint_of(k) or ("",))[0] in RIGID_BODY for a in ("--set", f"{k}={v!r}")]
        cmd = [str(INVERSE_DYNAMICS), "--model", str(model), "--states", str(states), "--out", str(out), *sets]
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"inverse_dynamics for experiment {name!r}: {done.stderr.strip()}")
        import pandas as pd

        table = pd.read_csv(out)
    tau = np.column_stack([table[f"tau[{i}]"].to_numpy() for i in range(1, n + 1)])
    load = np.column_stack(
        [table[f"load[{i}]"].to_numpy() if f"load[{i}]" in table else np.zeros(len(table)) for i in range(1, n + 1)]
    )
    return {"tau": tau, "load": load}
