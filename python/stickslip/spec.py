"""The SPEC of a parameter sweep (TOML), checked against the FMU before anything runs.

::

    stop_time = 2.0              # s
    communication_step = 1e-3    # s
    motion = "reference"         # or a motion file (TOML, docs/motion.md), or a CSV table:
                                 #   time, q_star[i] (qd_star[i], qdd_star[i] optional)
    fmu = "target/fmu/StickSlipManipulator.fmu"   # optional, this is the default
    [grid]                       # full factorial over every listed value
    "mu_k[3]" = [0.1, 0.15, 0.2]
    [sample]                     # Monte Carlo: n seeded draws, combined with every grid point
    n = 1000
    seed = 1
    "k[1]" = { uniform = [5e5, 2e6] }
    "slider_a[3]" = { normal = [0.2, 0.01] }
    "v_s[3]" = { loguniform = [1e-3, 1e-1] }

Relative paths (``motion``, ``fmu``) are taken from the current directory. Every swept name
must be a tunable Real parameter of the FMU (causality = parameter, variability = tunable).

The variants are numbered deterministically: grid points in the order of the product of
the listed values (the last name varies fastest), and for each grid point the n samples in
order. Each sampled parameter draws from its own stream, seeded by (seed, crc32 of its
name): the first m of n draws do not depend on n, on the other parameters, nor on where
the draws are used.
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import math
import tomllib
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .fmu import DEFAULT_FMU
from .motion import is_finite_number, motion_identity, motor_joints

DISTRIBUTIONS = {  # name -> (what the two numbers are, check, message when the check fails)
    "uniform": ("[low, high]", lambda a, b: a < b, "needs low < high"),
    "normal": ("[mean, standard deviation]", lambda a, b: b > 0, "needs a standard deviation > 0"),
    "loguniform": ("[low, high]", lambda a, b: 0 < a < b, "needs 0 < low < high"),
}
TOP_KEYS = ("stop_time", "communication_step", "motion", "fmu", "grid", "sample")


class SpecError(ValueError):
    """A SPEC that cannot run; the message names the key and the problem."""


@dataclass(frozen=True)
class Distribution:
    kind: str
    a: float
    b: float

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b, n)
        if self.kind == "normal":
            return rng.normal(self.a, self.b, n)
        return np.exp(rng.uniform(math.log(self.a), math.log(self.b), n))

    def as_toml(self) -> dict:
        return {self.kind: [self.a, self.b]}


@dataclass(frozen=True)
class Spec:
    """A parsed SPEC: the run settings, the grid values and the sample distributions."""

    stop_time: float
    communication_step: float
    motion: str  # "reference", the path of a motion file (TOML) or of a CSV table
    fmu: Path
    grid: dict = field(default_factory=dict)  # name -> tuple of values
    sample: dict = field(default_factory=dict)  # name -> Distribution
    n: int = 0  # number of samples (0: no [sample])
    seed: int = 0
    where: str = "SPEC"  # where it was read, for messages

    @property
    def steps(self) -> int:
        return round(self.stop_time / self.communication_step)

    @property
    def parameters(self) -> list:
        """The swept names: grid, then sample, in the order written."""
        return list(self.grid) + list(self.sample)

    def __len__(self) -> int:
        return math.prod(len(v) for v in self.grid.values()) * (self.n if self.sample else 1)

    def variants(self) -> list:
        """The parameter values of every variant, a dict per variant; its index is its ``run`` id."""
        points = [dict(zip(self.grid, values, strict=True)) for values in itertools.product(*self.grid.values())]
        if not self.sample:
            return points
        draws = {
            name: d.draw(np.random.default_rng([self.seed, zlib.crc32(name.encode())]), self.n)
            for name, d in self.sample.items()
        }
        return [p | {name: float(v[j]) for name, v in draws.items()} for p in points for j in range(self.n)]

    def canonical(self) -> dict:
        """What identifies the sweep's results: everything but where the FMU file lies (its
        content is identified by its hash, see :mod:`stickslip.sweep`); a motion file by its content."""
        motion = self.motion if self.motion == "reference" else motion_identity(self.motion)
        return {
            "stop_time": self.stop_time,
            "communication_step": self.communication_step,
            "motion": motion,
            "grid": {k: list(v) for k, v in self.grid.items()},
            "sample": {"n": self.n, "seed": self.seed, **{k: d.as_toml() for k, d in self.sample.items()}}
            if self.sample
            else {},
        }

    def digest(self) -> str:
        return hashlib.sha256(json.dumps(self.canonical(), sort_keys=True).encode()).hexdigest()


def _positive(table: dict, key: str, where: str) -> float:
    if key not in table:
        raise SpecError(f"{where}: `{key}` is missing")
    x = table[key]
    if not is_finite_number(x) or x <= 0:
        raise SpecError(f"{where}: `{key}` = {x!r}: must be a positive number (seconds)")
    return float(x)


def parse(text: str, where: str = "SPEC", overrides: dict | None = None) -> Spec:
    """A :class:`Spec` from TOML text; ``overrides`` (stop_time, n) replace the file's values.
    Checks the form only; :func:`check_against` checks the names against the FMU."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{where}: not valid TOML: {e}") from None
    unknown = [k for k in doc if k not in TOP_KEYS]
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {unknown}; a SPEC has {list(TOP_KEYS)}")
    overrides = overrides or {}
    if overrides.get("stop_time") is not None:
        doc["stop_time"] = overrides["stop_time"]
    stop = _positive(doc, "stop_time", where)
    step = _positive(doc, "communication_step", where)
    if step > stop:
        raise SpecError(f"{where}: communication_step = {step:g} s is longer than stop_time = {stop:g} s")
    if abs(round(stop / step) * step - stop) > 1e-9 * stop:
        raise SpecError(f"{where}: stop_time = {stop:g} s is not a whole number of communication steps of {step:g} s")
    if overrides.get("motion") is not None:
        doc["motion"] = overrides["motion"]
    motion = doc.get("motion", "reference")
    if not isinstance(motion, str) or not motion:
        raise SpecError(
            f'{where}: `motion` = {motion!r}: must be "reference" or the path of a motion file (TOML) or of a CSV table'
        )
    if motion != "reference" and not Path(motion).is_file():
        raise SpecError(f"{where}: motion file {motion!r} does not exist")
    fmu = doc.get("fmu", str(DEFAULT_FMU))
    if not isinstance(fmu, str) or not Path(fmu).is_file():
        raise SpecError(f"{where}: fmu {fmu!r} does not exist (build it with `bash scripts/build_fmu.sh`)")

    grid = doc.get("grid")
    if grid is not None:
        if not isinstance(grid, dict):
            raise SpecError(f"{where}: `grid` must be a table of name = [values]")
        if not grid:
            raise SpecError(f"{where}: [grid] is empty: list at least one parameter with its values")
        for name, values in grid.items():
            if not isinstance(values, list) or not values:
                raise SpecError(f"{where}: grid `{name}` = {values!r}: must be a non-empty list of numbers")
            bad = [v for v in values if not is_finite_number(v)]
            if bad:
                raise SpecError(f"{where}: grid `{name}`: {bad[0]!r} is not a finite number")
            if len(set(values)) != len(values):
                raise SpecError(f"{where}: grid `{name}` lists a value twice: {values}")
        grid = {name: tuple(float(v) for v in values) for name, values in grid.items()}

    sample, n, seed = doc.get("sample"), 0, 0
    if sample is not None:
        if not isinstance(sample, dict):
            raise SpecError(f"{where}: `sample` must be a table")
        sample = dict(sample)
        if overrides.get("n") is not None:
            sample["n"] = overrides["n"]
        n, seed = sample.pop("n", None), sample.pop("seed", None)
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise SpecError(f"{where}: [sample] `n` = {n!r}: must be a whole number >= 1")
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise SpecError(f"{where}: [sample] `seed` = {seed!r}: must be a whole number >= 0")
        if not sample:
            raise SpecError(f'{where}: [sample] draws no parameter: add e.g. "k[1]" = {{ uniform = [5e5, 2e6] }}')
        sample = {name: _distribution(name, d, where) for name, d in sample.items()}
        both = sorted(set(sample) & set(grid or {}))
        if both:
            raise SpecError(f"{where}: {both} both in [grid] and in [sample]")
    if not grid and not sample:
        raise SpecError(f"{where}: nothing to sweep: give a [grid] and/or a [sample] table")
    return Spec(stop, step, motion, Path(fmu), grid or {}, sample or {}, n, seed, where)


def _distribution(name: str, d, where: str) -> Distribution:
    kinds = " or ".join(f"{{ {k} = {form} }}" for k, (form, _, _) in DISTRIBUTIONS.items())
    if not isinstance(d, dict) or len(d) != 1 or next(iter(d)) not in DISTRIBUTIONS:
        raise SpecError(f"{where}: sample `{name}` = {d!r}: must be {kinds}")
    kind, values = next(iter(d.items()))
    form, ok, why = DISTRIBUTIONS[kind]
    if not isinstance(values, list) or len(values) != 2 or not all(is_finite_number(v) for v in values):
        raise SpecError(f"{where}: sample `{name}`: {kind} = {values!r}: must be two finite numbers {form}")
    a, b = (float(v) for v in values)
    if not ok(a, b):
        raise SpecError(f"{where}: sample `{name}`: {kind} = {values!r} {why}")
    return Distribution(kind, a, b)


def load(path, overrides: dict | None = None) -> Spec:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as e:
        raise SpecError(f"SPEC {path}: {e.strerror}") from None
    return parse(text, f"SPEC {path}", overrides)


def _refusal(v) -> str | None:
    """Why the variable ``v`` (fmpy ScalarVariable) cannot be swept, or None."""
    if v.causality == "input":
        return "is an input: the motion sets it"
    if v.causality == "output":
        return "is an output, not a parameter"
    if v.causality != "parameter":
        return f"has causality {v.causality}: only parameters can be swept"
    if v.variability != "tunable":
        return (
            f"is a {v.variability} parameter: the sweep varies tunable parameters only "
            "(the system's properties, not the integrator's settings)"
        )
    if v.type != "Real":
        return f"is a {v.type} parameter: the sweep varies Real parameters only"
    return None


def check_against(spec: Spec, model_description) -> None:
    """Refuses an FMU with motor drives (its motors would run at tau_m = 0), names the FMU does
    not have or that are not tunable Real parameters, and grid values or uniform ranges outside
    a parameter's declared [min, max]."""
    where = spec.where
    motors = motor_joints(model_description)
    if motors:
        raise SpecError(
            f"{where}: fmu {spec.fmu} has motor drives on joints {', '.join(map(str, motors))} (inputs "
            f"tau_m[i]): a sweep drives the joints through q* only and cannot set the motor torques; "
            f"sweep an FMU without motor drives"
        )
    by_name = {v.name: v for v in model_description.modelVariables}
    for name in spec.parameters:
        v = by_name.get(name)
        if v is None:
            close = difflib.get_close_matches(name, by_name, n=3)
            raise SpecError(
                f"{where}: unknown variable `{name}`: the FMU has no variable of that name"
                + (f" (did you mean {', '.join(close)}?)" if close else "")
            )
        why = _refusal(v)
        if why:
            raise SpecError(f"{where}: `{name}` {why}")
        lo = float(v.min) if v.min is not None else -math.inf
        hi = float(v.max) if v.max is not None else math.inf
        values = spec.grid.get(name, ())
        d = spec.sample.get(name)
        if d is not None and d.kind != "normal":
            values = (d.a, d.b)
        for x in values:
            if not lo <= x <= hi:
                raise SpecError(f"{where}: `{name}` = {x:g} is outside the FMU's range [{lo:g}, {hi:g}]")
