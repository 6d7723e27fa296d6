"""The FMI 3.0 FMU as ``package_fmu --fmi3`` packs it: its modelDescription (the FMI 2.0
variables grouped into arrays, src/fmi/description/arrays.rs and writer3.rs; units through
``declaredType`` and the ``TypeDefinitions``) read and validated by fmpy, and the archive's
layout (binaries per FMI 3.0 platform tuple, the universal macOS dylib split into its two
slices, terminalsAndIcons/icon.png, documentation/ and resources/ as in the FMI 2.0 FMU).

The FMUs are packed into the scratch directory from the reference arm, the motor-drive arm
and the KUKA iiwa URDF arm. The binaries in them are stand-ins: the linux64 library is the
FMI 3.0 one when it is built, else the FMI 2.0 one (or a placeholder), the win64 DLL a
placeholder and the darwin64 dylib a synthetic universal file of two tiny slices. What the
binaries do is not under test here, only where they go.
"""

from __future__ import annotations

import functools
import shutil
import struct
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import fmpy
import pytest
from fmpy.validation import validate_fmu

from helpers import ROOT, cargo_targets, scratch_dir

RELEASE = ROOT / "target" / "release"
MODELS = {
    "reference": None,  # package_fmu's default: models/reference_rrpr.toml
    "motor": ROOT / "models" / "reference_rrpr_motor.toml",
    "iiwa": ROOT / "models" / "urdf" / "kuka_iiwa" / "kuka_iiwa.toml",
}
CPU_X86_64, CPU_ARM64 = 0x01000007, 0x0100000C
FMI3_BINARIES = [
    "binaries/x86_64-linux/StickSlipManipulator.so",
    "binaries/x86_64-windows/StickSlipManipulator.dll",
    "binaries/x86_64-darwin/StickSlipManipulator.dylib",
    "binaries/aarch64-darwin/StickSlipManipulator.dylib",
]


def thin_slice(cputype: int, body: bytes) -> bytes:
    """A stand-in 64-bit Mach-O: MH_MAGIC_64 and the cputype (little-endian), then ``body``."""
    return struct.pack("<II", 0xFEEDFACF, cputype) + body


SLICES = {CPU_X86_64: thin_slice(CPU_X86_64, b"x86_64 slice"), CPU_ARM64: thin_slice(CPU_ARM64, b"arm64 slice" * 500)}


def universal(slices: dict) -> bytes:
    """A universal (fat) Mach-O of ``slices`` {cputype: bytes}, each at a 4 KiB boundary."""
    header = struct.pack(">II", 0xCAFEBABE, len(slices))
    body, offset = b"", 4096
    for cputype, data in slices.items():
        header += struct.pack(">IIIII", cputype, 3, offset, len(data), 12)
        body += b"\0" * (offset - 4096 - len(body)) + data
        offset += -(-len(data) // 4096) * 4096
    return header + b"\0" * (4096 - len(header)) + body


@functools.cache
def package_fmu() -> Path:
    """The release ``package_fmu`` binary, built on first use."""
    cargo = shutil.which("cargo") or str(Path.home() / ".cargo" / "bin" / "cargo")
    cmd = [cargo, "build", "--release", "--quiet", *cargo_targets("--bin", "package_fmu")]
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert r.returncode == 0, f"{' '.join(cmd)} failed:\n{r.stdout[-4000:]}"
    return RELEASE / "package_fmu"


@functools.cache
def stand_ins() -> dict:
    """The files given as binaries (their contents are not under test, see the module doc)."""
    d = scratch_dir() / "fmi3-binaries"
    d.mkdir(exist_ok=True)
    lib = next(
        (
            p
            for p in (RELEASE / "libstick_slip_manipulator_fmi3.so", RELEASE / "libstick_slip_manipulator.so")
            if p.is_file()
        ),
        None,
    )
    if lib is None:
        lib = d / "placeholder.so"
        lib.write_bytes(b"\x7fELF placeholder, not a library")
    dll, dylib = d / "placeholder.dll", d / "universal.dylib"
    dll.write_bytes(b"MZ placeholder, not a DLL")
    dylib.write_bytes(universal(SLICES))
    return {"--lib": lib, "--win64-lib": dll, "--darwin64-lib": dylib}


def run_package_fmu(*args) -> subprocess.CompletedProcess:
    return subprocess.run([str(package_fmu()), *map(str, args)], cwd=ROOT, capture_output=True, text=True)


@functools.cache
def fmu(key: str, fmi3: bool = True) -> Path:
    """The FMI 3.0 (or, for comparison, FMI 2.0) FMU of model ``key``, packed on first use."""
    # a name of its own: urdf_fmus/motor_fmus build `<key>.fmu` into the same scratch directory
    out = scratch_dir() / f"packed-{key}{'-fmi3' if fmi3 else ''}.fmu"
    args = ["--fmi3"] if fmi3 else []
    if MODELS[key] is not None:
        args += ["--model", MODELS[key]]
    for flag, path in stand_ins().items():
        args += [flag, path]
    r = run_package_fmu(*args, "--out", out)
    assert r.returncode == 0 and out.is_file(), f"package_fmu {' '.join(map(str, args))}:\n{r.stderr}"
    return out


def unit_of(v):
    """(unit, displayUnit) of an fmpy variable through its declared type: the FMI 3.0
    variables carry neither themselves (the ``fmi`` crate's schema refuses them there)."""
    assert (v.unit, v.displayUnit) == (None, None), f"{v.name} carries a unit itself"
    t = v.declaredType
    return (t.unit, t.displayUnit) if t is not None else (None, None)


def raw_variables(path: Path) -> dict:
    """The ModelVariables elements of the FMU's modelDescription.xml by name (fmpy does not
    read every FMI 3.0 attribute, e.g. intermediateUpdate)."""
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    return {v.get("name"): v for v in root.find("ModelVariables")}


@pytest.mark.parametrize("key", MODELS)
def test_fmpy_reads_and_validates_it(key):
    path = fmu(key)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path), validate=True)
    assert md.fmiVersion == "3.0"
    assert md.modelExchange is None and md.scheduledExecution is None
    cs = md.coSimulation
    assert cs.modelIdentifier == "StickSlipManipulator"
    assert cs.canHandleVariableCommunicationStepSize
    # fmpy's attribute names for canGetAndSetFMUState and canSerializeFMUState
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.hasEventMode and cs.providesIntermediateUpdate and cs.canReturnEarlyAfterIntermediateUpdate
    assert cs.maxOutputDerivativeOrder == 2
    assert cs.fixedInternalStepSize is None
    time = md.modelVariables[0]
    assert (time.name, time.valueReference, time.causality, time.variability) == (
        "time",
        0,
        "independent",
        "continuous",
    )
    assert [v.valueReference for v in md.modelVariables] == list(range(len(md.modelVariables)))
    assert (md.defaultExperiment.startTime, md.defaultExperiment.stopTime, md.defaultExperiment.stepSize) == (
        "0",
        "2",
        "0.001",
    )


@pytest.mark.parametrize("key", MODELS)
def test_the_arrays_hold_every_fmi_2_0_variable_once(key):
    """Every FMI 2.0 scalar ``x[i]``/``x[i,k]`` is an element of the FMI 3.0 array ``x``: the
    arrays' sizes add up to the FMI 2.0 variables, stem by stem, and the instantiation token is
    the FMI 2.0 GUID."""
    md2 = fmpy.read_model_description(str(fmu(key, fmi3=False)))
    md3 = fmpy.read_model_description(str(fmu(key)))
    assert md3.instantiationToken == md2.guid
    stems = {}
    for v in md2.modelVariables:
        stem = v.name.split("[")[0]
        stems[stem] = stems.get(stem, 0) + 1
    sizes = {}
    for v in md3.modelVariables[1:]:
        size = 1
        for d in v.dimensions:
            size *= int(d.start)
        sizes[v.name] = size
    assert sizes == stems
    # The same causality as the FMI 2.0 elements.
    causality2 = {v.name.split("[")[0]: v.causality for v in md2.modelVariables}
    assert {v.name: v.causality for v in md3.modelVariables[1:]} == causality2


def test_the_reference_arm_declares_dimensions_types_and_units():
    md = fmpy.read_model_description(str(fmu("reference")))
    v = {x.name: x for x in md.modelVariables}

    def dims(name):
        return [int(d.start) for d in v[name].dimensions]

    for name in ("q_star", "qd_star", "qdd_star", "q", "qd", "qdd", "stick", "n_stick", "F_drive", "eps_joint"):
        assert dims(name) == [4], name
    assert dims("f") == dims("n") == [4, 3]
    assert dims("x_E") == [3] and dims("eps") == []
    assert (unit_of(v["f"])[0], unit_of(v["n"])[0], unit_of(v["t_stick"])[0]) == ("N", "N.m", "s")
    assert unit_of(v["x_E"]) == unit_of(v["eps"]) == ("m", "mm")
    assert v["x_E"].declaredType.name == "Length"
    # Joint 3 is prismatic: q mixes rad and m, so it has no unit and names each element's.
    assert unit_of(v["q"]) == (None, None)
    assert "unit per element: rad (joints 1, 2, 4), m (joint 3)" in v["q"].description
    assert (v["stick"].type, v["n_stick"].type, v["n_substeps"].type) == ("Boolean", "Int32", "Int32")
    assert v["n_stick"].variability == "discrete"
    # The flexible joints 1 and 3 only have a drive spring.
    assert dims("k") == [2] and "(elements: joints 1, 3)" in v["k"].description
    assert (v["k"].causality, v["k"].variability, v["k"].start) == ("parameter", "tunable", "1000000 1000000")
    assert (unit_of(v["m"])[0], v["m"].start) == ("kg", "25 15 8 4")
    assert (v["h_max"].variability, unit_of(v["h_max"])[0]) == ("fixed", "s")
    for name in ("q_star", "qd_star", "qdd_star"):
        assert (v[name].causality, v[name].start) == ("input", "0 0 0 0"), name
    outputs = [x.valueReference for x in md.modelVariables if x.causality == "output"]
    assert [u.variable.valueReference for u in md.outputs] == outputs
    assert [u.variable.valueReference for u in md.initialUnknowns] == outputs
    assert all(u.dependencies == [] for u in md.outputs)


def test_an_all_revolute_arm_declares_rad_with_deg():
    md = fmpy.read_model_description(str(fmu("iiwa")))
    v = {x.name: x for x in md.modelVariables}
    for name, unit, display in (("q", "rad", "deg"), ("qd", "rad/s", "deg/s"), ("q_star", "rad", "deg")):
        assert [int(d.start) for d in v[name].dimensions] == [7], name
        assert unit_of(v[name]) == (unit, display), name


@pytest.mark.parametrize("key", MODELS)
def test_every_unit_comes_through_a_declared_type_and_equals_fmi_2_0s(key):
    """Every Float64 variable with a physical unit reaches it through its ``declaredType``
    (no variable carries ``unit`` or ``displayUnit`` itself, in the XML as written): one
    ``Float64Type`` per unit, each used, its display unit the unit's first in the
    ``UnitDefinitions``. The unit equals that of every FMI 2.0 element of the array; an
    array whose elements differ in unit (q of an arm with revolute and prismatic joints),
    or have none, declares no type."""
    md2 = fmpy.read_model_description(str(fmu(key, fmi3=False)), validate=True)
    md3 = fmpy.read_model_description(str(fmu(key)), validate=True)
    for name, e in raw_variables(fmu(key)).items():
        assert e.get("unit") is None and e.get("displayUnit") is None, name
    units2 = {}
    for v in md2.modelVariables:
        units2.setdefault(v.name.split("[")[0], set()).add(v.unit)
    display = {u.name: [d.name for d in u.displayUnits] for u in md3.unitDefinitions}
    types = md3.typeDefinitions
    assert len({t.name for t in types}) == len({t.unit for t in types}) == len(types) > 0
    used, with_unit = set(), 0
    for v in md3.modelVariables[1:]:
        unit, shown = unit_of(v)
        (shared,) = units2[v.name] if len(units2[v.name]) == 1 else (None,)
        assert unit == (shared if v.type == "Float64" else None), (key, v.name, unit, units2[v.name])
        if unit is not None:
            with_unit += 1
            used.add(v.declaredType.name)
            assert shown == (display[unit][0] if display[unit] else None), (v.name, shown)
    assert used == {t.name for t in types}
    print(f"{key}: {with_unit} Float64 variables with a unit, through {len(types)} types: {sorted(used)}")


@pytest.mark.parametrize("key", ["reference", "motor"])
def test_the_drive_inputs_allow_intermediate_update(key):
    raw = raw_variables(fmu(key))
    inputs = {name for name, e in raw.items() if e.get("causality") == "input"}
    expected = {"q_star", "qd_star", "qdd_star"} | ({"tau_m"} if key == "motor" else set())
    assert inputs == expected
    for name, e in raw.items():
        assert e.get("intermediateUpdate") == ("true" if name in expected else None), name
    if key == "motor":
        tau_m = raw["tau_m"]
        assert [d.get("start") for d in tau_m.findall("Dimension")] == ["2"]
        assert (tau_m.get("unit"), tau_m.get("declaredType"), tau_m.get("start")) == (None, "Torque", "0 0")
        assert "(elements: joints 1, 3)" in tau_m.get("description")


@pytest.mark.parametrize("key", MODELS)
def test_the_archive_has_the_fmi_3_0_layout(key):
    with zipfile.ZipFile(fmu(key)) as z3, zipfile.ZipFile(fmu(key, fmi3=False)) as z2:
        names3, names2 = z3.namelist(), z2.namelist()
        resources = [n for n in names2 if n.startswith("resources/")]
        assert "resources/model.toml" in resources
        assert names3 == [
            "modelDescription.xml",
            "terminalsAndIcons/icon.png",
            "documentation/index.html",
            *FMI3_BINARIES,
            *resources,
        ]
        if key == "iiwa":
            assert "resources/kuka_iiwa.urdf" in resources
        # The same icon, documentation and resources as the FMI 2.0 FMU.
        assert z3.read("terminalsAndIcons/icon.png") == z2.read("model.png")
        assert z3.read("terminalsAndIcons/icon.png").startswith(b"\x89PNG\r\n\x1a\n")
        assert z3.read("documentation/index.html") == z2.read("documentation/index.html")
        for name in resources:
            assert z3.read(name) == z2.read(name), name
        # The universal dylib's two slices, each in its platform's directory.
        assert z3.read(FMI3_BINARIES[2]) == SLICES[CPU_X86_64]
        assert z3.read(FMI3_BINARIES[3]) == SLICES[CPU_ARM64]
        assert z3.read(FMI3_BINARIES[0]) == stand_ins()["--lib"].read_bytes()
        for name in FMI3_BINARIES:
            assert z3.getinfo(name).external_attr >> 16 & 0o777 == 0o755, name


@pytest.mark.parametrize(
    "content, message",
    [
        (SLICES[CPU_X86_64], "thin (single-architecture) Mach-O"),
        (universal({CPU_X86_64: SLICES[CPU_X86_64]}), "no arm64 slice"),
        (b"\x7fELF not a dylib", "not a universal Mach-O file"),
    ],
)
def test_a_darwin64_library_that_is_not_universal_is_refused(content, message, tmp_path):
    bad = tmp_path / "bad.dylib"
    bad.write_bytes(content)
    out = tmp_path / "bad.fmu"
    r = run_package_fmu("--fmi3", "--lib", stand_ins()["--lib"], "--darwin64-lib", bad, "--out", out)
    assert r.returncode == 1
    assert f"--darwin64-lib {bad}: " in r.stderr and message in r.stderr, r.stderr
    assert not out.exists()
