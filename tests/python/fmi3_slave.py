"""An FMI 3.0 co-simulation instance of the FMU through fmpy's FMU3Slave, for the tests:
variables by name (the arrays of the FMI 3.0 modelDescription), log captured, the reference
motion's inputs as the arrays q_star, qd_star, qdd_star."""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import numpy as np

from helpers import DEFAULT_FMU, input_vector, unzip_dir

DEFAULT_FMU3 = DEFAULT_FMU.with_name(DEFAULT_FMU.stem + "-fmi3.fmu")


def fmu3_path() -> Path:
    """The FMI 3.0 FMU under test: $STICKSLIP_FMU3 or target/fmu/StickSlipManipulator-fmi3.fmu."""
    return Path(os.environ.get("STICKSLIP_FMU3", str(DEFAULT_FMU3))).resolve()


def require_fmu3() -> Path:
    path = fmu3_path()
    if not path.is_file():
        import pytest

        pytest.skip(f"{path} does not exist: build it with `bash scripts/build_fmu.sh` (scripts/test.sh does)")
    return path


class Slave3:
    """One fmi3InstantiateCoSimulation instance. Calls that return an error raise (fmpy's
    checks); `self.log` holds (status, category, message) of every log message."""

    def __init__(
        self,
        name: str = "inst3",
        path: str | None = None,
        logging_on: bool = False,
        event_mode_used: bool = False,
        early_return_allowed: bool = False,
        intermediate_update=None,
    ):
        from fmpy import read_model_description
        from fmpy.fmi3 import FMU3Slave

        self.path = str(path or require_fmu3())
        self.md = read_model_description(self.path)
        self.by_name = {v.name: v for v in self.md.modelVariables}
        self.log: list[tuple[int, str, str]] = []
        self.fmu = FMU3Slave(
            guid=self.md.guid,
            unzipDirectory=unzip_dir(self.path),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(
            loggingOn=logging_on,
            eventModeUsed=event_mode_used,
            earlyReturnAllowed=early_return_allowed,
            logMessage=self._log,
            intermediateUpdate=intermediate_update,
        )
        self.freed = False

    def _log(self, env, status, category, message):
        self.log.append((status, category.decode(), message.decode()))

    # -- variables -------------------------------------------------------------
    def size(self, name: str) -> int:
        v = self.by_name[name]
        return int(np.prod([int(d.start) for d in v.dimensions])) if v.dimensions else 1

    def vr(self, name: str) -> int:
        return self.by_name[name].valueReference

    def get(self, name: str) -> np.ndarray:
        v = self.by_name[name]
        n = self.size(name)
        if v.type == "Boolean":
            return np.array(self.fmu.getBoolean([v.valueReference], n), dtype=np.float64)
        if v.type == "Int32":
            return np.array(self.fmu.getInt32([v.valueReference], n), dtype=np.float64)
        return np.array(self.fmu.getFloat64([v.valueReference], n))

    def set(self, name: str, values):
        v = self.by_name[name]
        values = np.atleast_1d(np.asarray(values, dtype=np.float64))
        if v.type == "Boolean":
            self.fmu.setBoolean([v.valueReference], [bool(x) for x in values])
        else:
            self.fmu.setFloat64([v.valueReference], [float(x) for x in values])

    def set_inputs(self, values):
        """The 12 inputs of the reference arm, as helpers.input_vector orders them."""
        values = [float(x) for x in values]
        vrs = [self.vr("q_star"), self.vr("qd_star"), self.vr("qdd_star")]
        self.fmu.setFloat64(vrs, values)

    def output_names(self) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == "output"]

    def outputs(self) -> dict:
        return {name: self.get(name) for name in self.output_names()}

    # -- life cycle ------------------------------------------------------------
    def initialize(self, t0: float = 0.0, inputs=None, stop_time=None):
        self.fmu.enterInitializationMode(startTime=t0, stopTime=stop_time)
        self.set_inputs(input_vector(t0) if inputs is None else inputs)
        self.fmu.exitInitializationMode()

    def do_step(self, t: float, h: float):
        """fmi3DoStep: (eventHandlingNeeded, terminateSimulation, earlyReturn, lastSuccessfulTime)."""
        return self.fmu.doStep(t, h)

    def free(self):
        if self.freed:
            return
        self.freed = True
        try:
            self.fmu.terminate()
        except Exception:  # noqa: BLE001 -- an instance in any state is freed; its errors were logged
            pass
        self.fmu.freeInstance()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def raw_status(function, *args) -> int:
    """Calls an fmpy-loaded FMI 3.0 function without fmpy's status check; returns the status."""
    fn = getattr(function, "__wrapped__", None) or function
    return int(fn(*args))


def c_doubles(values):
    return (ctypes.c_double * len(values))(*values)
