"""scripts/target-seed.sh: a fresh clone's target/release (and target/fmi2, the FMI 2.0
library's profile) starts from the last full run's, without the workspace's own packages'
fingerprints (so cargo compiles those from the clone's sources), and the seed is keyed by
the toolchain and both Cargo.lock files.

Run on a made-up target dir in a scratch cache: the script's bash functions, as
scripts/test.sh calls them, in a copy of the files the key is made of."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest

from helpers import ROOT

SCRIPT = ROOT / "scripts" / "target-seed.sh"
WORKSPACE_UNITS = ("stick_slip_manipulator-0a1b", "stick_slip_manipulator_fmi3-2c3d", "stickslip-win64-tests-4e5f")
DEPENDENCY_UNITS = ("nalgebra-1234", "zstd-sys-5678")


def run(clone, cache, *calls: str) -> subprocess.CompletedProcess:
    script = f"set -euo pipefail\nsource {SCRIPT}\n" + "\n".join(calls)
    env_vars = {"STICKSLIP_CACHE_DIR": str(cache), "PATH": os.environ["PATH"]}
    return subprocess.run(["bash", "-c", script], cwd=clone, env=env_vars, capture_output=True, text=True)


@pytest.fixture
def clone(tmp_path):
    """A directory with the two Cargo.lock files and a target/release of the workspace's
    units and two dependencies' units."""
    c = tmp_path / "clone"
    (c / "tests" / "win64").mkdir(parents=True)
    shutil.copy(ROOT / "Cargo.lock", c / "Cargo.lock")
    shutil.copy(ROOT / "tests" / "win64" / "Cargo.lock", c / "tests" / "win64" / "Cargo.lock")
    release = c / "target" / "release"
    for unit in WORKSPACE_UNITS + DEPENDENCY_UNITS:
        (release / ".fingerprint" / unit).mkdir(parents=True)
        (release / ".fingerprint" / unit / "lib").write_text("fingerprint")
    (release / "deps").mkdir()
    (release / "deps" / "libnalgebra-1234.rlib").write_bytes(b"rlib")
    return c


def test_the_seed_keeps_the_dependencies_and_forgets_the_workspace(clone, tmp_path):
    cache = tmp_path / "cache"
    p = run(clone, cache, 'target_seed_save "$PWD/target"')
    assert p.returncode == 0, p.stderr
    (seed,) = [d for d in (cache / "target-seed").iterdir() if d.is_dir()]
    fingerprints = {d.name for d in (seed / "release" / ".fingerprint").iterdir()}
    assert fingerprints == set(DEPENDENCY_UNITS)
    assert (seed / "release" / "deps" / "libnalgebra-1234.rlib").read_bytes() == b"rlib"

    # A fresh clone (no target/release) gets the seed; the workspace's units are not in it.
    fresh = tmp_path / "fresh"
    shutil.copytree(clone, fresh, ignore=shutil.ignore_patterns("target"))
    p = run(fresh, cache, 'target_seed_restore "$PWD/target"')
    assert p.returncode == 0, p.stderr
    assert "target-seed:" in p.stdout
    restored = {d.name for d in (fresh / "target" / "release" / ".fingerprint").iterdir()}
    assert restored == set(DEPENDENCY_UNITS)
    assert (fresh / "target" / "release" / "deps" / "libnalgebra-1234.rlib").read_bytes() == b"rlib"


def test_the_fmi2_profile_directory_is_seeded_too(clone, tmp_path):
    """target/fmi2 (scripts/build_fmu.sh's FMI 2.0 library) is saved and restored like
    target/release, each on its own: a clone that has release/ but not fmi2/ gets fmi2/."""
    fmi2 = clone / "target" / "fmi2"
    for unit in WORKSPACE_UNITS[:1] + DEPENDENCY_UNITS:
        (fmi2 / ".fingerprint" / unit).mkdir(parents=True)
    cache = tmp_path / "cache"
    p = run(clone, cache, 'target_seed_save "$PWD/target"')
    assert p.returncode == 0 and "saved fmi2 release of" in p.stdout, p.stdout + p.stderr
    shutil.rmtree(fmi2)
    (clone / "target" / "release" / "mine").write_text("kept")
    p = run(clone, cache, 'target_seed_restore "$PWD/target"')
    assert p.returncode == 0 and "target/fmi2 from" in p.stdout and "target/release" not in p.stdout, p.stdout
    assert {d.name for d in (fmi2 / ".fingerprint").iterdir()} == set(DEPENDENCY_UNITS)
    assert (clone / "target" / "release" / "mine").read_text() == "kept"


def test_a_clone_with_a_target_dir_keeps_its_own(clone, tmp_path):
    cache = tmp_path / "cache"
    assert run(clone, cache, 'target_seed_save "$PWD/target"').returncode == 0
    (clone / "target" / "release" / "mine").write_text("kept")
    p = run(clone, cache, 'target_seed_restore "$PWD/target"')
    assert p.returncode == 0 and p.stdout == "", p.stdout + p.stderr
    assert (clone / "target" / "release" / "mine").read_text() == "kept"
    # and its workspace fingerprints stay: restoring touches nothing there
    assert (clone / "target" / "release" / ".fingerprint" / WORKSPACE_UNITS[0]).is_dir()


def test_another_cargo_lock_is_another_seed(clone, tmp_path):
    cache = tmp_path / "cache"
    assert run(clone, cache, 'target_seed_save "$PWD/target"').returncode == 0
    with open(clone / "Cargo.lock", "a") as f:
        f.write("\n# another dependency version\n")
    fresh = tmp_path / "fresh"
    shutil.copytree(clone, fresh, ignore=shutil.ignore_patterns("target"))
    p = run(fresh, cache, 'target_seed_restore "$PWD/target"')
    assert p.returncode == 0 and p.stdout == "", p.stdout + p.stderr
    assert not (fresh / "target" / "release").exists()
    # Saving it too: the two newest seeds are kept, a third removes the oldest.
    assert run(clone, cache, 'target_seed_save "$PWD/target"').returncode == 0
    with open(clone / "Cargo.lock", "a") as f:
        f.write("# and another\n")
    assert run(clone, cache, 'target_seed_save "$PWD/target"').returncode == 0
    assert len([d for d in (cache / "target-seed").iterdir() if d.is_dir()]) == 2


def test_switched_off(clone, tmp_path):
    cache = tmp_path / "cache"
    p = run(clone, cache, 'STICKSLIP_TARGET_SEED=0 target_seed_save "$PWD/target"')
    assert p.returncode == 0 and not (cache / "target-seed").exists()
