"""No global mutable state: instances in parallel threads give the results of one.

fmpy calls the FMU through ctypes.CDLL, which releases the GIL for the duration of
each foreign call, so two Python threads really run doStep concurrently (the
timing is printed; it is not asserted, CI machines vary).
"""

import threading
import time

import numpy as np

from helpers import Slave, input_vector

STEPS = 400  # 0.4 s of the reference motion, through the first stick-slip phases
VARIANTS = {
    "reference": {},
    # a different parameter set in the other instance: any shared state would show
    "low-friction": {"mu_k[3]": 0.1, "mu_s[3]": 0.1, "mu_k[1]": 0.1, "mu_s[1]": 0.1},
}


def _run(name, start_values, steps=STEPS):
    with Slave(name) as s:
        s.initialize(start_values=start_values)
        rows = [s.outputs()]
        for k in range(steps):
            t = k * 1e-3
            s.set_inputs(input_vector(t))
            s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3)
            rows.append(s.outputs())
        return np.array(rows)


def test_two_instances_in_threads_equal_sequential_runs():
    """Two instances (reference parameters and low friction mu = 0.1) run in two threads
    at the same time give outputs identical, bit for bit, to the same two runs made one
    after the other in the main thread; and the two variants do differ (so a mix-up
    would be seen)."""
    t0 = time.perf_counter()
    sequential = {label: _run(f"seq-{label}", sv) for label, sv in VARIANTS.items()}
    t_seq = time.perf_counter() - t0

    results, errors = {}, []

    def worker(label, sv):
        try:
            results[label] = _run(f"thr-{label}", sv)
        except BaseException as e:  # noqa: BLE001 -- any failure in a thread, reported below
            errors.append((label, repr(e)))

    threads = [threading.Thread(target=worker, args=(label, sv)) for label, sv in VARIANTS.items()]
    t0 = time.perf_counter()
    for th in threads:
        th.start()
    for th in threads:
        th.join(timeout=300)
    t_thr = time.perf_counter() - t0
    print(f"two runs of {STEPS} steps: sequential {t_seq:.2f} s, in two threads {t_thr:.2f} s")
    assert not errors, errors
    for label in VARIANTS:
        assert results[label].tobytes() == sequential[label].tobytes(), label
    assert not np.array_equal(sequential["reference"], sequential["low-friction"])


def test_many_instances_interleaved():
    """Four instances stepped alternately in one thread (step k of each, then k+1...) give
    the same outputs as one instance alone: instances share nothing."""
    alone = _run("alone", {}, steps=150)
    slaves = [Slave(f"il-{i}") for i in range(4)]
    try:
        for s in slaves:
            s.initialize()
        rows = [[s.outputs()] for s in slaves]
        for k in range(150):
            t = k * 1e-3
            for s, r in zip(slaves, rows, strict=True):
                s.set_inputs(input_vector(t))
                s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3)
                r.append(s.outputs())
    finally:
        for s in slaves:
            s.free()
    for r in rows:
        assert np.array(r).tobytes() == alone.tobytes()
