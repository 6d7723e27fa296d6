"""``stickslip identify SPEC --out DIR``: a real arm's physically valid model from its torque logs.

The pipeline, one stage per module:

1. :mod:`.spec`: the SPEC and its logs (positions of every joint, measured joint torques);
2. :mod:`.equations`: the logs through the derivative filter, one equation per measured torque
   sample, linear in the links' standard parameters (the engine's regressor, from the FMU's own
   binary), friction and armature; the base parameters of those columns (:mod:`.base`);
3. :mod:`.consistent`: the base parameters' weighted least squares with standard errors, and a
   physically consistent model of the same torques (semidefinite least squares);
4. :mod:`.validate`: the held-out runs' torques predicted by the identified model, the
   catalogue model and a per-joint model;
5. :mod:`.model_file`: the identified model written as a model file (and URDF) from which
   ``scripts/build_fmu.sh --model`` builds the identified FMU; :mod:`.report`: identify.json,
   report.md and figures.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .consistent import estimate, pseudo_inertia_eigenvalues
from .equations import equations, filtered, structural_base, with_lever_load
from .spec import IdentifySpec, load
from .validate import per_joint_fit, predictions, table

# The lever loads L of the dry friction follow the identified links' reactions: the equations
# are solved again with L at the identified model until every μ_k moves by less than
# LEVER_CHANGE of itself, at most LEVER_ITERATIONS times.
LEVER_ITERATIONS = 4
LEVER_CHANGE = 1e-3


class IdentifyError(RuntimeError):
    """An identification that could not finish; the message says why."""


def identify(spec, out=None, progress=None) -> dict:
    """Identifies the SPEC (a path, a dict or an :class:`IdentifySpec`); writes DIR ``out`` when
    given; returns the content of identify.json (plus ``"_internal"``: the arrays the report and
    figures use)."""
    from ..fit.idim import inverse_dynamics
    from ..fit.regressor import joint_torque_regressor
    from ..fmu import content_hash, unpacked
    from .model_file import model_texts

    t0 = time.perf_counter()
    say = progress or (lambda line: None)
    spec = spec if isinstance(spec, IdentifySpec) else load(spec)
    data = spec.fmu.read_bytes()
    unzipdir = unpacked(data, content_hash(data))

    def regressor(states):
        return joint_torque_regressor(unzipdir, states)

    def lever(source):
        return lambda states: inverse_dynamics(unzipdir, states, source=source)[1]

    coulomb = "coulomb" in spec.friction
    logs = [filtered(log, spec.derivatives, coulomb) for log in spec.experiments]
    motions = [with_lever_load(m, lever(None)) for m in logs]
    base = structural_base(regressor, spec.n, spec.friction, spec.armature, lever=lever(None))
    loaded = sorted(int(name[5:-1]) for name in base.names if name.startswith("mu_k["))
    _, pi_catalogue, _ = regressor(np.zeros((1, 3 * spec.n)))
    iterations, previous = [], None
    for _ in range(LEVER_ITERATIONS):
        eq = equations(motions, regressor, spec.friction, spec.armature, loaded=loaded)
        say(
            f"identify: {len(eq.b)} torque samples of {len(spec.experiments)} run(s), {len(eq.names)} parameters, "
            f"{base.count} base parameters"
        )
        est = estimate(eq, base, pi_catalogue, spec.prior)
        mu = np.array([est.theta[eq.names.index(f"mu_k[{i}]")] for i in loaded])
        iterations.append({"mu_k": dict(zip(loaded, mu.tolist(), strict=True)), "solver": est.solver["status"]})
        say(f"identify: physically consistent model: {est.solver['status']} ({time.perf_counter() - t0:.1f} s)")
        settled = previous is not None and np.allclose(mu, previous, rtol=LEVER_CHANGE, atol=0.0)
        if not loaded or settled or len(iterations) == LEVER_ITERATIONS:
            break
        # The lever loads come from the joint reactions, which the links' inertias set: again at
        # the identified links, until μ_k no longer moves.
        previous = mu
        source = model_texts(unzipdir, est.theta[: eq.inertial], urdf_file_name="iteration.urdf")
        motions = [with_lever_load(m, lever(source)) for m in logs]
    if loaded:
        spread = unidentified_spread(
            est,
            eq,
            base,
            logs,
            regressor,
            spec,
            lambda pi: lever(model_texts(unzipdir, pi, urdf_file_name="x.urdf")),
            loaded,
        )
        est.std_error_catalogue = spread
        est.std_error = np.hypot(est.std_error, spread)
        worst = float(np.max(spread / est.std_error))
        say(f"identify: the unidentified combinations add up to {worst:.2f} of a standard error through the loads")
    # The held-out runs' lever loads at the identified links.
    final = model_texts(unzipdir, est.theta[: eq.inertial], urdf_file_name="identified.urdf") if loaded else None
    catalogue_theta = np.concatenate([pi_catalogue, np.zeros(len(eq.names) - eq.inertial)])
    per_joint = per_joint_fit(motions)
    validation, series = {}, {}
    for log in spec.heldout:
        # The samples where the model's friction law holds: a joint at rest holds any friction up
        # to its static limit, which no sgn q̇ law predicts; the same rows the fit keeps.
        motion = with_lever_load(filtered(log, spec.derivatives, coulomb), lever(final))
        predicted = predictions(
            motion,
            regressor,
            spec.friction,
            spec.armature,
            {"identified": est.theta, "catalogue": catalogue_theta},
            per_joint,
            loaded,
        )
        validation[log.name] = table(predicted)
        series[log.name] = (log.time, predicted)
        for i, row in validation[log.name].items():
            say(
                f"identify: held-out {log.name!r} joint {i}: relative rms "
                + ", ".join(f"{name} {value:.3f}" for name, value in row.items())
            )
    warnings = list(est.warnings)
    for name, rows in validation.items():
        for i, row in rows.items():
            if row["identified"] > row["catalogue"] or row["identified"] > row.get("per joint", np.inf):
                other = "catalogue" if row["identified"] > row["catalogue"] else "per-joint"
                warnings.append(
                    f"held-out {name!r}, joint {i}: the identified model predicts its torque worse (relative rms "
                    f"{row['identified']:.3f}) than the {other} model: the logs may not excite what this run does, "
                    "or the model misses an effect"
                )
    if not spec.heldout:
        warnings.append("no [[heldout]] run: the model is not validated on torques it was not fitted to")
    result = {
        "trusted": not warnings,
        "base_parameters": [
            {
                "combination": text,
                "value": float(est.beta[k]),
                "std_error": float(est.std_error[k]),
                "std_error_classical": float(est.std_error_classical[k]),
                "std_error_sandwich": float(est.std_error_sandwich[k]),
                "std_error_catalogue": float(est.std_error_catalogue[k])
                if est.std_error_catalogue is not None
                else 0.0,
                "consistent_value": float(est.beta_consistent[k]),
            }
            for k, text in enumerate(base.describe())
        ],
        "unidentifiable": base.unidentifiable(),
        "model": {name: float(v) for name, v in zip(eq.names, est.theta, strict=True)},
        "catalogue": {name: float(v) for name, v in zip(eq.names, catalogue_theta, strict=True)},
        "pseudo_inertia_min_eigenvalue": [float(x) for x in pseudo_inertia_eigenvalues(est.theta[: eq.inertial])],
        "validation": {name: {str(i): row for i, row in rows.items()} for name, rows in validation.items()},
        "per_joint_model": {str(i): [float(x) for x in c] for i, c in per_joint.items()},
        "joint_sigma": {str(i): s for i, s in est.sigma.items()},
        "condition_number": est.condition,
        "warnings": warnings,
        "method": {
            "friction": spec.friction,
            "armature": spec.armature,
            "prior": spec.prior,
            "solver": est.solver,
            "lever_load_iterations": iterations,
            "samples": len(eq.b),
            "experiments": [log.name for log in spec.experiments],
            "heldout": [log.name for log in spec.heldout],
        },
        "wall_s": time.perf_counter() - t0,
        "_internal": {"spec": spec, "unzipdir": unzipdir, "series": series, "estimates": est, "equations": eq},
    }
    settings, unwritten = model_settings(eq.names, est.theta, unzipdir)
    result["model_settings"] = settings
    result["not_in_the_model_file"] = unwritten
    if unwritten:
        warnings.append(
            "the model file cannot hold "
            + ", ".join(unwritten)
            + " (no friction entry, rotor or contact geometry for them in the catalogue model): they are in "
            "identify.json and the validation, not in the identified FMU"
        )
        result["trusted"] = False
    if out is not None:
        from .report import write

        write(result, Path(out))
    return result


# Draws of the unidentified combinations (unidentified_spread), seeded.
SPREAD_DRAWS = 10
SPREAD_SEED = 7


def unidentified_spread(est, eq, base, logs, regressor, spec, lever_at, loaded) -> np.ndarray:
    """Per base parameter, the standard deviation of its weighted least squares over
    SPREAD_DRAWS draws of the links' combinations the torques cannot see (the null space of the
    base parameters), each parameter moved by up to ``spec.catalogue_uncertainty`` of its size
    (uniform; halved where that is no physical body), at which the lever loads L of the dry
    friction are computed again.

    The joint reactions, and so L, depend on combinations no joint torque shows (a link's mass
    folded into the link before it, its inertia about axes its joint does not turn): they stand
    at the catalogue's values, whose error reaches μ_k·L as an error of μ_k (the product is what
    the torques identify). A draw whose links are not a physical body is left out."""
    from .consistent import scales

    inertial = eq.inertial
    rng = np.random.default_rng(SPREAD_SEED)
    s = scales(est.theta[:inertial], 0)
    Bi = base.matrix()[:, :inertial] * s
    null = np.eye(inertial) - np.linalg.pinv(Bi) @ Bi
    w = np.ones(len(eq.b))
    for i, sigma in est.sigma.items():
        w[eq.joint == i] = 1.0 / sigma
    betas = []
    for _ in range(4 * SPREAD_DRAWS):
        if len(betas) == SPREAD_DRAWS:
            break
        move = s * (null @ (spec.catalogue_uncertainty * rng.uniform(-1.0, 1.0, inertial)))
        # A link the consistent fit left at the edge of the physical (the pseudo-inertia's
        # eigenvalue near 0) turns unphysical under most moves: the move is halved until the
        # links are bodies again, at most four times.
        for _ in range(5):
            pi = est.theta[:inertial] + move
            if min(pseudo_inertia_eigenvalues(pi)) > 0:
                break
            move = 0.5 * move
        else:
            continue
        motions = [with_lever_load(m, lever_at(pi)) for m in logs]
        drawn = equations(motions, regressor, spec.friction, spec.armature, loaded=loaded)
        Ab = drawn.A[:, base.independent] * w[:, None]
        betas.append(np.linalg.lstsq(Ab, drawn.b * w, rcond=None)[0])
    if len(betas) < 2:
        return np.zeros(base.count)
    return np.std(np.array(betas), axis=0, ddof=1)


def model_settings(names, theta, unzipdir) -> tuple:
    """(settings "NAME[i]=VALUE" of the FMU's tunable parameters that hold the identified
    friction and armature, the identified values no parameter holds): b_v[i] and mu_k[i] as
    they are (mu_s[i] raised to mu_k[i] where the catalogue's is below it: torques of a moving
    arm do not show the static coefficient); a motor's tau_c[i] and J_m[i] on the rotor's side,
    tau_c / N and I_a / N² (N its gear ratio)."""
    from fmpy import read_model_description

    md = read_model_description(unzipdir)
    start = {v.name: v.start for v in md.modelVariables if v.causality == "parameter"}
    settings, unwritten = [], []
    for name, value in zip(names, theta, strict=True):
        kind, _, rest = name.partition("[")
        if kind not in ("b_v", "mu_k", "tau_c", "I_a"):
            continue
        i = rest[:-1]
        gear = start.get(f"gear_ratio[{i}]")
        if kind in ("b_v", "mu_k") and name in start:
            settings.append(f"{name}={float(value)!r}")
            if kind == "mu_k" and f"mu_s[{i}]" in start and float(start[f"mu_s[{i}]"]) < value:
                settings.append(f"mu_s[{i}]={float(value)!r}")
        elif kind == "tau_c" and f"tau_c[{i}]" in start and gear is not None:
            settings.append(f"tau_c[{i}]={float(value) / float(gear)!r}")
        elif kind == "I_a" and f"J_m[{i}]" in start and gear is not None:
            settings.append(f"J_m[{i}]={float(value) / float(gear) ** 2!r}")
        elif value != 0.0:
            unwritten.append(f"{name} = {value:.6g}")
    return settings, unwritten
