"""The FMU of a URDF arm for the FMU tests: the KUKA LBR iiwa of models/urdf/kuka_iiwa
(7 revolute joints, flexible drives with bearing friction on joints 1, 2 and 4), built once
per process with ``bash scripts/build_fmu.sh --model models/urdf/kuka_iiwa/kuka_iiwa.toml
--out <scratch>/iiwa.fmu`` for the platforms of the FMU under test (linux64, and win64 when
it carries one; darwin64 is left to test_darwin64.py). After scripts/test.sh's own
build_fmu.sh stage the cargo builds in it do nothing, and the whole build takes a few
seconds. ``$STICKSLIP_URDF_FMU`` names a prebuilt one instead.

Used by test_urdf_fmu.py, and by test_ranges.py and test_fuzz.py, which run their checks
against it as well as against the reference FMU.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import time
import zipfile
from pathlib import Path

from helpers import ROOT, fmu_path, require_fmu, scratch_dir

IIWA_MODEL = ROOT / "models" / "urdf" / "kuka_iiwa" / "kuka_iiwa.toml"
IIWA_URDF = ROOT / "models" / "urdf" / "kuka_iiwa" / "kuka_iiwa.urdf"
IIWA_JOINTS = [f"lbr_iiwa_joint_{i}" for i in range(1, 8)]
# The build's wall time, for the test report.
BUILD_SECONDS = {}


def _platforms_under_test() -> str:
    """linux64, plus win64 when the FMU under test has a win64 binary."""
    with zipfile.ZipFile(fmu_path()) as z:
        names = z.namelist()
    return "linux64,win64" if any(n.startswith("binaries/win64/") for n in names) else "linux64"


@functools.cache
def model_fmu(key: str, model: Path, env: str) -> Path:
    """The FMU of model file `model`, built on first use into the scratch directory as
    `<key>.fmu` for the platforms under test (RuntimeError with build_fmu.sh's output if the
    build fails); `$<env>` may name a prebuilt one."""
    prebuilt = os.environ.get(env)
    if prebuilt:
        return Path(prebuilt).resolve()
    out = scratch_dir() / f"{key}.fmu"
    cmd = [
        "bash",
        "scripts/build_fmu.sh",
        "--platforms",
        _platforms_under_test(),
        "--model",
        str(model),
        "--out",
        str(out),
    ]
    started = time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    BUILD_SECONDS[key] = time.perf_counter() - started
    if r.returncode != 0 or not out.is_file():
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {r.returncode}):\n{r.stdout[-4000:]}")
    return out


def iiwa_fmu() -> Path:
    """The iiwa FMU's path, built on first use."""
    return model_fmu("iiwa", IIWA_MODEL, "STICKSLIP_URDF_FMU")


def require_iiwa_fmu() -> Path:
    """The iiwa FMU; skips the calling test when the FMU under test is not built (as
    helpers.require_fmu does), builds it otherwise."""
    require_fmu()
    return iiwa_fmu()


def rezip(src: Path, dst: Path, replace: dict | None = None, remove=()) -> Path:
    """A copy of the FMU ``src`` at ``dst`` with some entries' bytes replaced and some
    removed (the modelDescription, and so the GUID, kept)."""
    replace = replace or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            if info.filename in remove:
                continue
            data = replace.get(info.filename, None)
            zout.writestr(info, zin.read(info.filename) if data is None else data)
    return dst


def copy_tree(src: Path, dst: Path) -> Path:
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(src, dst)
    return dst
