"""A seeded FMI 3.0 call-sequence fuzzer of the FMI 3.0 FMU, as an adversarial master would
drive it (the FMI 2.0 one is fuzz_fmi.py).

Each batch runs in a child process (a crash of the FMU would take its host with it; it is
caught and reported with the batch's seed) and makes random calls through fmpy's FMU3Slave:
instantiation with any of eventModeUsed, earlyReturnAllowed and an intermediate-update
callback (which reads outputs, sets the drive inputs to extreme values, asks for early
return and makes calls Intermediate Update Mode forbids), the mode changes in any order,
steps from good and bad communication points with good and bad sizes, sets of any array to
extreme values (+-1e300, +-1e-300, +-0, NaN, +-inf and ordinary ones) with right and wrong
nValues, gets of every type with right and wrong value references and nValues, output
derivatives, FMU states taken, restored, serialized, mutated (bit flips, truncation,
extension) and deserialized, resets. It checks:

* no crash and no hang (each batch has a time limit);
* a status is one of OK, Warning, Discard, Error (never Fatal);
* no fmi3OK step after which a Float64 output reads NaN or infinite;
* an early return's lastSuccessfulTime lies inside its step.

    python tests/python/fuzz_fmi3.py --calls 20000 --batches 20 --seed 1
"""

from __future__ import annotations

import argparse
import json
import math
import random
import subprocess
import sys
from pathlib import Path

EXTREMES = [1e300, -1e300, 1e-300, -1e-300, 0.0, -0.0, math.nan, math.inf, -math.inf, 1.0, -1.0, 0.5, 1e6]


def _value(rng: random.Random, start: float | None) -> float:
    if start is not None and rng.random() < 0.5:
        return start * rng.choice([1.0, 0.5, 2.0, -1.0, 1.0 + 1e-9])
    return rng.choice(EXTREMES)


def _mutate(rng: random.Random, data: bytes) -> bytes:
    data = bytearray(data)
    kind = rng.randrange(3)
    if kind == 0 and data:
        i = rng.randrange(len(data))
        data[i] ^= 1 << rng.randrange(8)
    elif kind == 1 and data:
        del data[rng.randrange(len(data)) :]
    else:
        data += bytes(rng.randrange(256) for _ in range(rng.randrange(1, 16)))
    return bytes(data)


def run_batch(fmu: str, seed: int, calls: int) -> dict:
    """One batch in this process: returns counts and the problems found."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Slave, fmi3Float64, fmi3Int32, fmi3ValueReference

    rng = random.Random(seed)
    md = read_model_description(fmu)
    unzipped = extract(fmu)
    variables = [v for v in md.modelVariables]
    size = {v.valueReference: math.prod(int(d.start) for d in v.dimensions) if v.dimensions else 1 for v in variables}
    settable = [v for v in variables if v.causality in ("input", "parameter")]
    float_outputs = [v for v in variables if v.causality == "output" and v.type == "Float64"]
    starts = {
        v.valueReference: [float(x) for x in str(v.start).split()]
        if v.start is not None and v.type != "Boolean"
        else None
        for v in settable
    }
    problems: list[str] = []
    counts = {"calls": 0, "ok": 0, "error": 0, "discard": 0, "early": 0, "callbacks": 0}
    state = {"slave": None, "t": 0.0, "states": [], "blobs": []}

    def status_of(fn, *args):
        counts["calls"] += 1
        try:
            result = fn(*args)
        except FMICallException as e:
            if e.status not in (2, 3):
                problems.append(f"seed {seed}: {fn.__name__} returned status {e.status}")
            counts["discard" if e.status == 2 else "error"] += 1
            return None, e.status
        counts["ok"] += 1
        return result, 0

    def callback(env, t, set_requested, get_allowed, step_finished, can_return_early, early_requested, early_time):
        counts["callbacks"] += 1
        s = state["slave"]
        if s is None:
            return
        r = rng.random()
        try:
            if r < 0.3:
                v = rng.choice(variables)
                s.getFloat64([v.valueReference], size[v.valueReference])
            elif r < 0.4:
                v = rng.choice([v for v in settable if v.causality == "input"])
                s.setFloat64([v.valueReference], [_value(rng, None) for _ in range(size[v.valueReference])])
            elif r < 0.45:
                s.doStep(t, 1e-3)
            elif r < 0.5:
                s.enterEventMode()
        except FMICallException:
            pass
        if rng.random() < 0.05:
            early_requested[0] = True
            early_time[0] = t

    def new_instance():
        s = FMU3Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
        event_mode = rng.random() < 0.5
        s.instantiate(
            eventModeUsed=event_mode,
            earlyReturnAllowed=rng.random() < 0.5,
            intermediateUpdate=callback if rng.random() < 0.5 else None,
            logMessage=lambda *a: None,
        )
        state["slave"], state["t"], state["states"] = s, 0.0, []
        if rng.random() < 0.8:  # mostly the right way into Step Mode, so that the steps get fuzzed
            status_of(s.enterInitializationMode, None, 0.0, None)
            status_of(s.exitInitializationMode)
            if event_mode:
                status_of(s.updateDiscreteStates)
                status_of(s.enterStepMode)

    new_instance()
    for _ in range(calls):
        s = state["slave"]
        r = rng.random()
        if r < 0.03:
            status_of(s.enterInitializationMode, None, 0.0, rng.choice([None, 1.0, 0.01]))
        elif r < 0.06:
            status_of(s.exitInitializationMode)
        elif r < 0.08:
            status_of(s.updateDiscreteStates)
        elif r < 0.10:
            status_of(s.enterStepMode)
        elif r < 0.11:
            status_of(s.enterEventMode)
        elif r < 0.35:
            t = state["t"] if rng.random() < 0.9 else rng.choice([-1.0, math.nan, state["t"] + 1.0])
            h = rng.choice([1e-3, 1e-3, 2e-3, 5e-4, 0.0, -1e-3, math.nan, math.inf, 10.0])
            result, st = status_of(s.doStep, t, h)
            if st == 0 and result is not None:
                _, _, early, last = result
                if early:
                    counts["early"] += 1
                    if not (t < last < t + h):
                        problems.append(f"seed {seed}: early return at {last} outside the step ({t}, {t + h})")
                state["t"] = last
                for v in float_outputs:
                    values = s.getFloat64([v.valueReference], size[v.valueReference])
                    if not all(math.isfinite(x) for x in values):
                        problems.append(f"seed {seed}: `{v.name}` = {values} after an fmi3OK step at t = {last}")
                        break
        elif r < 0.55:
            v = rng.choice(settable)
            n = size[v.valueReference] + (0 if rng.random() < 0.9 else rng.choice([-1, 1]))
            values = [_value(rng, (starts[v.valueReference] or [None])[0]) for _ in range(max(n, 0))]
            if v.type == "Boolean":
                status_of(s.setBoolean, [v.valueReference], [bool(x) for x in values])
            else:
                status_of(s.setFloat64, [v.valueReference], values)
        elif r < 0.70:
            v = rng.choice(variables)
            vr = v.valueReference if rng.random() < 0.95 else rng.choice([10_000, 2**32 - 1])
            n = size.get(vr, 1) + (0 if rng.random() < 0.9 else 1)
            getter = rng.choice([s.getFloat64, s.getInt32, s.getBoolean, s.getInt8, s.getString])
            status_of(getter, [vr], n)
        elif r < 0.73:
            v = rng.choice(variables)
            n = size[v.valueReference]
            values = (fmi3Float64 * n)()
            orders = (fmi3Int32 * 1)(rng.choice([0, 1, 2, 3]))
            status_of(
                s.fmi3GetOutputDerivatives,
                s.component,
                (fmi3ValueReference * 1)(v.valueReference),
                1,
                orders,
                values,
                n,
            )
        elif r < 0.80:
            fmu_state, st = status_of(s.getFMUState)
            if st == 0:
                state["states"].append((fmu_state, state["t"]))
                blob, st = status_of(s.serializeFMUState, fmu_state)
                if st == 0:
                    state["blobs"].append(blob)
        elif r < 0.86 and state["states"]:
            fmu_state, t = rng.choice(state["states"])
            if status_of(s.setFMUState, fmu_state)[1] == 0:
                state["t"] = t
        elif r < 0.90 and state["blobs"]:
            blob = rng.choice(state["blobs"])
            if rng.random() < 0.7:
                blob = _mutate(rng, blob)
            status_of(s.deserializeFMUState, blob)
        elif r < 0.92:
            if status_of(s.reset)[1] == 0:
                state["t"] = 0.0
        elif r < 0.93:
            status_of(s.terminate)
        elif r < 0.935:
            for fmu_state, _ in state["states"]:
                status_of(s.freeFMUState, fmu_state)
            state["slave"] = None
            s.freeInstance()
            new_instance()
    if state["slave"] is not None:
        state["slave"].freeInstance()
    return {"seed": seed, "counts": counts, "problems": problems[:20]}


def run_child(fmu: str, seed: int, calls: int, timeout: float) -> dict:
    cmd = [sys.executable, __file__, "--child", "--fmu", fmu, "--seed", str(seed), "--calls", str(calls)]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"seed": seed, "problems": [f"seed {seed}: no answer in {timeout} s (hang)"], "counts": {}}
    if r.returncode != 0:
        tail = (r.stderr or "").strip().splitlines()[-3:]
        return {"seed": seed, "problems": [f"seed {seed}: the child died (exit {r.returncode}): {tail}"], "counts": {}}
    return json.loads(r.stdout.strip().splitlines()[-1])


def fuzz(fmu: str, seed: int, batches: int, calls: int, timeout: float = 300.0, verbose: bool = True) -> dict:
    results = [run_child(fmu, seed + b, calls, timeout) for b in range(batches)]
    problems = [p for r in results for p in r["problems"]]
    totals: dict[str, int] = {}
    for r in results:
        for k, v in r["counts"].items():
            totals[k] = totals.get(k, 0) + v
    if verbose:
        for r in results:
            print(f"batch seed {r['seed']}: {r['counts']} problems {len(r['problems'])}")
        print(f"total: {totals}; {len(problems)} problems")
    return {"totals": totals, "problems": problems}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--fmu", default=str(Path(__file__).resolve().parents[2] / "target/fmu/StickSlipManipulator-fmi3.fmu")
    )
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--batches", type=int, default=4)
    p.add_argument("--calls", type=int, default=2000)
    p.add_argument("--timeout", type=float, default=300.0)
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.child:
        print(json.dumps(run_batch(a.fmu, a.seed, a.calls)))
        return 0
    result = fuzz(a.fmu, a.seed, a.batches, a.calls, a.timeout)
    for problem in result["problems"]:
        print(problem)
    return 1 if result["problems"] else 0


if __name__ == "__main__":
    sys.exit(main())
