"""The identification example's torque logs (docs/calibration.md, "Real arms"), made exactly so:

* **The true arm** (truth.toml): the KUKA iiwa of models/urdf/kuka_iiwa with the URDF's links,
  rigid (position-controlled) drives on all seven joints, and joint friction the catalogue does
  not know: the study's dry friction μ_k·L from the joint reactions through each joint's
  bearings, plus viscous b_v·q̇ (TRUE_FRICTION). Its FMU is built from truth.toml
  (scripts/build_fmu.sh --platforms linux64) into a scratch directory.
* **The catalogue arm** (catalogue.toml, catalogue_kuka_iiwa.urdf): the same URDF with every
  link's mass, centre of mass and principal moments multiplied by 1 + u, u uniform in
  [−0.3, 0.3] (seed CATALOGUE_SEED; a principal moment above the sum of the other two is lowered
  to 0.99 of it, so that the catalogue is still a physical body); friction a datasheet guess.
* **The motions**: two excitation trajectories designed on the catalogue arm, as a user does
  before logging (``stickslip excite --fmu target/fmu/iiwa_catalogue.fmu --out DIR --seed S
  --starts 4``: five harmonics, period 10 s, |q̇| ≤ 1 rad/s, |q̈| ≤ 3 rad/s², within the URDF's
  limits; seeds 1 and 2; their coefficients committed as excitation_1.json, excitation_2.json;
  ``--design`` designs them again), two periods each (train_1, train_2); and two held-out runs of another kind
  (heldout_1, heldout_2): point-to-point cycloids between seeded random poses within 60 % of
  each joint's range, 1.2–2 s each with 0.3 s dwells, 12 s in all.
* **The logs**: the true FMU follows each motion (its rigid drives are the position controller),
  stepped every STEP = 0.5 ms and sampled every SAMPLE = 4 ms; the link encoders q[i] rounded
  to a 20-bit count (2π/2^20 rad); the joint torques F_drive[i] with white noise of
  TORQUE_NOISE = 0.5 % of the joint's largest |τ| over that run (seeded per run), written to 9
  significant digits.

``python examples/identification/make_data.py [--design]`` writes the committed CSVs and the
catalogue URDF (tests/python/test_identification_example.py checks they are reproduced byte for
byte from the committed excitation_*.json).
"""

from __future__ import annotations

import itertools
import math
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
URDF = ROOT / "models/urdf/kuka_iiwa/kuka_iiwa.urdf"
N = 7
SAMPLE = 4e-3  # s, the log's sample interval
STEP = 5e-4  # s, the FMU's communication step while it makes the logs
COUNT = 2 * math.pi / 2**20
TORQUE_NOISE = 0.005
CATALOGUE_SEED = 42
SPREAD = 0.3
# per joint (mu_k, b_v): what truth.toml holds
TRUE_FRICTION = {
    1: (0.08, 1.2),
    2: (0.07, 1.0),
    3: (0.06, 0.8),
    4: (0.06, 0.6),
    5: (0.05, 0.3),
    6: (0.05, 0.25),
    7: (0.04, 0.2),
}
EXCITATION = {"train_1": 1, "train_2": 2}  # run -> design seed
HELDOUT = {"heldout_1": 11, "heldout_2": 12}  # run -> pose seed
PERIODS = 2


def catalogue_urdf(text: str, seed: int = CATALOGUE_SEED) -> str:
    """The URDF text with every link's <inertial> perturbed as the module says."""
    rng = np.random.default_rng(seed)

    def perturb(match):
        block = match.group(0)
        mass = float(re.search(r'<mass value="([^"]+)"', block).group(1))
        if mass == 0.0:
            return block
        xyz = np.array(re.search(r'<origin[^>]*xyz="([^"]+)"', block).group(1).split(), dtype=float)
        moments = np.array([float(re.search(f'{k}="([^"]+)"', block).group(1)) for k in ("ixx", "iyy", "izz")])
        mass *= 1 + SPREAD * rng.uniform(-1, 1)
        xyz = xyz * (1 + SPREAD * rng.uniform(-1, 1, 3))
        moments = moments * (1 + SPREAD * rng.uniform(-1, 1, 3))
        moments = np.minimum(moments, 0.99 * (moments.sum() - moments))
        block = re.sub(r'<mass value="[^"]+"', f'<mass value="{mass:.6g}"', block)
        block = re.sub(
            r'(<origin[^>]*xyz=")[^"]+"', lambda m: m.group(1) + " ".join(f"{x:.6g}" for x in xyz) + '"', block
        )
        for k, v in zip(("ixx", "iyy", "izz"), moments, strict=True):
            block = re.sub(f'{k}="[^"]+"', f'{k}="{v:.6g}"', block)
        return block

    return re.sub(r"<inertial>.*?</inertial>", perturb, text, flags=re.S)


def build(model: Path, out: Path) -> Path:
    """The linux64 FMU of ``model`` (scripts/build_fmu.sh)."""
    done = subprocess.run(
        [
            "bash",
            str(ROOT / "scripts/build_fmu.sh"),
            "--platforms",
            "linux64",
            "--model",
            str(model),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise RuntimeError(f"build_fmu.sh {model.name} failed:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    return out


def design(catalogue_fmu: Path, seed: int) -> None:
    """excitation_<seed>.json: the excitation trajectory of ``seed`` designed on the catalogue
    arm by the command a user runs."""
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "stickslip.cli", "excite", "--fmu", str(catalogue_fmu), "--out", out]
        subprocess.run([*command, "--seed", str(seed), "--starts", "4"], check=True)
        (HERE / f"excitation_{seed}.json").write_text((Path(out) / "excitation.json").read_text())


def excitation(seed: int):
    """The excitation trajectory of excitation_<seed>.json (a Fourier)."""
    import json

    from stickslip.identify.excitation import Fourier

    doc = json.loads((HERE / f"excitation_{seed}.json").read_text())
    return Fourier(doc["period_s"], *(np.array(doc[k], dtype=np.float64) for k in ("q0", "a", "b")))


def point_to_point(seed: int, limits):
    """(motion(t, step), duration): cycloids between seeded random poses within 60 % of each
    joint's range, with dwells."""
    rng = np.random.default_rng(seed)
    middle, half = 0.5 * (limits[0] + limits[1]), 0.3 * (limits[1] - limits[0])
    poses = [middle + half * rng.uniform(-1, 1, N) for _ in range(8)]
    moves, t = [], 0.0
    for a, b in itertools.pairwise(poses):
        T = rng.uniform(1.2, 2.0)
        moves.append((t, T, a, b))
        t += T + 0.3

    def motion(time, step=0.0):
        for t0, T, a, b in moves:
            if time < t0:
                return list(a), [0.0] * N, [0.0] * N
            if time <= t0 + T:
                tau = (time - t0) / T
                s = tau - math.sin(2 * math.pi * tau) / (2 * math.pi)
                sd = (1 - math.cos(2 * math.pi * tau)) / T
                sdd = 2 * math.pi * math.sin(2 * math.pi * tau) / T**2
                d = b - a
                return list(a + d * s), list(d * sd), list(d * sdd)
        return list(moves[-1][3]), [0.0] * N, [0.0] * N

    return motion, t


def clean_run(truth_fmu: Path, motion, duration: float) -> dict:
    """The true FMU along ``motion``: columns t, q1..q7 (exact), tau1..tau7 (exact), every
    SAMPLE of the FMU's steps of STEP. (Within a step the FMU holds each input as its Taylor
    polynomial, so at the step's end a rigid joint's q̈ is the one at its start: a lag of one
    step in the inertial torques, which a 4 ms step would make a model error of 0.5 % of joint
    2's torque; at 0.5 ms it is an eighth of that, below the torque noise.)"""
    from stickslip.fit.synthetic import measure

    outputs = {f"F_drive[{i}]": (f"tau{i}", 0.0, 0.0) for i in range(1, N + 1)}
    outputs.update({f"q[{i}]": (f"q{i}", 0.0, 0.0) for i in range(1, N + 1)})
    inputs = {f"q_star[{i}]": f"cmd{i}" for i in range(1, N + 1)}
    columns = measure(truth_fmu, {}, outputs, duration=duration, step=STEP, motion=motion, inputs=inputs)
    every = round(SAMPLE / STEP)
    return {k: v[::every] for k, v in columns.items() if not k.startswith("cmd")}


def logged(clean: dict, seed: int) -> dict:
    """The log of a clean run: encoders rounded to their count, torques with the noise."""
    rng = np.random.default_rng(seed)
    out = {"t": clean["t"]}
    for i in range(1, N + 1):
        out[f"q{i}"] = np.round(clean[f"q{i}"] / COUNT) * COUNT
    for i in range(1, N + 1):
        tau = clean[f"tau{i}"]
        out[f"tau{i}"] = tau + TORQUE_NOISE * np.max(np.abs(tau)) * rng.standard_normal(len(tau))
    return out


def fourier_motion(trajectory):
    def motion(t, step=0.0):
        q, qd, qdd = (x[0] for x in trajectory.at(np.array([t])))
        return list(q), list(qd), list(qdd)

    return motion


def clean_runs(work: Path, redesign: bool = False) -> dict:
    """Run name -> its clean columns: the truth and catalogue FMUs built in ``work``."""
    (HERE / "catalogue_kuka_iiwa.urdf").write_text(catalogue_urdf(URDF.read_text(encoding="utf-8")))
    truth = build(HERE / "truth.toml", work / "truth.fmu")
    catalogue = build(HERE / "catalogue.toml", work / "catalogue.fmu")
    runs = {}
    for name, seed in EXCITATION.items():
        if redesign:
            design(catalogue, seed)
        trajectory = excitation(seed)
        runs[name] = clean_run(truth, fourier_motion(trajectory), PERIODS * trajectory.period)
    from stickslip.fmu import content_hash, unpacked
    from stickslip.identify import excitation as ex

    data = catalogue.read_bytes()
    names = {i: f"lbr_iiwa_joint_{i}" for i in range(1, N + 1)}
    limits = ex.urdf_limits(unpacked(data, content_hash(data)), names)
    bounds = (np.array([limits[i][0] for i in names]), np.array([limits[i][1] for i in names]))
    for name, seed in HELDOUT.items():
        motion, duration = point_to_point(seed, bounds)
        runs[name] = clean_run(truth, motion, duration)
    return runs


def write_csv(columns: dict, path: Path) -> None:
    names = list(columns)
    table = np.column_stack([columns[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.9g")


def main() -> int:
    with tempfile.TemporaryDirectory() as work:
        runs = clean_runs(Path(work), redesign="--design" in sys.argv[1:])
    for k, (name, clean) in enumerate(runs.items()):
        write_csv(logged(clean, seed=1000 + k), HERE / f"{name}.csv")
        print(f"make_data.py: {name}.csv, {len(clean['t'])} samples")
    return 0


if __name__ == "__main__":
    sys.exit(main())
