"""No leaks after fmi2FreeInstance / fmi2FreeFMUstate: the process's resident memory
does not grow over hundreds of instance and state life cycles."""

import gc

from helpers import Slave, reference_slave


def _rss_bytes():
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    import os

    return pages * os.sysconf("SC_PAGE_SIZE")


def _cycle():
    s = Slave("cycle")
    s.initialize()
    s.run_reference(0, 3)
    st = s.fmu.getFMUstate()
    data = s.fmu.serializeFMUstate(st)
    st2 = s.fmu.deSerializeFMUstate(data)
    s.fmu.freeFMUstate(st2)
    s.fmu.freeFMUstate(st)
    s.free()


def test_instances_and_states_do_not_leak():
    """400 cycles of instantiate, initialize, 3 steps, get/serialize/deserialize/free two FMU
    states, terminate and free grow the resident memory by less than 4 MB after a warm-up of
    50 cycles (a leaked instance of this model costs ~110 kB, so 350 of them would be ~38 MB).
    The library stays loaded by another open instance meanwhile."""
    with reference_slave("keeper"):
        for _ in range(50):
            _cycle()
        gc.collect()
        before = _rss_bytes()
        for _ in range(350):
            _cycle()
        gc.collect()
        grown = _rss_bytes() - before
    print(f"RSS growth over 350 cycles: {grown / 1e6:.2f} MB")
    assert grown < 4e6


def test_many_states_of_one_instance_do_not_leak():
    """5000 fmi2GetFMUstate/fmi2FreeFMUstate pairs on one instance grow RSS by less than 2 MB
    (a state of the reference model is ~1.2 kB: 5000 leaked ones would be ~6 MB)."""
    with reference_slave("states") as s:
        s.run_reference(0, 10)
        for _ in range(200):
            s.fmu.freeFMUstate(s.fmu.getFMUstate())
        before = _rss_bytes()
        for _ in range(5000):
            s.fmu.freeFMUstate(s.fmu.getFMUstate())
        grown = _rss_bytes() - before
    print(f"RSS growth over 5000 states: {grown / 1e6:.2f} MB")
    assert grown < 2e6
