"""The FMUs' macOS binaries, checked statically (nothing here can run macOS code).

``binaries/darwin64/StickSlipManipulator.dylib`` of the shipped FMI 2.0 ``.fmu``
(a universal file) and ``binaries/x86_64-darwin/StickSlipManipulator.dylib`` and
``binaries/aarch64-darwin/StickSlipManipulator.dylib`` of the FMI 3.0 FMU
(``StickSlipManipulator-fmi3.fmu``, ``$STICKSLIP_FMU3``: one thin file per FMI 3.0
platform tuple) are read by a small Mach-O reader written for this test (no Apple
or LLVM tool needed; ``scripts/build_fmu.sh`` checks the same properties with the
LLVM tools, so two independent readers agree). Checked, per slice of the
universal file and per thin FMI 3.0 file alike (the tests named ``[fmi2]`` and
``[fmi3]``):

* format: FMI 2.0 a fat (universal) file with exactly an ``x86_64`` and an
  ``arm64`` slice; FMI 3.0 two thin files, ``x86_64-darwin`` an ``x86_64`` and
  ``aarch64-darwin`` an ``arm64`` image; each a 64-bit little-endian ``MH_DYLIB``;
* exports: the export trie (what dyld resolves against) names exactly the 34
  FMI 2.0 co-simulation functions, ``_fmi2…``, and the four functions beyond FMI,
  ``_stickslip_inverse_dynamics``, ``_stickslip_joint_torque_regressor``,
  ``_stickslip_run_experiment`` and ``_stickslip_write_model`` (``EXPORTED_FUNCTIONS`` of
  ``src/fmi/exports.rs``), respectively exactly the 75
  functions of the FMI 3.0 API, ``_fmi3…`` (``EXPORTED_FUNCTIONS`` of
  ``fmi3/src/lib.rs``), nothing else;
* imports: ``/usr/lib/libSystem.B.dylib`` only (no weak, lazy, re-exported or
  upward libraries), and no ``LC_RPATH``;
* install name (``LC_ID_DYLIB``): ``@rpath/StickSlipManipulator.dylib``, never
  a build path; no load command names a path of the build machine;
* minimum macOS (``LC_BUILD_VERSION`` or ``LC_VERSION_MIN_MACOSX``): at most
  10.13 for x86_64 and 11.0 for arm64 (platform macOS);
* signature: the arm64 slice has an ``LC_CODE_SIGNATURE`` whose blob is an
  ad-hoc CodeDirectory covering the slice up to the signature, and every page
  hash in it matches the slice's bytes (what the kernel checks page by page);
  an x86_64 signature, if any, must match too;
* stripped: no debug map (STABS) and no local symbols in the symbol table.

``scripts/build_fmu.sh`` builds darwin64 by default (``scripts/test.sh`` and so
CI with it). Without a darwin64 binary in the FMU (``STICKSLIP_DARWIN64=0``, or
``--platforms`` without darwin64) the tests skip with the reason, except in CI
(``CI=true``), where they fail: CI must not pass without having checked it. The
same holds for the FMI 3.0 FMU and its two darwin binaries.
"""

import hashlib
import os
import re
import struct
import zipfile

import pytest

from fmi3_slave import fmu3_path
from helpers import ROOT, fmu_path

# CI's full run only (scripts/test.sh --quick leaves it out): the darwin64 binary (not built by --quick)
pytestmark = pytest.mark.full

DYLIB = "binaries/darwin64/StickSlipManipulator.dylib"
INSTALL_NAME = "@rpath/StickSlipManipulator.dylib"
LIBSYSTEM = "/usr/lib/libSystem.B.dylib"

# FMI 2.0: the 25 functions common to both interface types and the 9 of co-simulation.
FMI2_CS_FUNCTIONS = """
GetTypesPlatform GetVersion SetDebugLogging Instantiate FreeInstance SetupExperiment
EnterInitializationMode ExitInitializationMode Terminate Reset GetReal GetInteger
GetBoolean GetString SetReal SetInteger SetBoolean SetString GetFMUstate SetFMUstate
FreeFMUstate SerializedFMUstateSize SerializeFMUstate DeSerializeFMUstate
GetDirectionalDerivative SetRealInputDerivatives GetRealOutputDerivatives DoStep
CancelStep GetStatus GetRealStatus GetIntegerStatus GetBooleanStatus GetStringStatus
""".split()
# Beyond FMI: the engine's inverse dynamics, for the fit's equation-error stage, its
# joint-torque regressor, and the model with identified values written as a model file.
BEYOND_FMI = {
    "_stickslip_inverse_dynamics",
    "_stickslip_joint_torque_regressor",
    "_stickslip_run_experiment",
    "_stickslip_write_model",
}
EXPECTED_EXPORTS = {"_fmi2" + f for f in FMI2_CS_FUNCTIONS} | BEYOND_FMI

# FMI 3.0: every function of the API (fmi3Functions.h), for all three interface types;
# the FMU provides co-simulation and answers the others with fmi3Error.
FMI3_DYLIBS = {
    "x86_64": "binaries/x86_64-darwin/StickSlipManipulator.dylib",
    "arm64": "binaries/aarch64-darwin/StickSlipManipulator.dylib",
}
FMI3_FUNCTIONS = """
GetVersion SetDebugLogging InstantiateModelExchange InstantiateCoSimulation InstantiateScheduledExecution
FreeInstance EnterInitializationMode ExitInitializationMode EnterEventMode Terminate Reset
GetFloat32 GetFloat64 GetInt8 GetUInt8 GetInt16 GetUInt16 GetInt32 GetUInt32 GetInt64 GetUInt64
GetBoolean GetString GetBinary GetClock
SetFloat32 SetFloat64 SetInt8 SetUInt8 SetInt16 SetUInt16 SetInt32 SetUInt32 SetInt64 SetUInt64
SetBoolean SetString SetBinary SetClock
GetNumberOfVariableDependencies GetVariableDependencies
GetFMUState SetFMUState FreeFMUState SerializedFMUStateSize SerializeFMUState DeserializeFMUState
GetDirectionalDerivative GetAdjointDerivative EnterConfigurationMode ExitConfigurationMode
GetIntervalDecimal GetIntervalFraction GetShiftDecimal GetShiftFraction
SetIntervalDecimal SetIntervalFraction SetShiftDecimal SetShiftFraction
EvaluateDiscreteStates UpdateDiscreteStates
EnterContinuousTimeMode CompletedIntegratorStep SetTime SetContinuousStates GetContinuousStateDerivatives
GetEventIndicators GetContinuousStates GetNominalsOfContinuousStates GetNumberOfEventIndicators
GetNumberOfContinuousStates
EnterStepMode GetOutputDerivatives DoStep
ActivateModelPartition
""".split()
EXPECTED_FMI3_EXPORTS = {"_fmi3" + f for f in FMI3_FUNCTIONS}

CPU_X86_64 = 0x01000007
CPU_ARM64 = 0x0100000C
ARCH_NAMES = {CPU_X86_64: "x86_64", CPU_ARM64: "arm64"}
MAX_MIN_OS = {"x86_64": (10, 13), "arm64": (11, 0)}

MH_MAGIC_64 = 0xFEEDFACF
MH_DYLIB = 6
LC_SYMTAB = 0x2
LC_LOAD_DYLIB = 0xC
LC_ID_DYLIB = 0xD
LC_LAZY_LOAD_DYLIB = 0x20
LC_CODE_SIGNATURE = 0x1D
LC_DYLD_INFO = 0x22
LC_VERSION_MIN_MACOSX = 0x24
LC_BUILD_VERSION = 0x32
LC_REQ_DYLD = 0x80000000
LC_LOAD_WEAK_DYLIB = 0x18 | LC_REQ_DYLD
LC_RPATH = 0x1C | LC_REQ_DYLD
LC_REEXPORT_DYLIB = 0x1F | LC_REQ_DYLD
LC_DYLD_INFO_ONLY = 0x22 | LC_REQ_DYLD
LC_LOAD_UPWARD_DYLIB = 0x23 | LC_REQ_DYLD
LC_DYLD_EXPORTS_TRIE = 0x33 | LC_REQ_DYLD
DYLIB_LOADS = {LC_LOAD_DYLIB, LC_LOAD_WEAK_DYLIB, LC_LAZY_LOAD_DYLIB, LC_REEXPORT_DYLIB, LC_LOAD_UPWARD_DYLIB}
PLATFORM_MACOS = 1

CSMAGIC_EMBEDDED_SIGNATURE = 0xFADE0CC0
CSMAGIC_CODEDIRECTORY = 0xFADE0C02
CSSLOT_CODEDIRECTORY = 0
CS_ADHOC = 0x2
CS_HASHTYPE_SHA1 = 1
CS_HASHTYPE_SHA256 = 2


def uleb(data: bytes, pos: int):
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, pos


def cstring(data: bytes, pos: int) -> str:
    end = data.index(b"\0", pos)
    return data[pos:end].decode()


def export_trie(trie: bytes) -> set:
    """The names of the export trie (dyld's view of what a dylib exports)."""
    names, stack, seen = set(), [(0, "")], set()
    while stack:
        node, prefix = stack.pop()
        assert node not in seen, "loop in the export trie"
        seen.add(node)
        terminal_size, pos = uleb(trie, node)
        if terminal_size:
            names.add(prefix)
        pos += terminal_size
        children = trie[pos]
        pos += 1
        for _ in range(children):
            end = trie.index(b"\0", pos)
            edge = trie[pos:end].decode()
            child, pos = uleb(trie, end + 1)
            stack.append((child, prefix + edge))
    return names


class Slice:
    """One thin 64-bit Mach-O image, parsed as far as the checks need."""

    def __init__(self, data: bytes):
        self.data = data
        magic, self.cputype, _, self.filetype, ncmds, _, _, _ = struct.unpack_from("<8I", data, 0)
        assert magic == MH_MAGIC_64, f"not a 64-bit little-endian Mach-O: magic {magic:#x}"
        self.arch = ARCH_NAMES.get(self.cputype, hex(self.cputype))
        self.commands = []  # (cmd, offset of the command, cmdsize)
        pos = 32
        for _ in range(ncmds):
            cmd, size = struct.unpack_from("<2I", data, pos)
            self.commands.append((cmd, pos, size))
            pos += size

    def of(self, kind):
        return [(off, size) for cmd, off, size in self.commands if cmd == kind]

    def dylib_name(self, off) -> str:
        (name_off,) = struct.unpack_from("<I", self.data, off + 8)
        return cstring(self.data, off + name_off)

    def install_names(self):
        return [self.dylib_name(off) for off, _ in self.of(LC_ID_DYLIB)]

    def imports(self):
        return [(cmd, self.dylib_name(off)) for cmd, off, _ in self.commands if cmd in DYLIB_LOADS]

    def exports(self) -> set:
        tries = []
        for off, _ in self.of(LC_DYLD_INFO) + self.of(LC_DYLD_INFO_ONLY):
            export_off, export_size = struct.unpack_from("<2I", self.data, off + 40)
            tries.append((export_off, export_size))
        for off, _ in self.of(LC_DYLD_EXPORTS_TRIE):
            tries.append(struct.unpack_from("<2I", self.data, off + 8))
        assert len(tries) == 1, f"{self.arch}: {len(tries)} export tries"
        start, size = tries[0]
        return export_trie(self.data[start : start + size]) if size else set()

    def min_os(self):
        """(platform, (major, minor)) of every version command."""
        found = []
        for off, _ in self.of(LC_BUILD_VERSION):
            platform, minos = struct.unpack_from("<2I", self.data, off + 8)
            found.append((platform, (minos >> 16, (minos >> 8) & 0xFF)))
        for off, _ in self.of(LC_VERSION_MIN_MACOSX):
            (version,) = struct.unpack_from("<I", self.data, off + 8)
            found.append((PLATFORM_MACOS, (version >> 16, (version >> 8) & 0xFF)))
        return found

    def symbols(self):
        """(name, n_type) of the symbol table."""
        out = []
        for off, _ in self.of(LC_SYMTAB):
            symoff, nsyms, stroff, _ = struct.unpack_from("<4I", self.data, off + 8)
            for i in range(nsyms):
                strx, ntype, _, _, _ = struct.unpack_from("<IBBHQ", self.data, symoff + 16 * i)
                out.append((cstring(self.data, stroff + strx), ntype))
        return out

    def code_directory(self):
        """The CodeDirectory of the embedded signature, or None without LC_CODE_SIGNATURE."""
        sigs = self.of(LC_CODE_SIGNATURE)
        if not sigs:
            return None
        assert len(sigs) == 1
        dataoff, datasize = struct.unpack_from("<2I", self.data, sigs[0][0] + 8)
        blob = self.data[dataoff : dataoff + datasize]
        magic, _, count = struct.unpack_from(">3I", blob, 0)
        assert magic == CSMAGIC_EMBEDDED_SIGNATURE, f"{self.arch}: signature magic {magic:#x}"
        index = [struct.unpack_from(">2I", blob, 12 + 8 * i) for i in range(count)]
        cds = [offset for slot, offset in index if slot == CSSLOT_CODEDIRECTORY]
        assert len(cds) == 1, f"{self.arch}: {len(cds)} code directories"
        cd = blob[cds[0] :]
        (
            magic,
            _length,
            version,
            flags,
            hash_offset,
            ident_offset,
            n_special,
            n_code,
            code_limit,
            hash_size,
            hash_type,
            _,
            page_log2,
        ) = struct.unpack_from(">7I2I4B", cd, 0)
        assert magic == CSMAGIC_CODEDIRECTORY, f"{self.arch}: code directory magic {magic:#x}"
        return {
            "dataoff": dataoff,
            "version": version,
            "flags": flags,
            "ident": cstring(cd, ident_offset),
            "n_special": n_special,
            "code_limit": code_limit,
            "hash_type": hash_type,
            "hash_size": hash_size,
            "page_size": 1 << page_log2 if page_log2 else 0,
            "hashes": [cd[hash_offset + i * hash_size : hash_offset + (i + 1) * hash_size] for i in range(n_code)],
        }


def slices(blob: bytes) -> list:
    """The slices of a universal (fat) Mach-O."""
    magic, n = struct.unpack_from(">2I", blob, 0)
    assert magic == 0xCAFEBABE, f"not a universal Mach-O (magic {magic:#x})"
    out = []
    for i in range(n):
        cputype, _, offset, size, align = struct.unpack_from(">5I", blob, 8 + 20 * i)
        assert offset % (1 << align) == 0 and offset + size <= len(blob)
        out.append((cputype, Slice(blob[offset : offset + size])))
    return out


def in_ci() -> bool:
    """CI (``CI=true``, as CI services set it): a missing darwin64 binary fails there."""
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes", "on")


def missing(reason: str):
    """Fail in CI, where scripts/test.sh builds darwin64; skip with the reason elsewhere."""
    if in_ci():
        pytest.fail(
            f"CI=true and {reason}: scripts/test.sh builds darwin64 by default "
            "(STICKSLIP_DARWIN64=0 is for developers only)"
        )
    pytest.skip(
        f"{reason}: built by `bash scripts/build_fmu.sh` unless STICKSLIP_DARWIN64=0 or --platforms leaves darwin64 out"
    )


@pytest.fixture(scope="module")
def darwin64():
    """The FMI 2.0 FMU's universal dylib: its slices by architecture."""
    path = fmu_path()
    if not path.is_file():
        missing(f"{path} does not exist")
    with zipfile.ZipFile(path) as zf:
        if DYLIB not in zf.namelist():
            missing(f"{path.name} has no {DYLIB}")
        blob = zf.read(DYLIB)
    return {ARCH_NAMES.get(cpu, hex(cpu)): s for cpu, s in slices(blob)}


@pytest.fixture(scope="module")
def darwin64_fmi3():
    """The FMI 3.0 FMU's two thin dylibs, by the architecture their folder names."""
    path = fmu3_path()
    if not path.is_file():
        missing(f"{path} does not exist")
    out = {}
    with zipfile.ZipFile(path) as zf:
        for arch, member in FMI3_DYLIBS.items():
            if member not in zf.namelist():
                missing(f"{path.name} has no {member}")
            blob = zf.read(member)
            (magic,) = struct.unpack_from(">I", blob, 0)
            assert magic != 0xCAFEBABE, f"{member} is a universal file, not a thin {arch} image"
            out[arch] = Slice(blob)
    return out


@pytest.fixture(scope="module", params=["fmi2", "fmi3"])
def library(request):
    """(images by architecture, the exports they must have) of each FMU's macOS binaries."""
    if request.param == "fmi2":
        return request.getfixturevalue("darwin64"), EXPECTED_EXPORTS
    return request.getfixturevalue("darwin64_fmi3"), EXPECTED_FMI3_EXPORTS


def test_universal_file_with_an_x86_64_and_an_arm64_dylib(darwin64):
    assert sorted(darwin64) == ["arm64", "x86_64"]
    for arch, s in darwin64.items():
        assert s.arch == arch, "the fat header's CPU type differs from the slice's"
        assert s.filetype == MH_DYLIB, f"{arch}: file type {s.filetype}, not MH_DYLIB"


def test_fmi3_thin_dylibs_one_architecture_each(darwin64_fmi3):
    """x86_64-darwin holds an x86_64 image, aarch64-darwin an arm64 one (thin files)."""
    assert sorted(darwin64_fmi3) == ["arm64", "x86_64"]
    for arch, s in darwin64_fmi3.items():
        assert s.arch == arch, f"{FMI3_DYLIBS[arch]}: CPU type {s.arch}"
        assert s.filetype == MH_DYLIB, f"{arch}: file type {s.filetype}, not MH_DYLIB"


def _exported_functions(path: str, name: str, count: int) -> set:
    """The Mach-O symbol names (a leading underscore) of the EXPORTED_FUNCTIONS array in the
    Rust source ``path``, whose length and entries must both be ``count``."""
    source = (ROOT / path).read_text()
    block = re.search(r"EXPORTED_FUNCTIONS: \[&str; (\d+)\] = \[(.*?)\];", source, re.S)
    assert block, f"EXPORTED_FUNCTIONS not found in {path}"
    names = re.findall(f'"({name})"', block.group(2))
    assert len(names) == int(block.group(1)) == count
    return {"_" + n for n in names}


def test_fmi2_function_list_is_the_librarys():
    """The 34 FMI 2.0 names above and the four beyond FMI are src/fmi/exports.rs's
    EXPORTED_FUNCTIONS (what build_fmu.sh checks)."""
    assert _exported_functions("src/fmi/exports.rs", r"\w+", 38) == EXPECTED_EXPORTS


def test_exports_exactly_the_34_fmi2_functions_and_the_four_beyond_fmi(darwin64):
    assert len(EXPECTED_EXPORTS) == 38
    for arch, s in darwin64.items():
        exports = s.exports()
        assert exports == EXPECTED_EXPORTS, (
            f"{arch}: {len(exports)} exports; extra {sorted(exports - EXPECTED_EXPORTS)[:20]}, "
            f"missing {sorted(EXPECTED_EXPORTS - exports)}"
        )


def test_fmi3_function_list_is_the_librarys():
    """The 75 names above are fmi3/src/lib.rs's EXPORTED_FUNCTIONS (what build_fmu.sh checks)."""
    assert _exported_functions("fmi3/src/lib.rs", r"fmi3\w+", 75) == EXPECTED_FMI3_EXPORTS


def test_exports_exactly_the_75_fmi3_functions(darwin64_fmi3):
    assert len(EXPECTED_FMI3_EXPORTS) == 75
    for arch, s in darwin64_fmi3.items():
        exports = s.exports()
        assert exports == EXPECTED_FMI3_EXPORTS, (
            f"{arch}: {len(exports)} exports; extra {sorted(exports - EXPECTED_FMI3_EXPORTS)[:20]}, "
            f"missing {sorted(EXPECTED_FMI3_EXPORTS - exports)}"
        )


def test_imports_only_libsystem(library):
    images, _ = library
    for arch, s in images.items():
        assert s.imports() == [(LC_LOAD_DYLIB, LIBSYSTEM)], f"{arch}: {s.imports()}"
        assert not s.of(LC_RPATH), f"{arch}: has LC_RPATH"


def test_install_name_is_relative(library):
    images, _ = library
    for arch, s in images.items():
        assert s.install_names() == [INSTALL_NAME], f"{arch}: {s.install_names()}"
        for cmd, off, size in s.commands:
            text = s.data[off : off + size]
            for build_path in (b"/work/", b"/tmp/", b"/root/", b"target/"):
                assert build_path not in text, f"{arch}: load command {cmd:#x} names {text!r}"


def test_minimum_macos(library):
    images, _ = library
    for arch, s in images.items():
        versions = s.min_os()
        assert len(versions) == 1, f"{arch}: {versions}"
        platform, minos = versions[0]
        assert platform == PLATFORM_MACOS, f"{arch}: platform {platform}"
        assert minos <= MAX_MIN_OS[arch], f"{arch}: needs macOS {minos}, at most {MAX_MIN_OS[arch]} wanted"


def check_signature(arch, s, cd):
    assert cd["hash_type"] in (CS_HASHTYPE_SHA1, CS_HASHTYPE_SHA256), f"{arch}: hash type {cd['hash_type']}"
    digest = hashlib.sha256 if cd["hash_type"] == CS_HASHTYPE_SHA256 else hashlib.sha1
    assert cd["hash_size"] == digest().digest_size
    assert cd["page_size"] == 4096, f"{arch}: page size {cd['page_size']}"
    # The signature covers the whole image up to the signature itself.
    assert cd["code_limit"] == cd["dataoff"], f"{arch}: code limit {cd['code_limit']} != {cd['dataoff']}"
    page = cd["page_size"]
    assert len(cd["hashes"]) == -(-cd["code_limit"] // page)
    for i, expected in enumerate(cd["hashes"]):
        chunk = s.data[i * page : min((i + 1) * page, cd["code_limit"])]
        assert digest(chunk).digest() == expected, f"{arch}: page {i} does not match its hash"


def test_arm64_slice_is_ad_hoc_signed_and_the_hashes_match(library):
    images, _ = library
    arm = images["arm64"]
    cd = arm.code_directory()
    assert cd is not None, "arm64: no LC_CODE_SIGNATURE (Apple silicon refuses unsigned arm64 code)"
    assert cd["flags"] & CS_ADHOC, f"arm64: CodeDirectory flags {cd['flags']:#x}, not ad hoc"
    assert cd["ident"], "arm64: empty signing identifier"
    check_signature("arm64", arm, cd)
    x86 = images["x86_64"]
    cd = x86.code_directory()
    if cd is not None:
        check_signature("x86_64", x86, cd)


def test_stripped(library):
    images, expected_exports = library
    N_STAB, N_EXT, N_TYPE, N_UNDF = 0xE0, 0x01, 0x0E, 0x0
    for arch, s in images.items():
        symbols = s.symbols()
        stabs = [name for name, t in symbols if t & N_STAB]
        local = [name for name, t in symbols if not t & N_STAB and not t & N_EXT]
        assert not stabs, f"{arch}: {len(stabs)} debug (STAB) symbols, e.g. {stabs[:5]}"
        assert not local, f"{arch}: {len(local)} local symbols, e.g. {local[:5]}"
        defined = {name for name, t in symbols if t & N_EXT and (t & N_TYPE) != N_UNDF}
        assert defined <= expected_exports, f"{arch}: global symbols {sorted(defined - expected_exports)[:10]}"
