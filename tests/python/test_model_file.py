"""The identified model written back (python/stickslip/identify/model_file.py, issue 42, item 4):
the FMU's model with identified link inertias π and settings, written by the engine in the FMU's
own binary as a model file (and URDF), is the model the identification meant.

* unchanged, the written model file gives the FMU's inverse dynamics and lever loads bit for bit;
* with random physically valid π and settings of friction and drive parameters, the written
  model's inverse dynamics are Y·π of the FMU's regressor at random states (1e-12 of the largest
  |τ|), the file holds the settings' values, and its header names what changed;
* a physically impossible link is refused naming it; a name that is not a plain file name too;
* (full) the FMU that ``scripts/build_fmu.sh --model`` builds from the written files, for the
  reference arm (Denavit-Hartenberg) and the KUKA iiwa (URDF): its regressor's π is the written
  π (1e-14 of each link's mass, first moment and inertia), its tunable parameters start at the
  written values (fmpy's modelDescription), and ``stickslip simulate --motion`` runs it.
"""

from __future__ import annotations

import os
import re
import subprocess
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT, require_fmu, scratch_dir, unzip_dir
from stickslip import cli
from stickslip.fit import idim
from stickslip.fit.regressor import joint_torque_regressor
from stickslip.identify.model_file import write_model

SEED = 42
# Each link's standard parameters by kind, for the scale of a comparison of π.
KINDS = ([0], [1, 2, 3], [4, 5, 6, 7, 8, 9])
SETTINGS = ("mu_k[1]=0.03", "mu_s[1]=0.05", "b_v[1]=0.4", "k[3]=900000.0", "h[3]=2.5", "d_A[1]=0.12")


def random_states(n: int, rows: int, rng) -> np.ndarray:
    return np.hstack(
        [rng.uniform(-1.5, 1.5, (rows, n)), rng.uniform(-2, 2, (rows, n)), rng.uniform(-20, 20, (rows, n))]
    )


def random_pi(pi0: np.ndarray, rng) -> np.ndarray:
    """Physically valid standard parameters near ``pi0``: per link the mass within ±20 %, the centre
    of mass moved by up to 2 cm, the inertia about it that of a box of random sides and orientation."""
    pi = []
    for block in pi0.reshape(-1, 10):
        m = block[0] * rng.uniform(0.8, 1.2)
        c = block[1:4] / block[0] + rng.uniform(-0.02, 0.02, 3)
        a, b, d = rng.uniform(0.05, 0.4, 3)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        inertia = q @ np.diag([b * b + d * d, a * a + d * d, a * a + b * b]) * (m / 12) @ q.T
        origin = inertia + m * (c @ c * np.eye(3) - np.outer(c, c))
        pi.append([m, *(m * c), origin[0, 0], origin[0, 1], origin[1, 1], origin[0, 2], origin[1, 2], origin[2, 2]])
    return np.array(pi).ravel()


def pi_deviation(expected: np.ndarray, actual: np.ndarray) -> float:
    """The largest deviation per link relative to the largest magnitude of its kind."""
    worst = 0.0
    for a, b in zip(expected.reshape(-1, 10), actual.reshape(-1, 10), strict=True):
        for kind in KINDS:
            worst = max(worst, float(np.max(np.abs(a[kind] - b[kind])) / np.max(np.abs(a[kind]))))
    return worst


def test_the_unchanged_model_gives_the_fmus_numbers(tmp_path):
    unzipdir = unzip_dir(require_fmu())
    toml, urdf = write_model(unzipdir, tmp_path, name="same")
    assert (toml.name, urdf) == ("same.toml", None)
    text = toml.read_text(encoding="utf-8")
    assert "# Nothing changed" in text, text
    states = random_states(4, 50, np.random.default_rng(SEED))
    tau, load = idim.inverse_dynamics(unzipdir, states)
    tau_w, load_w = idim.inverse_dynamics(unzipdir, states, source=(text, None))
    assert np.array_equal(tau, tau_w) and np.array_equal(load, load_w, equal_nan=True)


def test_identified_pi_and_settings_are_written(tmp_path):
    unzipdir = unzip_dir(require_fmu())
    rng = np.random.default_rng(SEED)
    states = random_states(4, 200, rng)
    y, pi0, _ = joint_torque_regressor(unzipdir, states)
    pi = random_pi(pi0, rng)
    toml, _ = write_model(unzipdir, tmp_path, pi=pi, settings=SETTINGS)
    text = toml.read_text(encoding="utf-8")
    tau, _ = idim.inverse_dynamics(unzipdir, states, source=(text, None))
    expected = np.einsum("rik,k->ri", y, pi)
    deviation = float(np.max(np.abs(tau - expected) / np.max(np.abs(expected), axis=0)))
    print(f"τ of the written model against Y·π: {deviation:.1e} of the joint's largest |τ|")
    assert deviation <= 1e-12
    joints = tomllib.loads(text)["joint"]
    friction, drive = joints[0]["friction"], joints[2]["drive"]
    assert (friction["mu_k"], friction["mu_s"], friction["viscous"]) == (0.03, 0.05, 0.4)
    assert (drive["k"], drive["h"], joints[0]["bearings"]["d_a"]) == (900000.0, 2.5, 0.12)
    header = text[: text.index("\nname = ")]
    for line in ("link 1: m 25.0 -> ", "mu_k[1]: 0.2 -> 0.03", "k[3]: 1000000.0 -> 900000.0"):
        assert line in header, header


def test_an_impossible_link_or_name_is_refused(tmp_path):
    unzipdir = unzip_dir(require_fmu())
    _, pi, _ = joint_torque_regressor(unzipdir, np.zeros((0, 12)))
    pi[14] += 10.0  # link 2's I_xx beyond I_yy + I_zz about its centre of mass
    with pytest.raises(idim.InverseDynamicsError, match=r"joint\[2\]\.link\.inertia.*triangle inequality"):
        write_model(unzipdir, tmp_path, pi=pi)
    with pytest.raises(idim.InverseDynamicsError, match=r"n_parameters = 39"):
        write_model(unzipdir, tmp_path, pi=pi[:39])
    with pytest.raises(idim.InverseDynamicsError, match=r"no parameter is named `nonsense`"):
        write_model(unzipdir, tmp_path, settings=("nonsense[1]=2",))
    for name in ("", "..", "sub/identified"):
        with pytest.raises(ValueError, match="plain file name"):
            write_model(unzipdir, tmp_path, name=name)
    assert not list(tmp_path.iterdir()), "nothing written"


# ---------------------------------------------------------------------------
# the identified FMU (CI's full run: each builds an FMU)


def build_fmu(model: Path, out: Path) -> Path:
    """``bash scripts/build_fmu.sh --platforms linux64 --model <model> --out <out>``."""
    cmd = ["bash", "scripts/build_fmu.sh", "--platforms", "linux64", "--model", str(model), "--out", str(out)]
    started = time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert r.returncode == 0 and out.is_file(), f"{' '.join(cmd)} failed (exit {r.returncode}):\n{r.stdout[-4000:]}"
    print(f"{out.name} built in {time.perf_counter() - started:.1f} s")
    return out


# Per arm: its motion file (examples/motions) and the settings written.
ARMS = {
    "reference": ("reference.toml", SETTINGS),
    "kuka_iiwa": ("kuka_iiwa.toml", ("mu_k[2]=0.025", "b_v[4]=0.3", "k[1]=50000.0", "h[2]=20.0")),
}


def arm_fmu(arm: str) -> Path:
    """The arm's FMU: the FMU under test, or the iiwa's built from it (urdf_fmus.py)."""
    if arm == "kuka_iiwa":
        from urdf_fmus import require_iiwa_fmu

        return require_iiwa_fmu()
    return require_fmu()


def joints(unzipdir) -> int:
    """The FMU's number of joints: its outputs q[i]."""
    from fmpy import read_model_description

    return sum(1 for v in read_model_description(unzipdir).modelVariables if re.fullmatch(r"q\[\d+\]", v.name))


@pytest.mark.full
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_the_identified_fmu_holds_the_written_values(arm):
    from fmpy import extract, read_model_description

    motion, settings = ARMS[arm]
    unzipdir = unzip_dir(arm_fmu(arm))
    _, pi0, _ = joint_torque_regressor(unzipdir, np.zeros((0, 3 * joints(unzipdir))))
    pi = random_pi(pi0, np.random.default_rng(SEED))
    out = scratch_dir() / f"identified-{arm}-{os.getpid()}"
    toml, urdf = write_model(unzipdir, out, pi=pi, settings=settings)
    assert (urdf is None) == (arm == "reference")
    new = build_fmu(toml, out / "identified.fmu")
    new_dir = extract(str(new), unzipdir=str(out / "fmu"))
    _, pi_new, _ = joint_torque_regressor(new_dir, np.zeros((0, 3 * len(pi) // 10)))
    deviation = pi_deviation(pi, pi_new)
    print(f"{arm}: π of the identified FMU off by {deviation:.1e}")
    assert deviation <= 1e-14
    start = {v.name: v.start for v in read_model_description(str(new)).modelVariables}
    for setting in settings:
        name, value = setting.split("=")
        assert float(start[name]) == float(value), (name, start[name])
    csv = out / "run.csv"
    args = ["simulate", "--fmu", str(new), "--motion", str(ROOT / "examples" / "motions" / motion)]
    assert cli.main([*args, "--end", "0.05", "--out", str(csv)]) == 0
    assert csv.is_file()
