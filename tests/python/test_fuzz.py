"""The FMI call-sequence fuzzer (tests/python/fuzz_fmi.py) finds nothing: a short seeded run
in CI; the long one (>= 1e5 calls) is `python tests/python/fuzz_fmi.py --calls 100000
--batches 50 --seed 1` (README, "Behaviour masters rely on")."""

import fuzz_fmi
from helpers import require_fmu


def test_seeded_fuzz_run_finds_no_crash_hang_or_silent_non_finite_output():
    result = fuzz_fmi.fuzz(str(require_fmu()), seed=20261123, batches=4, calls=1000, timeout=120, verbose=False)
    counts = result["counts"]
    print("fuzz counts:", counts)
    assert not result["violations"], "\n".join(result["violations"])
    assert counts["calls"] == 4000
    # The run reached what it is meant to test.
    assert counts["steps_ok"] > 200 and counts["errors"] > 200, counts
    assert counts["states_mutated"] > 10 and counts["states_restored"] > 10, counts
