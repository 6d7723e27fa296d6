"""The FMI 2.0 libraries hold no FMI 3.0 code (issue 37, item 3).

``scripts/build_fmu.sh`` builds the FMI 2.0 library of every platform without the engine
crate's feature ``fmi3`` (``cargo build --profile fmi2 --no-default-features``): the FMI 3.0
layer (``src/fmi3``, the FMI 3.0 modelDescription writer, the logger's FMI 3.0 sink, the
engine's sub-step observer) is not compiled into it. Compiled in, even where nothing of the
FMI 2.0 library calls it, it made the linux64 library 3.5 % larger (1,587,624 against
1,534,136 bytes stripped): the exception tables of the unreached functions stay, the
logger's FMI 3.0 sink is reachable, and the rest of the crate is split into codegen units
and inlined differently (docs/platforms.md, "The FMI 2.0 library without the FMI 3.0 layer").

Every piece of the FMI 3.0 layer names FMI 3.0 functions in its messages (``fmi3DoStep``,
``fmi3SetFloat64`` in ``in_fmi3_terms``' table, the modes' "illegal call sequence" texts),
so the check is that no byte sequence ``fmi3`` occurs in the shipped FMI 2.0 binaries:
``binaries/linux64/StickSlipManipulator.so``, ``binaries/win64/StickSlipManipulator.dll`` and
both slices of ``binaries/darwin64/StickSlipManipulator.dylib``. That the text is there when
the layer is compiled in is checked on the FMI 3.0 FMU's libraries, built from the same
crate with it. A binary missing from the FMU (``--platforms`` without win64 or darwin64) is
a skip, except under ``CI=true``, where scripts/test.sh builds all three.
"""

import os
import zipfile

import pytest

from fmi3_slave import fmu3_path
from helpers import fmu_path

FMI2_BINARIES = {
    "linux64": "binaries/linux64/StickSlipManipulator.so",
    "win64": "binaries/win64/StickSlipManipulator.dll",
    "darwin64": "binaries/darwin64/StickSlipManipulator.dylib",
}
FMI3_BINARIES = {
    "linux64": "binaries/x86_64-linux/StickSlipManipulator.so",
    "win64": "binaries/x86_64-windows/StickSlipManipulator.dll",
    "darwin64": "binaries/x86_64-darwin/StickSlipManipulator.dylib",
}
FMI3_TEXT = b"fmi3"


def in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes", "on")


def binary(fmu, member: str) -> bytes:
    """The FMU's file ``member``; a skip (a failure under CI=true) if it is not there."""
    reason = None
    if not fmu.is_file():
        reason = f"{fmu} does not exist: build it with `bash scripts/build_fmu.sh`"
    else:
        with zipfile.ZipFile(fmu) as z:
            if member in z.namelist():
                return z.read(member)
        reason = f"{fmu.name} has no {member} (scripts/build_fmu.sh --platforms)"
    if in_ci():
        pytest.fail(f"CI=true and {reason}: scripts/test.sh builds linux64, win64 and darwin64")
    pytest.skip(reason)


@pytest.mark.parametrize("platform", FMI2_BINARIES)
def test_the_fmi2_library_holds_no_fmi3_code(platform):
    data = binary(fmu_path(), FMI2_BINARIES[platform])
    at = data.find(FMI3_TEXT)
    context = data[max(0, at - 40) : at + 40] if at >= 0 else b""
    print(f"{platform}: {FMI2_BINARIES[platform]}, {len(data):,} bytes, 'fmi3' {data.count(FMI3_TEXT)} times")
    assert at < 0, f"{FMI2_BINARIES[platform]} holds FMI 3.0 text at byte {at}: {context!r}"


@pytest.mark.parametrize("platform", FMI3_BINARIES)
def test_the_fmi3_library_of_the_same_crate_holds_that_text(platform):
    """The check above can fail: the FMI 3.0 library, the same engine crate with the
    feature ``fmi3``, holds its messages (and, on linux64 and win64, its export names)."""
    data = binary(fmu3_path(), FMI3_BINARIES[platform])
    assert data.count(FMI3_TEXT) > 20, platform
