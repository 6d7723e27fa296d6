"""MuJoCo's mj_step on the same URDF as an engine model file, for the speed comparison of
issue 19 (the engine's sub-step on the 7-joint arm against MuJoCo's step).

    source scripts/env.sh
    python scripts/bench_mujoco.py                       # KUKA iiwa (7 joints) and xArm 6
    python scripts/bench_mujoco.py --model models/urdf/kuka_iiwa/kuka_iiwa.toml
    python scripts/bench_mujoco.py --engine              # also `cargo bench --bench substep -- iiwa`,
                                                         # and the ratio, in the same run

The arm: MuJoCo 3.14's URDF compiler reads the model file's URDF with the recipe of
models/urdf/README.md (visual and collision elements removed, meshes not shipped;
``<mujoco><compiler discardvisual="true" balanceinertia="true"/></mujoco>`` put inside
``<robot>``; balanceinertia changes nothing on the iiwa, and makes the xArm's two
physically impossible inertias loadable). Then, as close to the engine's model file as
MuJoCo allows:

* timestep 2e-6 s (the engine's h_min and the fixed sub-step of its benches), MuJoCo's
  default Euler integrator, gravity from the model file;
* the URDF's own <dynamics damping/friction> removed (the engine does not use them):
  dof_damping = dof_frictionloss = 0, then
* a flexible drive (k, h): a position actuator on the joint, kp = k, kv = h, i.e. the
  force k (q* − q) − h q̇, the engine's drive law with q̇* = 0 and no clearance;
* a rigid drive: MuJoCo has no prescribed joint motion; a stiff position servo stands in
  (kp = 1e6 N·m/rad, critically damped at the joint's inertia in qpos0, dampratio = 1);
* friction: MuJoCo's joint friction is a constant frictionloss (dry friction whose
  magnitude does not depend on the joint load, solved by its constraint solver), where
  the engine's is μ times the bearing loads of the moving arm. frictionloss is set to the
  engine's kinetic friction moment in the start pose at rest: μ_k (R_A d_A/2 + R_B d_B/2 +
  2/3 |f_z| d_C/2), the bearing loads from Pinocchio's joint reactions of the same URDF at
  the reaction reference point.

The arm starts at rest in the pose ``--pose`` (default: the start pose of the motion of
tests/python/test_urdf_pinocchio.py), the drives hold it (ctrl = that pose), gravity pulls;
``mj_step(m, d, nstep=N)`` (the loop in C) is timed over N steps, repeated; the median and
the best repetition are reported in µs per step. The state is reset before each repetition.

With ``--engine`` the script first runs ``cargo bench --bench substep -- FILTER`` (criterion,
target/criterion/<group>/<bench>/new/estimates.json) and reports the engine's sub-step
cost (median / --substeps sub-steps per sample) next to MuJoCo's and the ratio; without it
it reads estimates already there that match FILTER, if any.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ARMS = [ROOT / "models" / "urdf" / "kuka_iiwa" / "kuka_iiwa.toml", ROOT / "models" / "urdf" / "xarm6" / "xarm6.toml"]
START_POSES = {  # the start of tests/python/test_urdf_pinocchio.py's motions
    "kuka_iiwa": [0.0, 0.3, 0.0, -0.5, 0.0, 0.4, 0.0],
    "xarm6": [0.0, 0.0, -0.5, 0.0, 0.3, 0.0],
}
RIGID_KP = 1e6


def mujoco_xml_from_urdf(path, balance_inertia: bool = True) -> str:
    """The URDF's text made loadable by MuJoCo's compiler (models/urdf/README.md): without its
    visual and collision elements, with a <mujoco><compiler .../></mujoco> extension first."""
    try:
        robot = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as e:
        raise SystemExit(f"{path}: not XML ({e})") from None
    if robot.tag != "robot":
        raise SystemExit(f"{path}: no <robot> element")
    for parent in robot.iter():
        for child in [c for c in parent if c.tag in ("visual", "collision")]:
            parent.remove(child)
    compiler = {"discardvisual": "true"} | ({"balanceinertia": "true"} if balance_inertia else {})
    extension = ElementTree.Element("mujoco")
    ElementTree.SubElement(extension, "compiler", compiler)
    robot.insert(0, extension)
    return ElementTree.tostring(robot, encoding="unicode")


def friction_moments(model_path: Path, doc: dict, joint_names: list, pose) -> dict:
    """{joint name: μ_k × the engine's bearing lever load} at rest in ``pose`` (Pinocchio)."""
    import pinocchio as pin

    urdf = model_path.parent / doc["urdf"]
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity.linear = np.array(doc.get("gravity", [0.0, 0.0, -9.81]), dtype=float)
    data = model.createData()
    pin.rnea(model, data, np.array(pose, float), np.zeros(model.nv), np.zeros(model.nv))
    out = {}
    for name, entry in doc.get("joints", {}).items():
        if "friction" not in entry or "bearings" not in entry:
            continue
        j = model.getJointId(name)
        b = entry["bearings"]
        p = np.array(b["reaction_point"], float)
        f = data.f[j].linear
        n = data.f[j].angular - np.cross(p, f)
        la, lb = b["l_a"], b["l_b"]
        r_a = np.hypot(lb * f[0] - n[1], lb * f[1] + n[0]) / (la + lb)
        r_b = np.hypot(la * f[0] + n[1], la * f[1] - n[0]) / (la + lb)
        lever = r_a * 0.5 * b["d_a"] + r_b * 0.5 * b["d_b"] + 2.0 / 3.0 * abs(f[2]) * 0.5 * b["d_c"]
        out[name] = entry["friction"]["mu_k"] * lever
    return out


def mujoco_arm(model_path: Path, timestep: float, pose=None):
    """(MjModel, MjData, description) of the model file's arm as the module docstring says."""
    import mujoco

    doc = tomllib.loads(model_path.read_text(encoding="utf-8"))
    urdf = model_path.parent / doc["urdf"]
    spec = mujoco.MjSpec.from_string(mujoco_xml_from_urdf(urdf))
    names = [j.name for j in spec.joints]
    arm = model_path.stem
    pose = list(pose if pose is not None else START_POSES.get(arm, [0.0] * len(names)))
    if len(pose) != len(names):
        raise SystemExit(f"{model_path}: --pose has {len(pose)} values for {len(names)} joints")
    entries = doc.get("joints", {})
    drives = []
    for name in names:
        a = spec.add_actuator()
        a.name = f"drive_{name}"
        a.target = name
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        drive = entries.get(name, {}).get("drive", {"type": "rigid"})
        if drive["type"] == "flexible":
            a.set_to_position(kp=drive["k"], kv=drive["h"])
            drives.append("flexible")
        else:
            a.set_to_position(kp=RIGID_KP, dampratio=1.0)
            drives.append("rigid")
    m = spec.compile()
    friction = friction_moments(model_path, doc, names, pose)
    m.dof_damping[:] = 0.0
    m.dof_frictionloss[:] = 0.0
    for name in names:
        m.dof_frictionloss[m.joint(name).dofadr[0]] = friction.get(name, 0.0)
    m.opt.timestep = timestep
    m.opt.gravity[:] = doc.get("gravity", [0.0, 0.0, -9.81])
    d = mujoco.MjData(m)
    desc = (
        f"{arm}: nq {m.nq}, {sum(m.body_mass):.4g} kg, drives {drives}, frictionloss "
        f"{np.array2string(m.dof_frictionloss, precision=3)} N·m, dof_damping {m.dof_damping.max():g}, "
        f"timestep {m.opt.timestep:g} s, integrator {mujoco.mjtIntegrator(m.opt.integrator).name}"
    )
    return m, d, np.array(pose, float), desc


def time_mj_step(m, d, pose, steps: int, repeats: int) -> list:
    """(wall, CPU) µs per mj_step of each repetition (nstep=steps, from rest at ``pose``, ctrl =
    pose). The CPU time (of this single-threaded process) is less sensitive to other jobs on
    the machine than the wall time."""
    import mujoco

    per = []
    for _ in range(repeats):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = pose
        d.ctrl[:] = pose
        mujoco.mj_forward(m, d)
        mujoco.mj_step(m, d, nstep=1000)  # warm-up
        t0, c0 = time.perf_counter(), time.process_time()
        mujoco.mj_step(m, d, nstep=steps)
        per.append(((time.perf_counter() - t0) / steps * 1e6, (time.process_time() - c0) / steps * 1e6))
        if not np.all(np.isfinite(d.qpos)):
            raise SystemExit("MuJoCo's state diverged")
    return per


def engine_estimates(filter_: str, substeps: int) -> dict:
    """{group/bench: µs per sub-step} of the criterion estimates whose id contains ``filter_``."""
    out = {}
    for est in sorted((ROOT / "target" / "criterion").glob("**/new/estimates.json")):
        rel = est.relative_to(ROOT / "target" / "criterion").parent.parent
        key = str(rel)
        if filter_.lower() in key.lower():
            ns = json.loads(est.read_text())["median"]["point_estimate"]
            out[key] = ns / substeps / 1e3
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--model", action="append", type=Path, help="model file (repeatable); default: both example arms")
    p.add_argument("--timestep", type=float, default=2e-6)
    p.add_argument("--steps", type=int, default=100_000, help="mj_step calls per repetition (default 100000)")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--pose", help="comma-separated start pose (one model only)")
    p.add_argument("--engine", action="store_true", help="run `cargo bench --bench substep -- FILTER` first")
    p.add_argument("--engine-filter", default="iiwa", help="criterion benchmark id filter (default: iiwa)")
    p.add_argument("--substeps", type=int, default=500, help="engine sub-steps per criterion sample (default 500)")
    a = p.parse_args(argv)
    models = a.model or ARMS
    pose = [float(x) for x in a.pose.split(",")] if a.pose else None
    if a.engine:
        cmd = ["cargo", "bench", "--bench", "substep", "--", a.engine_filter]
        print("bench_mujoco: " + " ".join(cmd), flush=True)
        subprocess.run(cmd, cwd=ROOT, check=True)
    load = lambda: " ".join(f"{x:.2f}" for x in os.getloadavg())  # noqa: E731
    print(f"bench_mujoco: MuJoCo {__import__('mujoco').__version__}, {os.cpu_count()} cores, load average {load()}")
    rows = []
    for path in models:
        m, d, q0, desc = mujoco_arm(Path(path).resolve(), a.timestep, pose)
        print(f"bench_mujoco: {desc}", flush=True)
        per = time_mj_step(m, d, q0, a.steps, a.repeats)
        wall, cpu = [w for w, _ in per], [c for _, c in per]
        med, best, cmed = statistics.median(wall), min(wall), statistics.median(cpu)
        rows.append((Path(path).stem, m.nq, med, best, cmed))
        print(
            f"bench_mujoco: {Path(path).stem}: mj_step {med:.3f} µs median wall ({cmed:.3f} µs CPU), {best:.3f} µs "
            f"best of {a.repeats} x {a.steps} steps; load average {load()}",
            flush=True,
        )
    print(
        f"\n| arm | joints | mj_step at {a.timestep:g} s: median wall | best wall | median CPU |\n|---|---|---|---|---|"
    )
    for arm, nq, med, best, cmed in rows:
        print(f"| {arm} | {nq} | {med:.3f} µs | {best:.3f} µs | {cmed:.3f} µs |")
    engine = engine_estimates(a.engine_filter, a.substeps)
    if engine:
        mj = {arm: med for arm, _, med, _, _ in rows}
        print("\n| engine benchmark | per sub-step | MuJoCo mj_step (same arm) | engine / MuJoCo |\n|---|---|---|---|")
        for key, us in engine.items():
            arm = next((x for x in mj if x.split("_")[-1] in key or x in key), None)
            ref = mj.get(arm) if arm else None
            ratio = f"{us / ref:.2f}" if ref else "–"
            print(f"| {key} | {us:.3f} µs | {f'{ref:.3f} µs' if ref else '–'} | {ratio} |")
    else:
        print(
            f"\n(no criterion estimates matching '{a.engine_filter}' under target/criterion: "
            "run with --engine for the engine's sub-step and the ratio)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
