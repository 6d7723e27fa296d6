"""The fit SPEC (TOML or a dict) and its measured data, checked against the FMU before anything runs.

::

    fmu = "target/fmu/StickSlipManipulator.fmu"   # the FMU whose parameters are fitted
    [[experiment]]                                # one or more measured runs, fitted together
    name = "run1"                                 # optional (default: the data file's stem)
    data = "run1.csv"                             # relative to the spec; a time column and measured columns
    time = "t"                                    # the time column, s, strictly increasing
    inputs = { "q_star[1]" = "motor1", "q_star[3]" = "motor3" }   # FMU inputs from columns (q_star[i],
                                                  # or tau_m[i] of a motor drive), rates by a cubic spline
                                                  # (not-a-knot); joints not named hold their start
    # motion = "motion.toml"                      # instead of inputs: a motion file (docs/motion.md)
    parameters = { "m[3]" = 8.0 }                 # known values for this experiment
    [experiment.measured]                         # FMU output <- column, with the measurement's noise
    "q[1]" = { column = "link1", sigma = 2e-6 }   # resolution = 1.5e-6: the encoder's count (default
                                                  # "auto": detected where the samples lie on a grid)
    [estimate]                                    # tunable FMU parameters to estimate
    "mu_k[1]" = { initial = 0.15, bounds = [0.05, 0.4] }
    "k[3]" = { initial = 8e5, bounds = [1e5, 5e6], scale = "log" }
    [options]
    starts = 8             # the initial point, the equation-error estimate, and a seeded Latin hypercube
    seed = 1
    loss = "linear"        # or "soft_l1", "huber", "cauchy" (scipy.optimize.least_squares)
    f_scale = 1.0          # the robust loss's scale, in normalized residuals
    absolute_sigma = false # false: the sigmas are relative, their scale is estimated from the residuals
    shooting = "auto"      # "single", "multiple" (segments restarted from the measured state) or "auto"
    stage = "output-error" # or "equation-error": the equation-error stage (IDIM) is the answer, with its
                           # standard errors (for torque-logged arms, whose open-loop runs drift)
    horizon = 0.5          # optional, s: the final cost is the prediction over this horizon from each
                           # measured state (else the whole run's simulation): for arms whose open-loop
                           # runs drift, such as those driven by logged torques
    segment = 0.1          # s, multiple shooting's segment length
    drop_nan = false       # true: rows with NaN samples are dropped (named in the report), else refused
    error_tolerance = 1e-6 # optional: the FMU's error_tolerance during the fit (else its start value)
    fit_start = true       # the start state of joints moving at an experiment's first sample is fitted
                           # with the parameters (stickslip.fit.start.start_unknowns); false: as read

The FMU is stepped from sample to sample of each experiment (variable communication steps),
so every measured sample is compared with the FMU's output at exactly its time.

Every problem is a :class:`FitSpecError` naming the field: the CLI prints it as one line and
exits with status 2, before any output is written.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..fmu import DEFAULT_FMU
from ..motion import MotionError, is_finite_number, load_motion_for, motion_torques

TOP_KEYS = ("fmu", "experiment", "estimate", "options")
EXPERIMENT_KEYS = ("name", "data", "time", "inputs", "motion", "parameters", "measured", "start", "derivatives")
STARTS = ("data", "rest")  # an experiment's start state: from its first samples, or the FMU's own
ESTIMATE_KEYS = ("initial", "bounds", "scale")
LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
SHOOTING = ("auto", "single", "multiple")
STAGES = ("output-error", "equation-error")
JACOBIANS = ("sensitivities", "differences")
OPTION_DEFAULTS = {
    "starts": 1,
    "seed": 1,
    "loss": "linear",
    "f_scale": 1.0,
    "absolute_sigma": False,
    "shooting": "auto",
    "segment": 0.1,
    "drop_nan": False,
    "error_tolerance": None,
    "max_evaluations": 200,
    "diff_step": 1e-3,
    "derivatives": "auto",
    "horizon": None,
    "stage": "output-error",
    "jacobian": "differences",
    "fit_start": True,
}
MAX_STARTS = 1000


class FitSpecError(ValueError):
    """A fit SPEC or data file that cannot be used; the message names the field and the problem."""


CHANNEL_KEYS = ("column", "sigma", "resolution")


@dataclass
class Channel:
    """One measured channel: the FMU output, the data column, the noise's standard deviation
    ``sigma`` and the encoder's quantum ``resolution`` (0: none; given, or detected from the
    samples' levels when the SPEC says ``resolution = "auto"`` or nothing)."""

    output: str
    column: str
    sigma: float
    values: np.ndarray = field(repr=False, default=None)
    resolution: float = 0.0
    resolution_detected: bool = False

    @property
    def std(self) -> float:
        """The standard deviation of a sample's error: the noise and the rounding to the
        encoder's count, sqrt(sigma² + resolution²/12) (a uniform error over one count)."""
        return math.sqrt(self.sigma**2 + self.resolution**2 / 12.0)


def detect_resolution(values) -> float:
    """The quantum q of samples that all lie on a grid x0 + n q (an encoder's count), or 0.
    q is the smallest step between two distinct levels; every other step must be a whole
    multiple of it (to 1e-6 of q), and the grid must hold at least one repeated level, as
    an encoder's samples do wherever the link is still."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    levels = np.unique(x)
    if len(levels) < 2 or len(levels) == len(x):
        return 0.0
    steps = np.diff(levels)
    q = float(steps.min())
    scale = max(float(np.max(np.abs(levels))), q)
    if not q > 1e-12 * scale:
        return 0.0
    n = steps / q
    if np.max(np.abs(n - np.round(n))) > 1e-6 + 1e-9 * scale / q:
        return 0.0
    return q


@dataclass
class Experiment:
    """One measured run: times, inputs (a motion callable ``motion(t, step)``), known parameters
    and the measured channels."""

    name: str
    data_path: Path
    time: np.ndarray
    motion: object  # motion(t, step) -> (q*, q*', q*'') over the joints
    torques: object  # a Torques of the motor-drive inputs tau_m[i], or None
    inputs: dict  # FMU input -> column ({} when a motion file gives them)
    parameters: dict
    channels: list
    dropped_rows: list = field(default_factory=list)
    motion_file: str | None = None
    derivatives: object = None  # the derivative filter (stickslip.fit.filtering.Filter)
    start: str = "data"  # "data": from the first samples; "rest": the FMU's own; "parameters": given
    filtered_inputs: list = field(default_factory=list)  # inputs whose column is a measurement, filtered

    @property
    def n_samples(self) -> int:
        return sum(len(c.values) for c in self.channels)


@dataclass
class Estimate:
    """A tunable parameter to estimate: its initial value, bounds and scale ("linear" or "log")."""

    name: str
    initial: float
    low: float
    high: float
    scale: str = "linear"
    # The experiment whose start state this is (:func:`stickslip.fit.start.start_unknowns`): an
    # unknown of the fit beside the model's parameters, not one of them (None for those).
    start_of: str | None = None

    @property
    def variable(self) -> str:
        """The FMU variable it sets: its name, or a start unknown's without the experiment."""
        return self.name if self.start_of is None else self.name[len(self.start_of) + 1 :]


@dataclass
class FitSpec:
    fmu: Path
    experiments: list
    estimates: list
    options: dict
    source: str
    model_description: object = field(repr=False, default=None)

    @property
    def names(self) -> list:
        return [e.name for e in self.estimates]


def load(spec, base_dir=None, replay: bool = False) -> FitSpec:
    """The checked FitSpec of a TOML file path or a dict (paths in a dict are relative to
    ``base_dir``, default the current directory); ``replay``: for replaying its experiments
    (``stickslip simulate --spec``), where ``[estimate]`` may be left out."""
    if isinstance(spec, dict):
        doc, source, base = spec, "fit spec", Path(base_dir or ".")
    else:
        path = Path(spec)
        try:
            doc = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise FitSpecError(f"{path}: no such file") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise FitSpecError(f"{path}: not valid TOML: {e}") from None
        source, base = str(path), path.resolve().parent
    return _checked(doc, source, base, replay)


def _unknown(keys, allowed, where: str) -> None:
    for k in keys:
        if k not in allowed:
            close = difflib.get_close_matches(k, allowed, n=1)
            hint = f" (did you mean `{close[0]}`?)" if close else f" (known: {', '.join(allowed)})"
            raise FitSpecError(f"{where}: unknown key `{k}`{hint}")


def _table(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise FitSpecError(f"{where}: must be a table, e.g. {where.split('.')[-1]} = {{ ... }}")
    return value


def _text(value, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise FitSpecError(
            f'{where} = {value!r}: must be a string, e.g. {where.rsplit(".", 1)[-1].split(" ")[-1]} = "..."'
        )
    return value


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not is_finite_number(value):
        raise FitSpecError(f"{where} = {value!r}: must be a finite number")
    return float(value)


def _checked(doc: dict, source: str, base: Path, replay: bool = False) -> FitSpec:
    from fmpy import read_model_description

    _unknown(doc, TOP_KEYS, source)
    fmu = Path(_text(doc["fmu"], f"{source}: fmu") if "fmu" in doc else DEFAULT_FMU)
    if not fmu.is_absolute():
        fmu = base / fmu
    if not fmu.is_file():
        raise FitSpecError(f"{source}: fmu = {str(fmu)!r}: no such file (build it with bash scripts/build_fmu.sh)")
    try:
        md = read_model_description(str(fmu))
    except Exception as e:  # noqa: BLE001 -- any unreadable FMU is one line
        raise FitSpecError(f"{source}: fmu = {str(fmu)!r}: not a readable FMU: {e}") from None
    variables = {v.name: v for v in md.modelVariables}
    options = _options(doc.get("options", {}), f"{source}: [options]")
    if options["error_tolerance"] is not None and "error_tolerance" in variables:
        _in_range(variables["error_tolerance"], options["error_tolerance"], f"{source}: [options] error_tolerance")
    experiments = doc.get("experiment")
    if not experiments:
        raise FitSpecError(f"{source}: no [[experiment]]: at least one measured run is needed")
    if isinstance(experiments, dict):
        experiments = [experiments]
    if not isinstance(experiments, list):
        raise FitSpecError(f"{source}: experiment must be an array of tables ([[experiment]])")
    exps = [
        _experiment(_table(e, f"{source}: experiment {k + 1}"), k, source, base, md, variables, options)
        for k, e in enumerate(experiments)
    ]
    names = [e.name for e in exps]
    if len(set(names)) != len(names):
        raise FitSpecError(f"{source}: experiment names {names} are not unique (give each a `name`)")
    raw_estimates = _table(doc.get("estimate", {}), f"{source}: [estimate]")
    estimates = _estimates(raw_estimates, source, variables) if raw_estimates or not replay else []
    for e in exps:
        clash = sorted(set(e.parameters) & {x.name for x in estimates})
        if clash:
            raise FitSpecError(f"{source}: experiment {e.name!r}: parameters {clash} are also estimated")
        _static_above_kinetic(estimates, e, variables, source)
    return FitSpec(fmu, exps, estimates, options, source, md)


def _static_above_kinetic(estimates: list, experiment, variables: dict, source: str) -> None:
    """The FMU refuses μ_s[i] < μ_k[i]. Where only one of the two is estimated, its bounds
    must keep it on the right side of the other's value in every experiment (the pair
    estimated together is kept there by the fit itself, through μ_s − μ_k >= 0)."""
    by_name = {e.name: e for e in estimates}
    for e in estimates:
        kind, _, rest = e.name.partition("[")
        if kind not in ("mu_k", "mu_s"):
            continue
        other = ("mu_s[" if kind == "mu_k" else "mu_k[") + rest
        if other in by_name or other not in variables:
            continue
        value = experiment.parameters.get(other, variables[other].start)
        if value is None:
            continue
        value = float(value)
        if kind == "mu_k" and e.high > value:
            raise FitSpecError(
                f"{source}: estimate.{e.name!r}.bounds = [{e.low:g}, {e.high:g}] reach above {other} = {value:g} "
                f"(experiment {experiment.name!r}), which the FMU refuses (mu_s >= mu_k): estimate {other} too, "
                f"or give it in the experiment's parameters, or keep the bound <= {value:g}"
            )
        if kind == "mu_s" and e.low < value:
            raise FitSpecError(
                f"{source}: estimate.{e.name!r}.bounds = [{e.low:g}, {e.high:g}] reach below {other} = {value:g} "
                f"(experiment {experiment.name!r}), which the FMU refuses (mu_s >= mu_k): estimate {other} too, "
                f"or give it in the experiment's parameters, or keep the bound >= {value:g}"
            )
    pairs = [(e, by_name.get(e.name.replace("mu_s[", "mu_k["))) for e in estimates if e.name.startswith("mu_s[")]
    for s, k in pairs:
        if k is not None and s.initial < k.initial:
            raise FitSpecError(
                f"{source}: estimate.{s.name!r}.initial = {s.initial:g} is below {k.name} initial = {k.initial:g}; "
                "the FMU refuses mu_s < mu_k"
            )


def _options(raw, where: str) -> dict:
    options = dict(OPTION_DEFAULTS)
    _unknown(_table(raw, where), list(OPTION_DEFAULTS), where)
    options.update(raw)
    for key in ("starts", "seed", "max_evaluations"):
        v = options[key]
        if isinstance(v, bool) or not isinstance(v, int) or v < (0 if key == "seed" else 1):
            raise FitSpecError(f"{where}: {key} = {v!r}: must be an integer >= {0 if key == 'seed' else 1}")
    if options["loss"] not in LOSSES:
        raise FitSpecError(f"{where}: loss = {options['loss']!r}: one of {', '.join(LOSSES)}")
    if options["jacobian"] not in JACOBIANS:
        raise FitSpecError(
            f"{where}: jacobian = {options['jacobian']!r}: one of {', '.join(map(repr, JACOBIANS))} ('sensitivities': "
            "the FMU's derivatives of its own scheme, one call a Jacobian; 'differences': forward differences of "
            "free runs with diff_step)"
        )
    if options["shooting"] not in SHOOTING:
        raise FitSpecError(f"{where}: shooting = {options['shooting']!r}: one of {', '.join(SHOOTING)}")
    for key, high in (("f_scale", math.inf), ("segment", math.inf), ("diff_step", 0.1)):
        if not 0 < _number(options[key], f"{where}: {key}") <= high:
            raise FitSpecError(
                f"{where}: {key} = {options[key]!r}: must be > 0" + (f" and <= {high:g}" if high < 1 else "")
            )
        options[key] = float(options[key])
    if options["starts"] > MAX_STARTS:
        raise FitSpecError(f"{where}: starts = {options['starts']}: at most {MAX_STARTS}")
    for key in ("absolute_sigma", "drop_nan", "fit_start"):
        if not isinstance(options[key], bool):
            raise FitSpecError(f"{where}: {key} = {options[key]!r}: must be true or false")
    options["derivatives"] = _filter(options["derivatives"], f"{where}: derivatives")
    if options["stage"] not in STAGES:
        raise FitSpecError(
            f"{where}: stage = {options['stage']!r}: one of {', '.join(map(repr, STAGES))} ('output-error': the "
            "simulation's error, from the equation-error start and others; 'equation-error': the torques' or slip "
            "equations' linear least squares is the answer)"
        )
    if options["horizon"] is not None:
        options["horizon"] = _number(options["horizon"], f"{where}: horizon")
        if not options["horizon"] > 0:
            raise FitSpecError(f"{where}: horizon = {options['horizon']:g}: must be > 0 seconds")
        if options["shooting"] == "single":
            raise FitSpecError(
                f'{where}: horizon = {options["horizon"]:g} and shooting = "single": a horizon restarts the runs '
                "from the measured state (multiple shooting); leave out one of the two"
            )
    if options["error_tolerance"] is not None:
        options["error_tolerance"] = _number(options["error_tolerance"], f"{where}: error_tolerance")
        if options["error_tolerance"] <= 0:
            raise FitSpecError(f"{where}: error_tolerance = {options['error_tolerance']:g}: must be > 0")
    return options


def _filter(raw, where: str):
    """The derivative filter of a SPEC value (:mod:`stickslip.fit.filtering`); a Filter given
    already (the options' one, for an experiment without its own) is taken as it is."""
    from .filtering import Filter, parse

    if isinstance(raw, Filter):
        return raw
    try:
        return parse(raw, where)
    except ValueError as e:
        raise FitSpecError(str(e)) from None


def _tunable(name: str, variables: dict, where: str):
    v = variables.get(name)
    if v is None:
        close = difflib.get_close_matches(name, list(variables), n=3)
        raise FitSpecError(f"{where}: `{name}` is not a variable of the FMU" + (f" (close: {close})" if close else ""))
    if v.causality != "parameter" or v.variability != "tunable" or v.type != "Real":
        raise FitSpecError(
            f"{where}: `{name}` is not a tunable Real parameter of the FMU "
            f"(causality {v.causality}, variability {v.variability}, type {v.type})"
        )
    return v


def _in_range(v, value: float, where: str) -> None:
    lo = float(v.min) if v.min is not None else -math.inf
    hi = float(v.max) if v.max is not None else math.inf
    if not lo <= value <= hi:
        raise FitSpecError(f"{where} = {value:g}: outside the FMU's range [{lo:g}, {hi:g}] of {v.name}")


def _estimates(raw: dict, source: str, variables: dict) -> list:
    if not raw:
        raise FitSpecError(f"{source}: [estimate] is empty: name at least one parameter to estimate")
    out = []
    for name, entry in raw.items():
        where = f"{source}: estimate.{name!r}"
        v = _tunable(name, variables, where)
        entry = _table(entry, where)
        _unknown(entry, ESTIMATE_KEYS, where)
        if "initial" not in entry:
            raise FitSpecError(f"{where}: no `initial` value (e.g. {{ initial = 0.15, bounds = [0.05, 0.4] }})")
        initial = _number(entry["initial"], f"{where}.initial")
        bounds = entry.get("bounds")
        if bounds is None:
            bounds = [v.min if v.min is not None else -math.inf, v.max if v.max is not None else math.inf]
        if not isinstance(bounds, list) or len(bounds) != 2:
            raise FitSpecError(f"{where}.bounds = {bounds!r}: must be [low, high]")
        if any(isinstance(b, bool) or not isinstance(b, (int, float)) or math.isnan(b) for b in bounds):
            raise FitSpecError(f"{where}.bounds = {bounds!r}: must be two numbers [low, high]")
        low, high = (float(b) for b in bounds)
        if not low < high:
            raise FitSpecError(f"{where}.bounds = [{low:g}, {high:g}]: low must be below high")
        _in_range(v, low, f"{where}.bounds[0]") if math.isfinite(low) else None
        _in_range(v, high, f"{where}.bounds[1]") if math.isfinite(high) else None
        if not low <= initial <= high:
            raise FitSpecError(f"{where}.initial = {initial:g}: outside its bounds [{low:g}, {high:g}]")
        scale = entry.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise FitSpecError(f'{where}.scale = {scale!r}: "linear" or "log"')
        if scale == "log" and not low > 0:
            raise FitSpecError(f'{where}: scale = "log" needs bounds above 0, not [{low:g}, {high:g}]')
        if not (math.isfinite(low) and math.isfinite(high)):
            raise FitSpecError(f"{where}.bounds: need finite bounds (the multi-start draws between them)")
        out.append(Estimate(name, initial, low, high, scale))
    return out


def _experiment(raw: dict, k: int, source: str, base: Path, md, variables: dict, options: dict) -> Experiment:
    where = f"{source}: experiment {k + 1}"
    _unknown(raw, EXPERIMENT_KEYS, where)
    if "data" not in raw:
        raise FitSpecError(f"{where}: no `data` (the CSV file of the measured run)")
    data_path = Path(_text(raw["data"], f"{where}: data"))
    if not data_path.is_absolute():
        data_path = base / data_path
    name = _text(raw["name"], f"{where}: name") if "name" in raw else data_path.stem
    where = f"{source}: experiment {name!r}"
    time_column = _text(raw.get("time", "t"), f"{where}: time")
    for inp, col in _table(raw.get("inputs", {}), f"{where}: inputs").items():
        _text(col, f"{where}: inputs.{inp!r}")
    inputs = _table(raw.get("inputs", {}), f"{where}: inputs")
    measured = _table(raw.get("measured", {}), f"{where}: measured")
    if not measured:
        raise FitSpecError(f"{where}: [experiment.measured] is empty: name the FMU outputs that were measured")
    if inputs and "motion" in raw:
        raise FitSpecError(f"{where}: give either `inputs` (columns) or `motion` (a motion file), not both")
    parameters = {}
    for pname, value in _table(raw.get("parameters", {}), f"{where}: parameters").items():
        v = variables.get(pname)
        if v is None or v.causality != "parameter":
            close = difflib.get_close_matches(pname, list(variables), n=3)
            raise FitSpecError(
                f"{where}: parameters.{pname!r}: not a parameter of the FMU" + (f" (close: {close})" if close else "")
            )
        if v.type == "Boolean":
            if not isinstance(value, bool):
                raise FitSpecError(f"{where}: parameters.{pname!r} = {value!r}: must be true or false")
            parameters[pname] = value
            continue
        parameters[pname] = _number(value, f"{where}: parameters.{pname!r}")
        _in_range(v, parameters[pname], f"{where}: parameters.{pname!r}")
    table = _read_csv(data_path, where)
    needed = {time_column: "the time column"}
    needed.update({col: f"input {inp}" for inp, col in inputs.items()})
    channels = []
    for output, entry in measured.items():
        v = variables.get(output)
        if v is None or v.causality != "output":
            outputs = [x.name for x in md.modelVariables if x.causality == "output"]
            close = difflib.get_close_matches(output, outputs, n=3)
            raise FitSpecError(
                f"{where}: measured.{output!r}: not an output of the FMU" + (f" (close: {close})" if close else "")
            )
        entry = _table(entry, f"{where}: measured.{output!r}")
        _unknown(entry, CHANNEL_KEYS, f"{where}: measured.{output!r}")
        if "column" not in entry or "sigma" not in entry:
            raise FitSpecError(
                f'{where}: measured.{output!r}: needs `column` and `sigma`, e.g. {{ column = "link1", sigma = 1e-6 }}'
            )
        _text(entry["column"], f"{where}: measured.{output!r}.column")
        sigma = _number(entry["sigma"], f"{where}: measured.{output!r}.sigma")
        if sigma <= 0:
            raise FitSpecError(f"{where}: measured.{output!r}.sigma = {sigma:g}: must be > 0")
        resolution = entry.get("resolution", "auto")
        if resolution != "auto":
            resolution = _number(resolution, f"{where}: measured.{output!r}.resolution")
            if resolution < 0:
                raise FitSpecError(
                    f'{where}: measured.{output!r}.resolution = {resolution:g}: must be >= 0 (0: none, "auto": '
                    "detected from the samples)"
                )
        channels.append(Channel(output, str(entry["column"]), sigma, resolution=resolution))
        needed[str(entry["column"])] = f"measured {output}"
    for column, role in needed.items():
        if column not in table:
            close = difflib.get_close_matches(column, list(table), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else f" (columns: {', '.join(table)})"
            raise FitSpecError(f"{where}: {data_path.name} has no column {column!r} ({role}){hint}")
    bad_rows = sorted({int(r) for col in needed for r in np.flatnonzero(~np.isfinite(table[col]))})
    dropped = []
    if bad_rows:
        shown = ", ".join(str(r + 2) for r in bad_rows[:8]) + (" ..." if len(bad_rows) > 8 else "")
        if not options["drop_nan"]:
            raise FitSpecError(
                f"{where}: {data_path.name} has NaN or missing samples in rows {shown} (line numbers, header = 1); "
                "set [options] drop_nan = true to drop those rows"
            )
        keep = np.ones(len(table[time_column]), dtype=bool)
        keep[bad_rows] = False
        table = {c: v[keep] for c, v in table.items()}
        dropped = [r + 2 for r in bad_rows]
    t = table[time_column]
    if len(t) < 2:
        raise FitSpecError(
            f"{where}: {data_path.name} has {len(t)} sample(s): an experiment needs at least two "
            "(it must be longer than one communication step)"
        )
    steps = np.diff(t)
    if np.any(steps <= 0):
        row = int(np.flatnonzero(steps <= 0)[0]) + 3
        raise FitSpecError(f"{where}: {data_path.name}: time {time_column!r} is not strictly increasing (line {row})")
    if steps.min() < 1e-5 or steps.max() > 1.0:
        raise FitSpecError(
            f"{where}: {data_path.name}: sample intervals {steps.min():g}..{steps.max():g} s; the FMU's "
            "communication step must lie in [1e-5, 1] s"
        )
    for c in channels:
        c.values = table[c.column]
        if c.resolution == "auto":
            c.resolution = detect_resolution(c.values)
            c.resolution_detected = c.resolution > 0
    derivatives = _filter(raw.get("derivatives", options["derivatives"]), f"{where}: derivatives")
    start = _start(raw, parameters, where)
    measured_columns = {c.column for c in channels}
    (motion, torques, filtered), motion_file = _motion(
        raw, inputs, table, t, md, where, base, derivatives, measured_columns
    )
    return Experiment(
        name,
        data_path,
        t,
        motion,
        torques,
        dict(inputs),
        parameters,
        channels,
        dropped,
        motion_file,
        derivatives,
        start,
        filtered,
    )


START_PARAMETERS = ("use_start_values", "static_start", "q_start[", "qd_start[", "theta_m_start[", "omega_m_start[")


def _start(raw: dict, parameters: dict, where: str) -> str:
    """How the experiment starts: "data" (the default: from its first samples), "rest" (the
    FMU's own start), or "parameters" (the experiment's parameters set the start values)."""
    given = [p for p in parameters if p.startswith(START_PARAMETERS)]
    start = raw.get("start")
    if start is not None and start not in STARTS:
        raise FitSpecError(
            f"{where}: start = {start!r}: one of {', '.join(map(repr, STARTS))} ('data': the joints' positions and "
            "speeds of the first samples, the default; 'rest': the FMU's own start)"
        )
    if given:
        if start is not None:
            raise FitSpecError(
                f"{where}: start = {start!r} and the start values {given} in parameters: give one of the two"
            )
        return "parameters"
    return start or "data"


def _read_csv(path: Path, where: str) -> dict:
    """Columns of a CSV with a header row, as float arrays (empty fields and non-numbers: NaN)."""
    import pandas as pd

    try:
        frame = pd.read_csv(path, skipinitialspace=True)
    except FileNotFoundError:
        raise FitSpecError(f"{where}: data = {str(path)!r}: no such file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as e:
        reason = " ".join(str(e).split())
        raise FitSpecError(f"{where}: {path.name}: not a readable CSV: {reason}") from None
    except OSError as e:
        raise FitSpecError(f"{where}: data = {str(path)!r}: cannot read: {e.strerror or e}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    return {c: pd.to_numeric(frame[c], errors="coerce").to_numpy(dtype=np.float64) for c in frame.columns}


def _motion(raw: dict, inputs: dict, table: dict, t, md, where: str, base: Path, derivatives, measured: set):
    """The drive inputs: (``motion(t, step)`` -> (q*, q*', q*'') over the joints, a
    :class:`Torques` of the motor torques or None, the inputs whose column is a measurement)
    and the motion file's name (None for columns).

    A q_star column that is a measurement (a measured channel's column too, or samples whose
    noise or encoder count dominates their differences, :func:`stickslip.fit.filtering.rough`)
    goes through the derivative filter: q*, q*', q*'' are the filter's; a
    command column (a controller's set points) through the not-a-knot spline of its samples."""
    from ..motion import SplineMotion, fmu_joints, motor_joints
    from .filtering import rough

    joints, _ = fmu_joints(md)
    motors = motor_joints(md)
    if "motion" in raw:
        path = Path(_text(raw["motion"], f"{where}: motion"))
        if not path.is_absolute():
            path = base / path
        try:
            motion = load_motion_for(path, md)
            torques = None
            if motion_torques(motion):  # the motion file's tau_m columns drive the motors
                names = list(motion_torques(motion))
                torques = Torques(motion.torques.time, names, motion.torques.values)
            return (motion, torques, []), str(path)
        except (MotionError, OSError) as e:
            raise FitSpecError(f"{where}: motion = {str(path)!r}: {e}") from None
    if not inputs:
        raise FitSpecError(f"{where}: no `inputs` and no `motion`: say how the drives were commanded")
    start = {v.name: float(v.start or 0.0) for v in md.modelVariables if v.causality == "input"}
    q = np.array([[start.get(f"q_star[{i}]", 0.0) for i in range(1, joints + 1)]] * len(t))
    torque_names, torque_columns, filtered = [], [], []
    for name, column in inputs.items():
        m = re.fullmatch(r"(q_star|tau_m)\[(\d+)\]", name)
        i = int(m.group(2)) if m else 0
        if m and m.group(1) == "q_star" and 1 <= i <= joints:
            q[:, i - 1] = table[column]
            if derivatives.method != "spline" and (column in measured or rough(table[column])):
                filtered.append(name)
        elif m and m.group(1) == "tau_m" and i in motors:
            torque_names.append(name)
            torque_columns.append(table[column])
        else:
            known = f"q_star[1..{joints}]" + (f", tau_m[{motors}]" if motors else "")
            raise FitSpecError(
                f"{where}: inputs.{name!r}: not a drive input of the FMU ({known}; rates follow from a cubic "
                "spline through the column)"
            )
    torques = Torques(t, torque_names, np.column_stack(torque_columns)) if torque_names else None
    motion = SplineMotion(t, q, f"{where}: inputs")
    if filtered:
        motion = FilteredMotion(motion, t, q, [int(x[7:-1]) for x in filtered], derivatives)
    return (motion, torques, filtered), None


class Torques:
    """Motor torques tau_m[i] sampled at the experiment's times, joined by a not-a-knot cubic
    spline; at a communication point the FMU gets the value and its first two derivatives
    (fmi2SetRealInputDerivatives), so it holds the spline's Taylor polynomial across the step."""

    def __init__(self, time, names: list, values):
        from scipy.interpolate import CubicSpline

        self.names = list(names)
        self.spline = CubicSpline(np.asarray(time, dtype=np.float64), np.asarray(values, dtype=np.float64), axis=0)

    def __call__(self, t: float):
        """(values, first derivatives, second derivatives) at t, over ``names``."""
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)


class FilteredMotion:
    """A :class:`stickslip.motion.SplineMotion` whose joints ``joints`` (1-based) are measured
    positions: at the samples their q*, q*', q*'' are the derivative filter's
    (:func:`stickslip.fit.filtering.derivatives`); between samples, the cubic spline through
    the filtered values (its rates at the samples are the spline's, close to the filter's)."""

    def __init__(self, spline_motion, time, q, joints: list, derivatives):
        from scipy.interpolate import CubicSpline

        from .filtering import derivatives as filtered

        self.inner = spline_motion
        self.joints = spline_motion.joints
        self.columns = [i - 1 for i in joints]
        self.time = np.asarray(time, dtype=np.float64)
        value, rate, accel = filtered(self.time, np.asarray(q, dtype=np.float64)[:, self.columns], derivatives)
        self.at_samples = (value, rate, accel)
        self.spline = CubicSpline(self.time, value, axis=0)
        self.end_time, self.stop_time = spline_motion.end_time, spline_motion.stop_time
        self.source = spline_motion.source

    def __call__(self, t: float, step: float = 0.0):
        q, qd, qdd = (list(x) for x in self.inner(t, step))
        k = int(np.searchsorted(self.time, t))
        exact = k < len(self.time) and self.time[k] == t
        for j, c in enumerate(self.columns):
            if exact:
                q[c], qd[c], qdd[c] = (float(x[k, j]) for x in self.at_samples)
            elif self.time[0] <= t <= self.time[-1]:
                q[c], qd[c], qdd[c] = (float(self.spline(t, d)[j]) for d in (0, 1, 2))
        return q, qd, qdd

    def describe(self) -> str:
        return self.inner.describe() + f"; joints {[c + 1 for c in self.columns]} through the derivative filter"
