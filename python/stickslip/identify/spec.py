"""The identification SPEC (TOML or a dict) and its torque logs, checked before anything runs.

::

    fmu = "target/fmu/my_arm.fmu"        # the arm's FMU: its model (the catalogue values) and engine
    [[experiment]]                       # torque logs the identification uses (one or more)
    name = "run1"                        # optional (default: the data file's stem)
    data = "run1.csv"                    # relative to the SPEC: a time column, positions, torques
    time = "t"                           # s, strictly increasing, evenly spaced
    positions = { "q[1]" = "q1", "q[2]" = "q2" }        # every joint's measured position (rad or m)
    torques = { "tau[1]" = "tau1", "tau[2]" = "tau2" }  # measured joint torques (N·m or N, link side)
    [[heldout]]                          # runs the answer predicts and is judged by, never fitted
    data = "run4.csv"                    # same keys as [[experiment]]
    time = "t"
    positions = { ... }
    torques = { ... }
    [identify]
    friction = "viscous+coulomb"         # each joint's friction columns: "none", "viscous",
                                         # "coulomb" or "viscous+coulomb"
    armature = true                      # each joint's reflected rotor inertia on its own q̈
    prior = 1e-4                         # the catalogue values' weight where the data cannot tell
    catalogue_uncertainty = 0.3          # how far off the catalogue's links may be (relative): sets
                                         # what the combinations the torques cannot see add to the
                                         # uncertainty of μ_k through its loads
    derivatives = "auto"                 # the derivative filter (as in fit SPECs)

Every problem is an :class:`IdentifySpecError` naming the field; the command prints it as one
line and exits with status 2 before anything is written.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..fit.spec import FitSpecError, _filter, _read_csv, _unknown

TOP_KEYS = ("fmu", "experiment", "heldout", "identify")
EXPERIMENT_KEYS = ("name", "data", "time", "positions", "torques")
FRICTION = ("none", "viscous", "coulomb", "viscous+coulomb")
IDENTIFY_DEFAULTS = {
    "friction": "viscous+coulomb",
    "armature": True,
    "prior": 1e-4,
    "catalogue_uncertainty": 0.3,
    "derivatives": "auto",
}


class IdentifySpecError(FitSpecError):
    """An identification SPEC or log that cannot be used; the message names the field."""


@dataclass
class Log:
    """One run's log: times, every joint's position, the measured torques (joint -> samples)."""

    name: str
    time: np.ndarray
    q: np.ndarray  # samples × n
    tau: dict = field(default_factory=dict)  # 1-based joint -> samples


@dataclass
class IdentifySpec:
    source: str
    fmu: Path
    n: int  # the arm's joints
    experiments: list
    heldout: list
    friction: str
    armature: bool
    prior: float
    derivatives: object  # a fit.filtering.Filter
    catalogue_uncertainty: float = 0.3


def load(spec, base_dir=None) -> IdentifySpec:
    """The SPEC at a path (TOML) or given as a dict (paths relative to ``base_dir``)."""
    if isinstance(spec, dict):
        return _checked(spec, "SPEC", Path(base_dir or "."))
    path = Path(spec)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise IdentifySpecError(f"{path}: no such file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise IdentifySpecError(f"{path}: not a TOML file: {' '.join(str(e).split())}") from None
    return _checked(doc, str(path), path.parent)


def _checked(doc: dict, source: str, base: Path) -> IdentifySpec:
    from fmpy import read_model_description

    try:
        _unknown(doc, TOP_KEYS, source)
    except FitSpecError as e:
        raise IdentifySpecError(str(e)) from None
    if not isinstance(doc.get("fmu"), str) or not doc["fmu"]:
        raise IdentifySpecError(f'{source}: fmu = "...": the arm\'s FMU (built from its model file) is required')
    fmu = (base / doc["fmu"]).resolve()
    if not fmu.is_file():
        raise IdentifySpecError(f"{source}: fmu = {doc['fmu']!r}: no such file")
    try:
        md = read_model_description(str(fmu))
    except Exception as e:  # noqa: BLE001 -- fmpy raises several kinds for a file that is not an FMU
        raise IdentifySpecError(f"{source}: fmu = {doc['fmu']!r}: not an FMU: {' '.join(str(e).split())}") from None
    n = sum(1 for v in md.modelVariables if re.fullmatch(r"q\[\d+\]", v.name))
    options = dict(IDENTIFY_DEFAULTS)
    raw = doc.get("identify", {})
    if not isinstance(raw, dict):
        raise IdentifySpecError(f"{source}: identify: must be a table, e.g. [identify]")
    try:
        _unknown(raw, list(IDENTIFY_DEFAULTS), f"{source}: identify")
    except FitSpecError as e:
        raise IdentifySpecError(str(e)) from None
    options.update(raw)
    if options["friction"] not in FRICTION:
        raise IdentifySpecError(
            f"{source}: identify.friction = {options['friction']!r}: one of {', '.join(map(repr, FRICTION))}"
        )
    if not isinstance(options["armature"], bool):
        raise IdentifySpecError(f"{source}: identify.armature = {options['armature']!r}: true or false")
    prior = options["prior"]
    if isinstance(prior, bool) or not isinstance(prior, (int, float)) or not (0.0 < prior < 1.0):
        raise IdentifySpecError(f"{source}: identify.prior = {prior!r}: a number in (0, 1), e.g. 1e-4")
    spread = options["catalogue_uncertainty"]
    if isinstance(spread, bool) or not isinstance(spread, (int, float)) or not (0.0 <= spread <= 1.0):
        raise IdentifySpecError(
            f"{source}: identify.catalogue_uncertainty = {spread!r}: a relative error in [0, 1], e.g. 0.3"
        )
    try:
        flt = _filter(options["derivatives"], f"{source}: identify.derivatives")
    except FitSpecError as e:
        raise IdentifySpecError(str(e)) from None
    logs = {}
    for key in ("experiment", "heldout"):
        raw = doc.get(key, [])
        if not isinstance(raw, list) or not all(isinstance(x, dict) for x in raw):
            raise IdentifySpecError(f"{source}: {key}: must be tables, e.g. [[{key}]]")
        logs[key] = [_log(x, k, f"{source}: {key}[{k + 1}]", base, n) for k, x in enumerate(raw)]
    if not logs["experiment"]:
        raise IdentifySpecError(f"{source}: no [[experiment]]: at least one torque log is needed")
    names = [x.name for x in logs["experiment"] + logs["heldout"]]
    if len(set(names)) != len(names):
        raise IdentifySpecError(f"{source}: two runs share a name: {sorted({x for x in names if names.count(x) > 1})}")
    return IdentifySpec(
        source,
        fmu,
        n,
        logs["experiment"],
        logs["heldout"],
        options["friction"],
        options["armature"],
        float(prior),
        flt,
        float(spread),
    )


def _joint_columns(raw, prefix: str, where: str, n: int) -> dict:
    """{joint: column} of a table {"q[1]" = "q1", ...} whose keys name joints 1..n."""
    if not isinstance(raw, dict) or not raw:
        raise IdentifySpecError(f'{where}: must be a table such as {{ "{prefix}[1]" = "column" }}')
    out = {}
    for key, column in raw.items():
        m = re.fullmatch(re.escape(prefix) + r"\[(\d+)\]", key)
        if m is None or not 1 <= int(m.group(1)) <= n:
            raise IdentifySpecError(f"{where}: {key!r}: must be {prefix}[i] with i in 1..{n}")
        if not isinstance(column, str) or not column:
            raise IdentifySpecError(f"{where}.{key} = {column!r}: must be a column name")
        out[int(m.group(1))] = column
    return out


def _log(raw: dict, k: int, where: str, base: Path, n: int) -> Log:
    try:
        _unknown(raw, EXPERIMENT_KEYS, where)
    except FitSpecError as e:
        raise IdentifySpecError(str(e)) from None
    for key in ("data", "time", "positions", "torques"):
        if key not in raw:
            raise IdentifySpecError(f"{where}: `{key}` is required")
    if not isinstance(raw["data"], str) or not isinstance(raw["time"], str):
        raise IdentifySpecError(f"{where}: data and time must be strings (a file and a column)")
    path = base / raw["data"]
    try:
        table = _read_csv(path, where)
    except FitSpecError as e:
        raise IdentifySpecError(str(e)) from None
    positions = _joint_columns(raw["positions"], "q", f"{where}.positions", n)
    missing = [i for i in range(1, n + 1) if i not in positions]
    if missing:
        raise IdentifySpecError(f"{where}.positions: every joint's position is needed; missing q[{missing[0]}]")
    torques = _joint_columns(raw["torques"], "tau", f"{where}.torques", n)

    def column(name: str, what: str) -> np.ndarray:
        if name not in table:
            raise IdentifySpecError(f"{where}: {what} column {name!r} is not in {path.name}")
        values = table[name]
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise IdentifySpecError(f"{where}: {path.name} line {bad[0] + 2}, column {name!r}: not a finite number")
        return values

    t = column(raw["time"], "time")
    if len(t) < 20:
        raise IdentifySpecError(f"{where}: {path.name} has {len(t)} samples: at least 20 are needed")
    steps = np.diff(t)
    if not np.all(steps > 0):
        raise IdentifySpecError(f"{where}: {path.name} line {int(np.argmin(steps)) + 3}: time does not increase")
    if np.max(np.abs(steps - np.median(steps))) > 1e-3 * np.median(steps) + 1e-12:
        raise IdentifySpecError(f"{where}: {path.name}: the samples are not evenly spaced (1e-3 of the interval)")
    q = np.column_stack([column(positions[i], f"q[{i}]") for i in range(1, n + 1)])
    tau = {i: column(c, f"tau[{i}]") for i, c in sorted(torques.items())}
    name = raw.get("name", Path(raw["data"]).stem)
    if not isinstance(name, str) or not name:
        raise IdentifySpecError(f"{where}.name = {name!r}: must be a string")
    return Log(name, t, q, tau)
