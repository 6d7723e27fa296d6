"""A seeded FMI call-sequence fuzzer of the FMU, as an adversarial master would drive it.

Each batch runs in a child process (so that a crash of the FMU, which would take its
host with it, is caught and reported with the batch's seed) and makes random calls
through fmpy's FMU2Slave: the life-cycle calls in any order, steps with good and bad
communication points and step sizes, sets of any variable (inputs, parameters, settings,
outputs, Booleans) to extreme values (+-1e300, +-1e-300, +-0, NaN, +-inf and ordinary
ones), input derivatives, FMU states taken, restored, serialized, mutated (bit flips,
truncation, extension, zeros) and deserialized, and whole experiments in one call
(``stickslip_run_experiment``: fuzzed points, inputs, outputs and sensitivities, in any
state). An FMU with motor drives (inputs tau_m[i], e.g. one of
models/reference_rrpr_motor.toml) also gets calls aimed at them: tau_m and its
derivatives of orders 0 to 3, the fixed gear_ratio and start values theta_m_start,
omega_m_start, static_start in any state, the tunable J_m, b_m, tau_c, and starts from a
static equilibrium (static_start) or given rotor states. An FMU of a URDF arm (a URDF in its
resources/) is also instantiated, now and then, from a copy of its resources whose URDF is
mutated the same way or has a number replaced by an extreme or garbage. It checks what a
master relies on:

* no crash and no hang (each batch has a time limit);
* no fmi2OK step (or initialization) after which an output reads NaN or infinite;
* a status is one of OK, Warning, Discard, Error (never Fatal or Pending);
* fmi2Instantiate with a mutated URDF fails (returns NULL, fmpy raises) and logs an
  fmi2Error message: the FMU never runs a URDF other than the one its GUID was made from.

Run it from the repository root, e.g. the long run of the README:

    python tests/python/fuzz_fmi.py --calls 100000 --batches 50 --seed 1

and the same against a URDF arm's FMU (``--fmu``, e.g. one built by ``bash
scripts/build_fmu.sh --model models/urdf/kuka_iiwa/kuka_iiwa.toml --out iiwa.fmu``).

It prints one line per batch and a summary; exit status 1 if any batch failed.
"""

import argparse
import json
import math
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"

EXTREMES = [1e300, -1e300, 1e-300, -1e-300, 0.0, -0.0, math.nan, math.inf, -math.inf]
STEPS = [1e-5, 1e-4, 1e-3, 1e-3, 1e-3, 1e-2, 0.1, 1.0, 0.0, -1e-3, math.nan, math.inf, 1e-300]


def _value(rng: random.Random, start):
    """An extreme, an ordinary or a near-start value."""
    r = rng.random()
    if r < 0.35:
        return rng.choice(EXTREMES)
    if r < 0.7 and start is not None:
        return float(start) * rng.choice([0.0, 0.5, 0.99, 1.0, 1.01, 2.0, 10.0, -1.0])
    return rng.gauss(0.0, 1.0) * 10 ** rng.randint(-6, 6)


def _mutate(rng: random.Random, data: bytes) -> bytes:
    b = bytearray(data)
    kind = rng.randrange(4)
    if kind == 0 and b:
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
    elif kind == 1:
        b = b[: rng.randrange(len(b) + 1)]
    elif kind == 2:
        b += bytes(rng.randrange(256) for _ in range(rng.randint(1, 32)))
    elif b:
        i = rng.randrange(len(b))
        b[i : i + rng.randint(1, 64)] = bytes(len(b[i : i + 64]))
    return bytes(b)


URDF_VALUES = ["-1", "0", "nan", "inf", "1e308", "-1e308", "", "x", "1 2", "1e-308"]


def _mutate_urdf(rng: random.Random, text: bytes) -> bytes:
    """A byte-level mutation (as for FMU states), or one attribute value (or one number
    of it) replaced by an extreme or by garbage."""
    if rng.random() < 0.5:
        return _mutate(rng, text)
    spans = [(m.start(1), m.end(1)) for m in re.finditer(rb'="([^"]*)"', text)]
    if not spans:
        return _mutate(rng, text)
    s, e = rng.choice(spans)
    tokens = [(m.start() + s, m.end() + s) for m in re.finditer(rb"\S+", text[s:e])]
    if tokens and rng.random() < 0.5:
        s, e = rng.choice(tokens)
    return text[:s] + rng.choice(URDF_VALUES).encode() + text[e:]


class CorruptResources:
    """A directory beside the FMU's unzipped one whose binaries/ is a link to the FMU's (the
    library loaded is the same) and whose resources/ is a copy with the URDF mutated."""

    def __init__(self, unzipdir: str):
        self.source = Path(unzipdir)
        self.urdfs = sorted((self.source / "resources").glob("*.urdf"))
        self.dir = None

    def prepare(self, rng: random.Random):
        """A mutated URDF in place; None if the mutation changed nothing."""
        if self.dir is None:
            self.dir = Path(tempfile.mkdtemp(prefix="fuzz-urdf-"))
            (self.dir / "binaries").symlink_to(self.source / "binaries")
            shutil.copytree(self.source / "resources", self.dir / "resources")
            for extra in self.source.iterdir():
                if extra.name not in ("binaries", "resources"):
                    (self.dir / extra.name).symlink_to(extra)
        urdf = rng.choice(self.urdfs)
        original = urdf.read_bytes()
        mutated = _mutate_urdf(rng, original)
        for u in self.urdfs:
            (self.dir / "resources" / u.name).write_bytes(original if u != urdf else mutated)
        return None if mutated == original else str(self.dir)

    def remove(self):
        if self.dir is not None:
            shutil.rmtree(self.dir, ignore_errors=True)


def run_batch(fmu: str, seed: int, calls: int) -> dict:
    """Makes `calls` random calls on one instance (re-instantiated after fmi2FreeInstance);
    returns the counts and the violations found."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    rng = random.Random(seed)
    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    reals = [v for v in md.modelVariables if v.type == "Real"]
    bools = [v for v in md.modelVariables if v.type == "Boolean"]
    real_outputs = [v.valueReference for v in reals if v.causality == "output"]
    inputs = [v for v in reals if v.causality == "input"]
    counts = {
        "calls": 0,
        "ok": 0,
        "errors": 0,
        "discards": 0,
        "steps_ok": 0,
        "states_mutated": 0,
        "states_restored": 0,
        "corrupt_urdf_refused": 0,
        "motor_calls": 0,
        "experiments": 0,
        "experiments_ok": 0,
    }
    # Motor drives: their torque inputs, and the motor variables by kind.
    by_name = {v.name: v for v in md.modelVariables}
    motor = {
        "torque": [v for v in inputs if v.name.startswith("tau_m[")],
        "fixed": [v for v in reals if v.name.startswith(("gear_ratio[", "theta_m_start[", "omega_m_start["))],
        "tunable": [v for v in reals if v.name.startswith(("J_m[", "b_m[", "tau_c["))],
    }
    static_start = by_name.get("static_start")
    corrupt = CorruptResources(unzipdir)
    violations = []
    slave = None
    states = []
    serialized = []
    t = 0.0

    def new_slave():
        s = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=f"fuzz{seed}",
        )
        s.instantiate()
        return s

    def outputs_finite(after: str):
        values = slave.getReal(real_outputs)
        bad = [
            (md.modelVariables[vr].name if vr < len(md.modelVariables) else vr, x)
            for vr, x in zip(real_outputs, values, strict=True)
            if not math.isfinite(x)
        ]
        if bad:
            violations.append(f"seed {seed}: fmi2OK {after}, then non-finite outputs {bad[:3]}")

    def corrupt_instantiation():
        """fmi2Instantiate with a mutated URDF must fail, with an fmi2Error logged."""
        from stickslip.fmu import LogCapture

        directory = corrupt.prepare(rng)
        if directory is None:
            return
        log = LogCapture()
        other = FMU2Slave(
            guid=md.guid,
            unzipDirectory=directory,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=f"corrupt{seed}",
        )
        try:
            other.instantiate(callbacks=log.callbacks)
        except Exception:  # noqa: BLE001 -- fmpy raises a bare Exception("Failed to instantiate model")
            other.freeLibrary()
            if not any(st == 3 and "fmi2Instantiate" in m for (_, st, _, m) in log.records):
                violations.append(f"seed {seed}: fmi2Instantiate refused a mutated URDF without an fmi2Error message")
            counts["corrupt_urdf_refused"] += 1
            return
        other.freeInstance()
        violations.append(f"seed {seed}: fmi2Instantiate accepted a mutated URDF")

    actions = [
        "step",
        "set",
        "set_inputs",
        "get",
        "derivatives",
        "setup",
        "enter",
        "exit",
        "get_state",
        "set_state",
        "serialize",
        "deserialize",
        "reset",
        "terminate",
        "free",
        "bool",
        "start",
    ]
    weights = [40, 15, 12, 6, 3, 2, 2, 2, 3, 3, 3, 4, 2, 1, 1, 2, 3]
    actions, weights = [*actions, "experiment"], [*weights, 3]

    def experiment_call():
        """stickslip_run_experiment with fuzzed points, inputs, outputs and sensitivities: any
        status but Fatal; an OK one has finite outputs at every point."""
        import numpy as np

        from stickslip import experiment

        nonlocal t
        counts["experiments"] += 1
        if rng.random() < 0.5:
            # From the start, as the fit calls it: reset, set up, values set.
            slave.reset()
            slave.setupExperiment(startTime=0.0)
            t = 0.0
        n = rng.randint(1, 40)
        h = rng.choice(STEPS)
        start = t if rng.random() < 0.8 else rng.choice([t + 1e-3, -1.0, math.nan])
        times = [start + k * h for k in range(n)]
        if rng.random() < 0.1:
            times[rng.randrange(n)] = rng.choice([math.nan, math.inf, -1.0, start])
        drive = [[rng.gauss(0.0, 0.2) for _ in inputs] for _ in range(n)]
        if rng.random() < 0.2:  # an extreme input somewhere
            drive[rng.randrange(n)][rng.randrange(len(inputs))] = _value(rng, 0.1)
        outs = [rng.choice(reals).valueReference for _ in range(rng.randint(0, 4))]
        wrt = [rng.choice(reals).valueReference for _ in range(rng.randint(0, 2) if rng.random() < 0.3 else 0)]
        steps = [rng.choice([1e-6, 1e-3, 0.0, -1.0, math.nan, 1e300]) for _ in wrt]
        r = experiment.run(
            slave,
            times,
            [v.valueReference for v in inputs],
            drive,
            output_vrs=outs,
            sensitivity_vrs=wrt,
            steps=steps,
            central=rng.random() < 0.5,
            threads=rng.choice([0, 1, 2, 5]),
        )
        if r.status not in (0, 1, 2, 3):
            violations.append(f"seed {seed}: stickslip_run_experiment returned status {r.status}")
        if r.status <= 1:
            counts["experiments_ok"] += 1
            values = np.asarray(r.outputs)
            if not np.all(np.isfinite(values)):
                violations.append(f"seed {seed}: stickslip_run_experiment OK with non-finite outputs")
            t = times[-1]
        else:
            t = math.nan

    if corrupt.urdfs:
        actions, weights = [*actions, "corrupt_urdf"], [*weights, 2]
    if motor["torque"]:
        actions, weights = [*actions, "motor"], [*weights, 10]

    def motor_call():
        """One call aimed at the motor drives."""
        counts["motor_calls"] += 1
        kind = rng.choice(["torque", "torque", "derivative", "derivative", "fixed", "tunable", "static_start"])
        if kind == "torque":
            v = rng.choice(motor["torque"])
            slave.setReal([v.valueReference], [_value(rng, 0.05)])
        elif kind == "derivative":
            v = rng.choice(motor["torque"])
            slave.setRealInputDerivatives([v.valueReference], [rng.choice([1, 1, 2, 2, 3, 0])], [_value(rng, 1.0)])
        elif kind in ("fixed", "tunable"):
            v = rng.choice(motor[kind])
            slave.setReal([v.valueReference], [_value(rng, v.start)])
        elif static_start is not None:
            slave.setBoolean([static_start.valueReference], [rng.random() < 0.5])

    slave = new_slave()
    recover = True
    for _ in range(calls):
        counts["calls"] += 1
        action = rng.choices(actions, weights=weights)[0]
        if recover:
            # After an error a master resets and starts again, most of the time.
            action, recover = "start", False
        try:
            if action == "step":
                h = rng.choice(STEPS)
                point = t if rng.random() < 0.85 else rng.choice([t + 1e-3, -1.0, math.nan, t * 2 + 1])
                slave.doStep(currentCommunicationPoint=point, communicationStepSize=h)
                counts["steps_ok"] += 1
                t = point + h
                outputs_finite(f"doStep(t = {point}, h = {h})")
            elif action == "set":
                v = rng.choice(reals)
                slave.setReal([v.valueReference], [_value(rng, v.start)])
            elif action == "set_inputs":
                slave.setReal([v.valueReference for v in inputs], [_value(rng, 0.1) for _ in inputs])
            elif action == "get":
                v = rng.choice(reals)
                slave.getReal([v.valueReference])
            elif action == "derivatives":
                v = rng.choice(inputs)
                slave.setRealInputDerivatives([v.valueReference], [rng.choice([1, 2, 3, 0])], [_value(rng, 0.1)])
            elif action == "setup":
                t = rng.choice([0.0, 0.0, 1.0, -1.0, math.nan])
                slave.setupExperiment(startTime=t, tolerance=rng.choice([None, 1e-3, 1e-9, 0.5, math.nan]))
            elif action == "enter":
                slave.enterInitializationMode()
            elif action == "exit":
                slave.exitInitializationMode()
                outputs_finite("exitInitializationMode")
            elif action == "get_state":
                states.append(slave.getFMUstate())
            elif action == "set_state" and states:
                slave.setFMUstate(rng.choice(states))
                counts["states_restored"] += 1
                t = math.nan  # unknown: the next step may use a wrong point
            elif action == "serialize" and states:
                serialized.append(bytes(slave.serializeFMUstate(rng.choice(states))))
            elif action == "deserialize" and serialized:
                data = rng.choice(serialized)
                if rng.random() < 0.7:
                    data = _mutate(rng, data)
                    counts["states_mutated"] += 1
                states.append(slave.deSerializeFMUstate(data))
            elif action == "reset":
                slave.reset()
                t = 0.0
            elif action == "terminate":
                slave.terminate()
            elif action == "free":
                slave.freeInstance()
                slave = new_slave()
                states.clear()
                t = 0.0
            elif action == "start":
                # The ordinary start: reset, start values, initial inputs. FMU
                # states stay valid across fmi2Reset.
                slave.reset()
                slave.setupExperiment(startTime=0.0)
                for _ in range(rng.randint(0, 3)):
                    v = rng.choice(reals)
                    try:
                        slave.setReal([v.valueReference], [_value(rng, v.start)])
                    except FMICallException:
                        pass
                if motor["torque"] and static_start is not None:
                    # A static start (rotors turned to hold the links) or, with start values,
                    # given rotor states.
                    slave.setBoolean([static_start.valueReference], [rng.random() < 0.5])
                slave.enterInitializationMode()
                slave.setReal([v.valueReference for v in inputs], [rng.gauss(0.0, 0.3) for _ in inputs])
                slave.exitInitializationMode()
                t = 0.0
                outputs_finite("start")
            elif action == "bool" and bools:
                v = rng.choice(bools)
                slave.setBoolean([v.valueReference], [rng.random() < 0.5])
            elif action == "corrupt_urdf":
                corrupt_instantiation()
            elif action == "motor":
                motor_call()
            elif action == "experiment":
                experiment_call()
            counts["ok"] += 1
        except FMICallException as e:
            status = getattr(e, "status", None)
            if status == 2:
                counts["discards"] += 1
            elif status in (1, 3):
                counts["errors"] += 1
                recover = rng.random() < 0.6
            else:
                violations.append(f"seed {seed}: {action} returned status {status}: {e}")
        if math.isnan(t):
            try:
                t = slave.getRealStatus(2)  # fmi2LastSuccessfulTime
            except FMICallException:
                t = 0.0
    try:
        slave.freeInstance()
    except Exception:  # noqa: BLE001 -- whatever freeing a fuzzed instance raises, the batch reports its counts
        pass
    corrupt.remove()
    return {"seed": seed, "counts": counts, "violations": violations}


def run_child(fmu: str, seed: int, calls: int, timeout: float) -> dict:
    """One batch in a child process: a crash or hang is reported with its seed."""
    cmd = [sys.executable, str(Path(__file__)), "--child", "--fmu", fmu, "--seed", str(seed), "--calls", str(calls)]
    started = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"seed": seed, "counts": {}, "violations": [f"seed {seed}: hang (no result in {timeout} s)"]}
    if p.returncode != 0:
        return {
            "seed": seed,
            "counts": {},
            "violations": [f"seed {seed}: child died with status {p.returncode}: {p.stderr[-800:]}"],
        }
    result = json.loads(p.stdout.strip().splitlines()[-1])
    result["wall_s"] = time.perf_counter() - started
    return result


def fuzz(fmu: str, seed: int, batches: int, calls: int, timeout: float = 300.0, verbose: bool = True) -> dict:
    total = {}
    violations = []
    for b in range(batches):
        r = run_child(fmu, seed * 1_000_003 + b, calls, timeout)
        for k, v in r["counts"].items():
            total[k] = total.get(k, 0) + v
        violations += r["violations"]
        if verbose:
            print(
                f"batch {b + 1}/{batches} seed {r['seed']}: {r['counts']} "
                f"{len(r['violations'])} violations ({r.get('wall_s', 0):.1f} s)",
                flush=True,
            )
    return {"counts": total, "violations": violations}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu", default=str(DEFAULT_FMU))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--calls", type=int, default=2000, help="calls in all (per batch with --child)")
    ap.add_argument("--batches", type=int, default=4)
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per batch")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(run_batch(a.fmu, a.seed, a.calls)))
        return 0
    per_batch = max(1, a.calls // a.batches)
    result = fuzz(a.fmu, a.seed, a.batches, per_batch, a.timeout)
    print("summary:", json.dumps(result["counts"]))
    for v in result["violations"]:
        print("VIOLATION", v)
    print(f"{len(result['violations'])} violations")
    return 1 if result["violations"] else 0


if __name__ == "__main__":
    sys.exit(main())
