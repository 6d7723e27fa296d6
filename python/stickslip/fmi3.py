"""The FMI 3.0 FMU (``<name>-fmi3.fmu``) seen through the FMI 2.0 FMU's scalar names.

The FMI 3.0 modelDescription groups the FMI 2.0 scalars (``q[1]`` … ``q[4]``, ``f[2,3]``)
into arrays (``q``, ``f``) in the FMI 2.0 order (docs/fmi3.md). :func:`scalar_view` gives back
the scalars, each with a value reference of its own into the arrays, and :class:`ScalarSlave`
runs an FMI 3.0 instance behind the FMI 2.0 calls that :mod:`stickslip.simulate` and
:mod:`stickslip.fmu` make (``setupExperiment``, ``setReal``, ``getReal``, ``doStep`` …), so that
``stickslip simulate --fmu X-fmi3.fmu`` takes the same ``--set mu_k[3]=…`` and writes the same
columns as with the FMI 2.0 FMU (and, without early return, the same numbers, bit for bit).

An array over some of the joints says which in its description, ``(elements: joints 1, 3)``
(src/fmi/description/writer3.rs); without that note element i is joint i.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from itertools import product

_ELEMENTS = re.compile(r"\(elements: joints? ([0-9, ]+)\)")


def is_fmi3(md) -> bool:
    return str(md.fmiVersion).startswith("3")


@dataclass
class Scalar:
    """One FMI 2.0-style scalar of an FMI 3.0 array (the attributes fmpy's ScalarVariable has
    that this package reads)."""

    name: str
    valueReference: int
    causality: str
    variability: str
    type: str  # "Real" or "Boolean", as in FMI 2.0
    description: str
    start: object = None
    array: int = 0  # the FMI 3.0 value reference
    offset: int = 0  # the element's position in the array
    size: int = 1  # the array's number of elements
    fmi3_type: str = "Float64"


@dataclass
class ScalarView:
    """The parts of an FMI 2.0 modelDescription this package reads, for an FMI 3.0 FMU."""

    guid: str
    fmiVersion: str
    coSimulation: object
    modelVariables: list = field(default_factory=list)
    arrays: dict = field(default_factory=dict)  # FMI 3.0 value reference -> (type, size)


def _indices(v) -> list[tuple[int, ...]]:
    dims = [int(d.start) for d in v.dimensions]
    if not dims:
        return [()]
    m = _ELEMENTS.search(v.description or "")
    first = [int(j) for j in m.group(1).replace(" ", "").split(",")] if m else list(range(1, dims[0] + 1))
    if len(first) != dims[0]:
        raise ValueError(f"`{v.name}`: {dims[0]} elements but the description names {len(first)} joints")
    rest = [range(1, d + 1) for d in dims[1:]]
    return [(i, *r) for i in first for r in product(*rest)]


def scalar_view(md) -> ScalarView:
    """The FMI 2.0-style scalars of an FMI 3.0 model description (fmpy's), in order."""
    view = ScalarView(guid=md.guid, fmiVersion=md.fmiVersion, coSimulation=md.coSimulation)
    for v in md.modelVariables:
        if v.causality == "independent":
            continue
        indices = _indices(v)
        starts = str(v.start).split() if v.start is not None else [None] * len(indices)
        view.arrays[v.valueReference] = (v.type, len(indices))
        for offset, index in enumerate(indices):
            name = v.name if not index else f"{v.name}[{','.join(map(str, index))}]"
            view.modelVariables.append(
                Scalar(
                    name=name,
                    valueReference=len(view.modelVariables),
                    causality=v.causality,
                    variability=v.variability,
                    type="Boolean" if v.type == "Boolean" else "Real",
                    description=v.description or "",
                    start=starts[offset] if offset < len(starts) else None,
                    array=v.valueReference,
                    offset=offset,
                    size=len(indices),
                    fmi3_type=v.type,
                )
            )
    return view


class ScalarSlave:
    """An FMI 3.0 co-simulation instance (fmpy's FMU3Slave) behind the FMI 2.0 calls of
    fmpy's FMU2Slave that this package makes, on the scalars of :func:`scalar_view`.
    Log messages go to a :class:`stickslip.fmu.LogCapture`'s ``records`` as FMI 2.0's do."""

    def __init__(self, view: ScalarView, unzipDirectory: str, instanceName: str = "run"):
        from fmpy.fmi3 import FMU3Slave

        self.view = view
        self.scalars = view.modelVariables
        self.fmu = FMU3Slave(
            guid=view.guid,
            unzipDirectory=unzipDirectory,
            modelIdentifier=view.coSimulation.modelIdentifier,
            instanceName=instanceName,
        )
        self.records = None
        self.name = instanceName

    def instantiate(self, callbacks=None, loggingOn=False, log=None):
        self.records = log.records if log is not None else None

        def message(env, status, category, text):
            if self.records is not None:
                self.records.append((self.name, int(status), category.decode(), text.decode("utf-8", "replace")))

        self.fmu.instantiate(loggingOn=loggingOn, logMessage=message)

    # -- life cycle ------------------------------------------------------------
    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None):
        # FMI 3.0 takes the experiment with fmi3EnterInitializationMode, and reads no values
        # before it: the parameters FMI 2.0 code sets next go in in Initialization Mode.
        self.fmu.enterInitializationMode(tolerance=tolerance, startTime=startTime, stopTime=stopTime)

    def enterInitializationMode(self):
        """Already there (see :meth:`setupExperiment`)."""

    def exitInitializationMode(self):
        self.fmu.exitInitializationMode()

    def doStep(self, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint=True):
        self.fmu.doStep(currentCommunicationPoint, communicationStepSize)

    def terminate(self):
        self.fmu.terminate()

    def freeInstance(self):
        self.fmu.freeInstance()

    # -- values: whole arrays read, the elements asked for picked ----------------
    def _arrays(self, vrs):
        arrays: dict[int, list[tuple[int, int]]] = {}
        for i, vr in enumerate(vrs):
            s = self.scalars[vr]
            arrays.setdefault(s.array, []).append((i, s.offset))
        return arrays

    def _get_array(self, vr: int):
        kind, size = self.view.arrays[vr]
        getter = {"Float64": self.fmu.getFloat64, "Int32": self.fmu.getInt32, "Boolean": self.fmu.getBoolean}[kind]
        return getter([vr], size)

    def getReal(self, vrs):
        out = [0.0] * len(vrs)
        for array, picks in self._arrays(vrs).items():
            values = self._get_array(array)
            for i, offset in picks:
                out[i] = float(values[offset])
        return out

    def getBoolean(self, vrs):
        return [bool(x) for x in self.getReal(vrs)]

    def setReal(self, vrs, values):
        for array, picks in self._arrays(vrs).items():
            current = list(self._get_array(array))
            for i, offset in picks:
                current[offset] = float(values[i])
            if self.view.arrays[array][0] == "Int32":
                self.fmu.setInt32([array], [int(x) for x in current])
            else:
                self.fmu.setFloat64([array], current)

    def setBoolean(self, vrs, values):
        for array, picks in self._arrays(vrs).items():
            current = [bool(x) for x in self._get_array(array)]
            for i, offset in picks:
                current[offset] = bool(values[i])
            self.fmu.setBoolean([array], current)
