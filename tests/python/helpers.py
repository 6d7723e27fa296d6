"""Shared helpers of the FMU tests (tests/python/test_*.py) and of
examples/pd_control.py.

* where the FMU is (``target/fmu/StickSlipManipulator.fmu``, or ``$STICKSLIP_FMU``),
  extracted once per process;
* the reference motion of shared/reference-manipulator.md (``stickslip.motion``):
  cycloidal profiles over T = 1.5 s evaluated with the same floating-point
  operations as ``src/motion.rs``, so that the inputs are bit-identical to those
  of the Rust engine's ``simulate_reference`` binary;
* a direct run of the engine (``simulate_reference`` CSV), cached per process;
* :class:`Slave`, a thin wrapper over fmpy's ``FMU2Slave`` that looks every
  variable up by name in the modelDescription (never a hard-coded value
  reference) and captures the FMU's log messages (``stickslip.fmu.LogCapture``);
* comparison of two runs relative to each signal's largest magnitude.
"""

from __future__ import annotations

import atexit
import csv
import functools
import hashlib
import math
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

# Reference motion (shared/reference-manipulator.md) and the FMU's log capture: the
# package `stickslip` (python/stickslip, installed into the venv by scripts/env.sh).
from stickslip.fmu import LogCapture
from stickslip.motion import MOTION_TIME, REFERENCE_PROFILES, RUN_TIME, cycloidal, reference_inputs  # noqa: F401
from stickslip.motion import input_names as motion_input_names

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"

INTERVAL = 1e-3  # communication step, s
N_JOINTS = 4
FLEXIBLE = (1, 3)  # 1-based joint indices with a flexible drive


def fmu_path() -> Path:
    """The FMU under test: $STICKSLIP_FMU or target/fmu/StickSlipManipulator.fmu."""
    return Path(os.environ.get("STICKSLIP_FMU", str(DEFAULT_FMU))).resolve()


def require_fmu() -> Path:
    """The FMU's path; skips the calling test (with the reason) if it is not built."""
    path = fmu_path()
    if not path.is_file():
        import pytest

        pytest.skip(f"{path} does not exist: build it with `bash scripts/build_fmu.sh` (scripts/test.sh does)")
    return path


# ---------------------------------------------------------------------------
# reference motion


def communication_times(end: float = RUN_TIME, interval: float = INTERVAL) -> np.ndarray:
    """t_k = k * interval, k = 0..n (the same products as the Rust binary's ``k as f64 * interval``)."""
    n = round(end / interval)
    return np.array([k * interval for k in range(n + 1)], dtype=np.float64)


def input_names():
    """Names of the 12 inputs, in the order q_star[1..4], qd_star[1..4], qdd_star[1..4]."""
    return motion_input_names(N_JOINTS)


def input_vector(t: float):
    """The 12 input values at time t, in the order of :func:`input_names`."""
    q, qd, qdd = reference_inputs(t)
    return q + qd + qdd


def input_signals(end: float = RUN_TIME, interval: float = INTERVAL) -> np.ndarray:
    """The reference motion as fmpy's structured input array ('time' first) at every t_k."""
    times = communication_times(end, interval)
    names = input_names()
    signals = np.zeros(len(times), dtype=[("time", np.float64)] + [(n, np.float64) for n in names])
    signals["time"] = times
    rows = np.array([input_vector(float(t)) for t in times])
    for j, n in enumerate(names):
        signals[n] = rows[:, j]
    return signals


# ---------------------------------------------------------------------------
# direct run of the engine


def cargo_targets(*targets: str) -> list:
    """The cargo target selection for a test's own `cargo build --release`: `targets`, or
    `--all-targets` under scripts/test.sh (STICKSLIP_FMU_ALL_TARGETS=1), which resolves the
    dependencies' features as `cargo test` did and so reuses its build of the engine."""
    return ["--all-targets"] if os.environ.get("STICKSLIP_FMU_ALL_TARGETS") == "1" else list(targets)


def _cargo() -> str:
    cargo = shutil.which("cargo") or str(Path.home() / ".cargo" / "bin" / "cargo")
    return cargo


_TMP = None


def scratch_dir() -> Path:
    """A per-process scratch directory, removed at exit."""
    global _TMP
    if _TMP is None:
        _TMP = Path(tempfile.mkdtemp(prefix="stickslip-pytest-"))
        atexit.register(shutil.rmtree, _TMP, True)
    return _TMP


def read_csv(path) -> dict:
    """A CSV of simulate_reference as {column name: float array} (RFC-4180 quoting)."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = [[float(x) for x in row] for row in reader if row]
    data = np.array(rows, dtype=np.float64)
    return {name: data[:, j] for j, name in enumerate(header)}


@functools.cache
def direct_run(end: float = RUN_TIME, interval: float = INTERVAL) -> dict:
    """The engine's own run of the reference motion (``simulate_reference``).

    The binary is built with the test run's target selection (``cargo_targets``): `cargo run
    --bin` would resolve the dependencies' features without the dev-dependencies and compile
    the engine once more (about 55 s under scripts/test.sh, whose `cargo test` built it)."""
    out = scratch_dir() / f"direct_{end:g}_{interval:g}.csv"
    build = [_cargo(), "build", "--release", "--quiet", *cargo_targets("--bin", "simulate_reference")]
    subprocess.run(build, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    target = Path(os.environ.get("CARGO_TARGET_DIR", str(ROOT / "target")))
    cmd = [str(target / "release" / "simulate_reference"), "--out", str(out)]
    cmd += ["--interval", repr(interval), "--end", repr(end)]
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return read_csv(out)


# ---------------------------------------------------------------------------
# the FMU


@functools.cache
def model_description(path: str | None = None):
    from fmpy import read_model_description

    return read_model_description(str(path or fmu_path()))


def unzip_dir(path: str | None = None) -> str:
    """The FMU extracted once per process (removed at exit); each FMU (by resolved path)
    into a directory of its own, so that instances of two FMUs in one process (the
    reference and a URDF arm's) never share resources/."""
    return _unzip_dir(str(Path(path or fmu_path()).resolve()))


@functools.cache
def _unzip_dir(path: str) -> str:
    from fmpy import extract

    default = path == str(fmu_path())
    target = scratch_dir() / ("fmu" if default else f"fmu-{hashlib.sha1(path.encode()).hexdigest()[:12]}")
    if target.exists():
        shutil.rmtree(target)
    return extract(path, unzipdir=str(target))


class Variables:
    """Name -> ScalarVariable of the modelDescription, and the output lists."""

    def __init__(self, md):
        self.md = md
        self.by_name = {v.name: v for v in md.modelVariables}
        self.real_outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
        self.bool_outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Boolean"]

    def vr(self, name: str) -> int:
        return self.by_name[name].valueReference

    def vrs(self, names) -> list:
        return [self.vr(n) for n in names]


@functools.cache
def variables(path: str | None = None) -> Variables:
    return Variables(model_description(path))


class Slave:
    """An FMI 2.0 CS instance through fmpy's FMU2Slave, variables by name, log captured."""

    def __init__(self, name: str = "inst", logging_on: bool = False, path: str | None = None, instantiate: bool = True):
        from fmpy.fmi2 import FMU2Slave

        self.path = str(path or require_fmu())
        self.md = model_description(self.path)
        self.vars = variables(self.path)
        self.log = LogCapture()
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=unzip_dir(self.path),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.instantiated = False
        self.freed = False
        if instantiate:
            self.fmu.instantiate(callbacks=self.log.callbacks, loggingOn=logging_on)
            self.instantiated = True
        self._in_vrs = self.vars.vrs(input_names())
        self._real_out_vrs = self.vars.vrs(self.vars.real_outputs)
        self._bool_out_vrs = self.vars.vrs(self.vars.bool_outputs)

    # -- set-up ----------------------------------------------------------------
    def initialize(self, inputs=None, start_values: dict | None = None, t0: float = 0.0, stop_time=None):
        """setupExperiment, start values, enter/exit initialization with the inputs at t0."""
        self.fmu.setupExperiment(startTime=t0, stopTime=stop_time)
        for name, value in (start_values or {}).items():
            self.set(name, value)
        self.fmu.enterInitializationMode()
        self.set_inputs(input_vector(t0) if inputs is None else inputs)
        self.fmu.exitInitializationMode()

    def set(self, name: str, value):
        v = self.vars.by_name[name]
        if v.type == "Boolean":
            self.fmu.setBoolean([v.valueReference], [bool(value)])
        else:
            self.fmu.setReal([v.valueReference], [float(value)])

    def get(self, name: str):
        v = self.vars.by_name[name]
        if v.type == "Boolean":
            return bool(self.fmu.getBoolean([v.valueReference])[0])
        return self.fmu.getReal([v.valueReference])[0]

    def set_inputs(self, values):
        """The 12 inputs in the order of :func:`input_names`."""
        self.fmu.setReal(self._in_vrs, [float(x) for x in values])

    # -- stepping --------------------------------------------------------------
    def outputs(self) -> np.ndarray:
        """All Real outputs then all Boolean outputs (as 0/1), in modelDescription order."""
        r = self.fmu.getReal(self._real_out_vrs)
        b = self.fmu.getBoolean(self._bool_out_vrs)
        return np.array(r + [float(x != 0) for x in b], dtype=np.float64)

    def output_names(self):
        return self.vars.real_outputs + self.vars.bool_outputs

    def run_reference(self, k0: int, steps: int, interval: float = INTERVAL) -> np.ndarray:
        """Steps k0 .. k0+steps-1 of the reference motion (inputs at t_k, doStep(t_k, interval));
        returns the outputs after each step, one row per step."""
        rows = []
        for k in range(k0, k0 + steps):
            t = k * interval
            self.set_inputs(input_vector(t))
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=interval)
            rows.append(self.outputs())
        return np.array(rows)

    def free(self):
        if self.freed:
            return
        self.freed = True
        if self.instantiated:
            try:
                self.fmu.terminate()
            except Exception:  # noqa: BLE001 -- an instance in any state is freed; its errors were reported before
                pass
            self.fmu.freeInstance()  # also releases this object's handle of the library
        else:
            self.fmu.freeLibrary()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def reference_slave(name: str = "ref", **kw) -> Slave:
    """A Slave initialized at t = 0 with the reference motion's inputs."""
    s = Slave(name, **kw)
    s.initialize()
    return s


# ---------------------------------------------------------------------------
# comparison


# Outputs that describe the stepper, not the motion: the sub-step sequence of an
# error-controlled run depends on the communication points to the last bit.
STEPPER_STATISTICS = ("n_substeps", "n_rejected", "h_last")


def physical(names) -> list:
    """The indices of ``names`` that are not stepper statistics."""
    return [j for j, n in enumerate(names) if n not in STEPPER_STATISTICS]


def max_relative_deviation(actual: np.ndarray, expected: np.ndarray) -> float:
    """max |actual - expected| / max |expected| (per signal = per column), over all columns.
    A column that is identically zero in ``expected`` must match exactly (else inf)."""
    actual = np.atleast_2d(actual)
    expected = np.atleast_2d(expected)
    assert actual.shape == expected.shape, (actual.shape, expected.shape)
    worst = 0.0
    for j in range(expected.shape[1]):
        scale = float(np.max(np.abs(expected[:, j])))
        diff = float(np.max(np.abs(actual[:, j] - expected[:, j])))
        if diff == 0.0:
            continue
        worst = max(worst, diff / scale if scale > 0 else math.inf)
    return worst


def assert_close_signals(actual: dict, expected: dict, names, rel: float = 1e-12):
    """Every named signal agrees to ``rel`` of its largest magnitude in ``expected``."""
    bad = []
    for n in names:
        a = np.asarray(actual[n], dtype=np.float64)
        e = np.asarray(expected[n], dtype=np.float64)
        assert a.shape == e.shape, (n, a.shape, e.shape)
        scale = float(np.max(np.abs(e)))
        diff = float(np.max(np.abs(a - e)))
        if diff > rel * scale:
            bad.append(f"{n}: max |diff| = {diff:.3e}, scale {scale:.3e}")
    assert not bad, f"signals differ beyond {rel:.0e}:\n" + "\n".join(bad)


def bit_identical(actual: dict, expected: dict, names) -> bool:
    return all(np.array_equal(np.asarray(actual[n], float), np.asarray(expected[n], float)) for n in names)


def binomial_tail(n: int, p: float, k: int) -> float:
    """P(X >= k) for X ~ Binomial(n, p): sum_{i=k}^{n} C(n, i) p^i (1 - p)^(n - i)."""
    import math

    return sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1))


def allowed_misses(n: int, p: float, alpha: float = 1e-3) -> int:
    """The most misses of n a coverage test may allow so that, where each pair misses with
    probability p, it fails in fewer than ``alpha`` of its runs: the largest m with
    P(X >= m + 1) < alpha (the statistical tests' sizing, issue 41)."""
    return next(k for k in range(n + 2) if binomial_tail(n, p, k) < alpha) - 1
