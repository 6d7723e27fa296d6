"""Pinocchio and the engine on the same URDF file, for the URDF tests (issue 19).

* Pinocchio (``pin``) loading the *same* URDF file as the engine's model file:
  :func:`pinocchio_model`, and the quantities the engine reports, computed by
  Pinocchio: :func:`pinocchio_dynamics` (tau by RNEA, the joint reactions
  ``data.f`` moved to a reference point, the end point, the mass matrix by CRBA).
  (MuJoCo's reading of the same URDF is in scripts/bench_mujoco.py.)
* The engine's side: the model file (TOML) read for what the URDF does not
  carry (:func:`model_file`), the engine's ``inverse_dynamics`` binary
  (:func:`engine_inverse_dynamics`), an FMU of a model file
  (:func:`package_fmu`), and a model file with every drive made rigid
  (:func:`rigid_variant`).

Conventions (checked by hand on a pendulum in tests/python/test_urdf_pinocchio.py):
Pinocchio's ``data.f[j]`` after ``rnea`` is the spatial force that the parent
body applies, through joint j, on the subtree supported by joint j (gravity
included, as ``rnea`` accelerates the base by -g), expressed in joint j's local
frame with its moment about that frame's origin. For a URDF, joint j's frame is
its child link's frame. The engine reports ``f[j]``, ``n[j]``: the force and
moment link j-1 exerts on link j, resolved in the URDF child link frame, about
the joint origin (``inverse_dynamics``) or about the joint's reaction reference
point P (the FMU), so that n_P = n_O - P x f.
"""

from __future__ import annotations

import csv
import functools
import os
import re
import shutil
import subprocess
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from helpers import cargo_targets

ROOT = Path(__file__).resolve().parents[2]
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", str(ROOT / "target")))
RELEASE = TARGET / "release"

# The example arms of models/urdf (name -> model file).
ARMS = {
    "kuka_iiwa": ROOT / "models" / "urdf" / "kuka_iiwa" / "kuka_iiwa.toml",
    "xarm6": ROOT / "models" / "urdf" / "xarm6" / "xarm6.toml",
}


# ---------------------------------------------------------------------------
# the model file


class ModelFile:
    """What the tests need of a URDF model file: its URDF, chain ends, end point, gravity and
    per joint (in chain order, 1-based as the engine numbers them) the URDF name, the axis,
    the reaction reference point and the drive."""

    def __init__(self, path):
        self.path = Path(path)
        self.doc = tomllib.loads(self.path.read_text(encoding="utf-8"))
        self.urdf = (self.path.parent / self.doc["urdf"]).resolve()
        self.end_point = np.array(self.doc.get("end_point", [0.0, 0.0, 0.0]), dtype=float)
        self.gravity = np.array(self.doc.get("gravity", [0.0, 0.0, -9.81]), dtype=float)
        self.entries = self.doc.get("joints", {})
        root = ET.parse(self.urdf).getroot()
        self.urdf_joints = {j.get("name"): j for j in root.findall("joint")}
        links = {link.get("name") for link in root.findall("link")}
        children = {j.find("child").get("link") for j in root.findall("joint")}
        parents = {j.find("parent").get("link") for j in root.findall("joint")}
        (urdf_root,) = links - children
        self.base_link = self.doc.get("base_link", urdf_root)
        if "tip_link" in self.doc:
            self.tip_link = self.doc["tip_link"]
        else:
            (self.tip_link,) = links - parents
        # The chain base_link -> tip_link, walking up from the tip.
        by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
        chain, link = [], self.tip_link
        while link != self.base_link:
            j = by_child[link]
            chain.append(j)
            link = j.find("parent").get("link")
        chain.reverse()
        self.moving = [j for j in chain if j.get("type") in ("revolute", "continuous", "prismatic")]
        self.names = [j.get("name") for j in self.moving]

    @property
    def n(self) -> int:
        return len(self.names)

    def axis(self, i: int) -> np.ndarray:
        """Unit axis of joint i (1-based) in its own frame, from the URDF."""
        el = self.moving[i - 1].find("axis")
        a = np.array([float(x) for x in el.get("xyz").split()]) if el is not None else np.array([1.0, 0.0, 0.0])
        return a / np.linalg.norm(a)

    def reaction_point(self, i: int) -> np.ndarray:
        """The reaction reference point of joint i in its frame (bearings' reaction_point, a
        slider's centre, else the joint origin)."""
        e = self.entries.get(self.names[i - 1], {})
        if "bearings" in e:
            return np.array(e["bearings"]["reaction_point"], dtype=float)
        if "slider" in e:
            return np.array(e["slider"]["centre"], dtype=float)
        return np.zeros(3)

    def flexible(self, i: int) -> bool:
        return self.entries.get(self.names[i - 1], {}).get("drive", {}).get("type") == "flexible"

    def bearings(self, i: int):
        return self.entries.get(self.names[i - 1], {}).get("bearings")


@functools.cache
def model_file(path) -> ModelFile:
    return ModelFile(path)


def rigid_variant(path, out_dir) -> Path:
    """A copy of the model file ``path`` in ``out_dir`` (with its URDF beside it) in which every
    drive is rigid (``drive = { type = "rigid" }``); friction and contact geometry are kept."""
    path = Path(path)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    mf = model_file(path)
    shutil.copyfile(mf.urdf, out_dir / mf.urdf.name)
    text = path.read_text(encoding="utf-8")
    new, count = re.subn(r"(?m)^drive\s*=\s*\{[^}\n]*\}", 'drive = { type = "rigid" }', text)
    assert count == sum(mf.flexible(i) for i in range(1, mf.n + 1)), "every flexible drive line replaced"
    out = out_dir / (path.stem + "_rigid.toml")
    out.write_text(new, encoding="utf-8")
    return out


# ---------------------------------------------------------------------------
# Pinocchio


def pinocchio_model(mf: ModelFile):
    """pinocchio.buildModelFromUrdf of the model file's URDF, checked to be the engine's chain:
    the same moving joints in the same order, the model file's gravity."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(mf.urdf))
    names = [model.names[j] for j in range(1, model.njoints)]
    assert names == mf.names, f"Pinocchio's joints {names} are not the chain {mf.names}"
    assert model.nq == model.nv == mf.n
    model.gravity.linear = mf.gravity
    return model


def pinocchio_dynamics(model, mf: ModelFile, q, qd, qdd, reaction_points: bool = False) -> dict:
    """Per state (rows of q, qd, qdd): tau (RNEA), f and n (``data.f[j]``: the force link j-1
    exerts on link j in the child link frame, moment about the joint origin, or about the
    reaction reference point with ``reaction_points``), x_E (tip_link frame placement applied
    to the model file's end point) and M (CRBA, symmetrised)."""
    import pinocchio as pin

    data = model.createData()
    tip = model.getFrameId(mf.tip_link)
    assert tip < model.nframes, f"no frame {mf.tip_link} in Pinocchio's model"
    n, rows = mf.n, len(q)
    out = {
        "tau": np.empty((rows, n)),
        "f": np.empty((rows, n, 3)),
        "n": np.empty((rows, n, 3)),
        "x_E": np.empty((rows, 3)),
        "M": np.empty((rows, n, n)),
    }
    points = [mf.reaction_point(i) if reaction_points else np.zeros(3) for i in range(1, n + 1)]
    for k in range(rows):
        out["tau"][k] = pin.rnea(model, data, q[k], qd[k], qdd[k])
        for j in range(1, n + 1):
            f = data.f[j].linear.copy()
            out["f"][k, j - 1] = f
            out["n"][k, j - 1] = data.f[j].angular - np.cross(points[j - 1], f)
        pin.framesForwardKinematics(model, data, q[k])
        out["x_E"][k] = data.oMf[tip].act(mf.end_point)
        M = pin.crba(model, data, q[k]).copy()
        out["M"][k] = np.triu(M) + np.triu(M, 1).T
    return out


def reaction_quantities(f: np.ndarray, n: np.ndarray, axis: np.ndarray) -> dict:
    """Axial force f.a, radial force |f - (f.a) a|, axial moment n.a, bending moment
    |n - (n.a) a| of reactions f, n (..., 3) for a unit joint axis a."""
    fa = f @ axis
    na = n @ axis
    return {
        "axial force": fa,
        "radial force": np.linalg.norm(f - fa[..., None] * axis, axis=-1),
        "axial moment": na,
        "bending moment": np.linalg.norm(n - na[..., None] * axis, axis=-1),
    }


def bearing_normal_load(bearings: dict, f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """R_A + R_B + |f_z| of the study's (3.13)-(3.15) from reactions at the reaction point
    (joint frame, z along the axis): bearing A l_A below, B l_B above the point."""
    la, lb = bearings["l_a"], bearings["l_b"]
    span = la + lb
    r_a = np.hypot(lb * f[..., 0] - n[..., 1], lb * f[..., 1] + n[..., 0]) / span
    r_b = np.hypot(la * f[..., 0] + n[..., 1], la * f[..., 1] - n[..., 0]) / span
    return r_a + r_b + np.abs(f[..., 2])


# ---------------------------------------------------------------------------
# the engine


def _cargo() -> str:
    return shutil.which("cargo") or str(Path.home() / ".cargo" / "bin" / "cargo")


@functools.cache
def engine_binaries() -> Path:
    """target/release with ``inverse_dynamics``, ``package_fmu`` and the cdylib, built (or
    brought up to date: cargo does nothing when they are) by ``cargo build --release``."""
    targets = cargo_targets("--lib", "--bin", "inverse_dynamics", "--bin", "package_fmu")
    cmd = [_cargo(), "build", "--release", "--quiet", *targets]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{r.stderr[-4000:]}")
    return RELEASE


def _parse_header(line: str, width: int) -> list:
    """A CSV header whose names may contain commas (``f[1,2]``): RFC-4180 quoted names are read
    as such; unquoted ones are split at the commas outside brackets."""
    names = next(csv.reader([line]))
    if len(names) == width:
        return names
    return re.findall(r"[^,\[\]]+(?:\[[^\]]*\])?", line)


def read_table(path) -> dict:
    """A CSV of numbers as {column name: float array}."""
    with open(path, encoding="utf-8") as f:
        first = f.readline().rstrip("\n")
        rows = np.loadtxt(f, delimiter=",", ndmin=2)
    header = _parse_header(first, rows.shape[1])
    assert len(header) == rows.shape[1], f"{path}: {len(header)} names for {rows.shape[1]} columns"
    return {name: rows[:, c] for c, name in enumerate(header)}


def engine_inverse_dynamics(model_path, q, qd, qdd, work_dir) -> dict:
    """``inverse_dynamics --model FILE --states IN.csv --out OUT.csv`` at the states given
    (written with repr, i.e. exactly), as arrays shaped like :func:`pinocchio_dynamics`'s."""
    n = q.shape[1]
    work_dir = Path(work_dir)
    states, out = work_dir / "states.csv", work_dir / "dynamics.csv"
    with open(states, "w", encoding="utf-8") as fh:
        fh.write(",".join(f"{b}[{i}]" for b in ("q", "qd", "qdd") for i in range(1, n + 1)) + "\n")
        for row in np.hstack([q, qd, qdd]):
            fh.write(",".join(repr(float(x)) for x in row) + "\n")
    exe = engine_binaries() / "inverse_dynamics"
    subprocess.run(
        [str(exe), "--model", str(model_path), "--states", str(states), "--out", str(out)],
        check=True,
        capture_output=True,
    )
    t = read_table(out)
    col = lambda name: t[name]  # noqa: E731
    return {
        "tau": np.stack([col(f"tau[{i}]") for i in range(1, n + 1)], axis=1),
        "f": np.stack([np.stack([col(f"f[{i},{k}]") for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1),
        "n": np.stack([np.stack([col(f"n[{i},{k}]") for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1),
        "x_E": np.stack([col(f"x_E[{k}]") for k in (1, 2, 3)], axis=1),
        "M": np.stack(
            [np.stack([col(f"M[{i},{j}]") for j in range(1, n + 1)], axis=1) for i in range(1, n + 1)], axis=1
        ),
    }


def package_fmu(model_path, out) -> Path:
    """The FMU (linux64 binary only) of a model file, by ``package_fmu --model FILE --out FILE``."""
    exe = engine_binaries() / "package_fmu"
    r = subprocess.run(
        [str(exe), "--model", str(model_path), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        raise RuntimeError(f"package_fmu --model {model_path} failed: {r.stderr}")
    return Path(out)
