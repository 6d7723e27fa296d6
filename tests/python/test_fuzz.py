"""The FMI call-sequence fuzzer (tests/python/fuzz_fmi.py) finds nothing: a short seeded run
in CI against the reference FMU, against the FMU of a URDF arm (the KUKA iiwa, 7 joints,
urdf_fmus.py), where the fuzzer also instantiates from mutated copies of the packaged URDF,
and against the FMU with motor drives (models/reference_rrpr_motor.toml, motor_fmus.py), where
it also makes calls aimed at the motors (tau_m and its derivatives, gear_ratio, the start
values, static_start, J_m, b_m, tau_c); the long one (>= 1e5 calls) is `python
tests/python/fuzz_fmi.py --calls 100000 --batches 50 --seed 1` (README, "Behaviour masters rely
on"), with `--fmu` for a URDF arm's or the motor FMU."""

import pytest

import fuzz_fmi
from helpers import require_fmu
from motor_fmus import require_motor_fmu
from urdf_fmus import require_iiwa_fmu

# CI's full run only (scripts/test.sh --quick leaves it out): the seeded FMI fuzz
pytestmark = pytest.mark.full

# fmu: (FMU, batches, calls per batch, least ok steps, least errors, least state
# mutations and restores, least refused URDF mutations, least calls aimed at motors). The
# iiwa's 4,000 calls take about 14 s (the reference's about 50 s: its steps are longer), the
# motor FMU's 2,000 about 6 s.
RUNS = {
    "reference": (require_fmu, 4, 1000, 200, 200, 10, 0, 0),
    "iiwa": (require_iiwa_fmu, 4, 1000, 200, 200, 10, 20, 0),
    "motor": (require_motor_fmu, 2, 1000, 100, 100, 10, 0, 60),
}


@pytest.mark.parametrize("fmu", list(RUNS))
def test_seeded_fuzz_run_finds_no_crash_hang_or_silent_non_finite_output(fmu):
    path, batches, calls, steps_ok, errors, states, corrupt, motor = RUNS[fmu]
    result = fuzz_fmi.fuzz(str(path()), seed=20261123, batches=batches, calls=calls, timeout=120, verbose=False)
    counts = result["counts"]
    print(f"fuzz counts ({fmu}):", counts)
    assert not result["violations"], "\n".join(result["violations"])
    assert counts["calls"] == batches * calls
    # The run reached what it is meant to test.
    assert counts["steps_ok"] > steps_ok and counts["errors"] > errors, counts
    assert counts["states_mutated"] > states and counts["states_restored"] > states, counts
    assert counts["corrupt_urdf_refused"] >= corrupt, counts
    assert counts["motor_calls"] >= motor, counts
    assert counts["experiments_ok"] >= 5, counts  # stickslip_run_experiment fuzzed too
