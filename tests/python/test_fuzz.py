"""The FMI call-sequence fuzzer (tests/python/fuzz_fmi.py) finds nothing: a short seeded run
in CI against the reference FMU and against the FMU of a URDF arm (the KUKA iiwa, 7 joints,
urdf_fmus.py), where the fuzzer also instantiates from mutated copies of the packaged URDF;
the long one (>= 1e5 calls) is `python tests/python/fuzz_fmi.py --calls 100000 --batches 50
--seed 1` (README, "Behaviour masters rely on"), with `--fmu` for a URDF arm's FMU."""

import pytest

import fuzz_fmi
from helpers import require_fmu
from urdf_fmus import require_iiwa_fmu

# fmu: (FMU, batches, calls per batch, least ok steps, least errors, least state
# mutations and restores, least refused URDF mutations). The iiwa's 4,000 calls take about
# 14 s (the reference's about 50 s: its steps are longer).
RUNS = {
    "reference": (require_fmu, 4, 1000, 200, 200, 10, 0),
    "iiwa": (require_iiwa_fmu, 4, 1000, 200, 200, 10, 20),
}


@pytest.mark.parametrize("fmu", list(RUNS))
def test_seeded_fuzz_run_finds_no_crash_hang_or_silent_non_finite_output(fmu):
    path, batches, calls, steps_ok, errors, states, corrupt = RUNS[fmu]
    result = fuzz_fmi.fuzz(str(path()), seed=20261123, batches=batches, calls=calls, timeout=120, verbose=False)
    counts = result["counts"]
    print(f"fuzz counts ({fmu}):", counts)
    assert not result["violations"], "\n".join(result["violations"])
    assert counts["calls"] == batches * calls
    # The run reached what it is meant to test.
    assert counts["steps_ok"] > steps_ok and counts["errors"] > errors, counts
    assert counts["states_mutated"] > states and counts["states_restored"] > states, counts
    assert counts["corrupt_urdf_refused"] >= corrupt, counts
