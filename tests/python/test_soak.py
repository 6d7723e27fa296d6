"""Soak (tests/python/soak.py): instantiate/free cycles and a long run in one process keep
the resident memory flat. CI runs 1,500 cycles and 60 s of simulated time; the README's
long version is 10^4 cycles and 600 s (`python tests/python/soak.py --cycles 10000
--seconds 600`)."""

import soak
from helpers import require_fmu


def test_resident_memory_stays_flat():
    r = soak.soak(str(require_fmu()), cycles=1500, seconds=60.0)
    cycles, run = r["samples"]["cycles"], r["samples"]["run"]
    print("cycles:", cycles)
    print("run:", run)
    assert r["finite"]
    assert min(r["n_stick"]) >= 2, "the arm kept sticking and slipping"
    # The allocators of the host (Python's, glibc's) settle in page steps over the
    # first few hundred cycles; a leak of 400 bytes per cycle would add 300 KiB over the
    # second half, one of 8 bytes per step 240 KiB over the run's.
    assert soak.growth_kib(cycles) <= 256, cycles
    assert soak.growth_kib(run) <= 64, run
