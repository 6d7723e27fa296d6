"""A step the engine cannot complete returns fmi2Discard and leaves the state at the
last good communication point (fmi2GetRealStatus(fmi2LastSuccessfulTime)); the master
can then change parameters (or reset) and go on.

All comparisons are with a clean instance run through the same reference motion:
"unchanged" and "continues like the clean run" mean bit for bit.
"""

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Discard, fmi2Error, fmi2LastSuccessfulTime, fmi2Terminated

from helpers import Slave, input_vector, reference_slave

K = 100  # step at which the trouble starts (t = 0.1 s: both flexible joints slipping)
MORE = 50


@pytest.fixture(scope="module")
def clean():
    """Outputs of a clean run after initialization and after each of K + MORE steps."""
    with reference_slave("clean") as s:
        return np.vstack([s.outputs(), s.run_reference(0, K + MORE)])


def _step(s, k):
    t = k * 1e-3
    s.set_inputs(input_vector(t))
    s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3)


def _discarded_step(s, k):
    """doStep k must be discarded; returns the FMICallException."""
    with pytest.raises(FMICallException) as info:
        _step(s, k)
    return info.value


def test_discard_from_tunable_parameters_then_continue(clean):
    """A kinetic coefficient above the static one in joint 3 (mu_k = 0.5 > mu_s = 0.2), set
    between steps at t = 0.1 s, each value in its range but the pair inconsistent: the next
    fmi2DoStep returns fmi2Discard with a logStatusDiscard message naming mu_s,
    fmi2LastSuccessfulTime is 0.1 s (to 1e-12), fmi2Terminated is false and every output is
    unchanged. The master sets the coefficient back to 0.2, repeats the step, and the 50
    steps after it equal the clean run bit for bit."""
    with reference_slave("tunable") as s:
        s.run_reference(0, K)
        before = s.outputs()
        assert np.array_equal(before, clean[K])
        s.set("mu_k[3]", 0.5)
        s.log.clear()
        e = _discarded_step(s, K)
        assert e.status == fmi2Discard
        assert abs(s.fmu.getRealStatus(fmi2LastSuccessfulTime) - K * 1e-3) <= 1e-12
        assert s.fmu.getBooleanStatus(fmi2Terminated) is False
        assert np.array_equal(s.outputs(), before)
        msgs = [m for (_, st, c, m) in s.log.records if st == fmi2Discard]
        assert msgs and "fmi2DoStep" in msgs[0] and "mu_s" in msgs[0], s.log.text()
        assert all(c == "logStatusDiscard" for (_, st, c, _) in s.log.records if st == fmi2Discard)

        s.set("mu_k[3]", 0.2)
        s.set("mu_s[3]", 0.2)
        after = s.run_reference(K, MORE)
        assert after.tobytes() == clean[K + 1 :].tobytes()


FIXED_STEPS = {"h_min": 2e-6, "h_max": 2e-6}


def test_discard_from_iteration_tolerance_then_reset(clean):
    """The discard's message names the joint and the cause.
    With fixed sub-steps (with error control the iteration tolerance is floored at
    1e-4 error_tolerance) and the fixed parameter `tolerance` set to 1e-300 the iteration
    cannot converge once a joint slips: some step k returns fmi2Discard,
    fmi2LastSuccessfulTime is t_k (to 1e-12) and the outputs are those of the clean
    fixed-step run at t_k. `tolerance` is fixed, so setting it now is refused (fmi2Error);
    the master resets, initializes with the defaults and runs like the clean run again."""
    with Slave("clean-fixed") as s:
        s.initialize(start_values=FIXED_STEPS)
        clean_fixed = np.vstack([s.outputs(), s.run_reference(0, K + MORE)])
    with Slave("tolerance") as s:
        s.initialize(start_values={"tolerance": 1e-300, **FIXED_STEPS})
        k = 0
        while True:
            assert k < K + MORE, "no discard"
            try:
                _step(s, k)
            except FMICallException as e:
                assert e.status == fmi2Discard
                break
            k += 1
        assert k > 0, "the very first step failed"
        assert abs(s.fmu.getRealStatus(fmi2LastSuccessfulTime) - k * 1e-3) <= 1e-12
        assert np.array_equal(s.outputs(), clean_fixed[k])
        # The message tells the truth: which joint, the cause (a tolerance rounding cannot
        # reach) and that a shorter communication step does not help.
        msgs = [m for (_, st, _, m) in s.log.records if st == fmi2Discard]
        assert msgs, s.log.text()
        for part in ("for joint ", "loosen `tolerance`", "a shorter communication step does not help"):
            assert part in msgs[0], msgs[0]
        with pytest.raises(FMICallException) as info:
            s.set("tolerance", 1e-10)
        assert info.value.status == fmi2Error
        s.fmu.reset()
        s.initialize()
        assert s.run_reference(0, K + MORE).tobytes() == clean[1:].tobytes()


def test_discard_then_restore_saved_state(clean):
    """After a discarded step the master restores an FMU state saved before the trouble
    (fmi2SetFMUstate also restores the tunable parameters) and continues like the clean run."""
    with reference_slave("restore") as s:
        s.run_reference(0, K)
        saved = s.fmu.getFMUstate()
        s.set("mu_k[3]", 0.5)
        assert _discarded_step(s, K).status == fmi2Discard
        s.fmu.setFMUstate(saved)
        s.fmu.freeFMUstate(saved)
        assert s.get("mu_k[3]") == 0.2
        assert s.run_reference(K, MORE).tobytes() == clean[K + 1 :].tobytes()


def test_mu_k_above_mu_s_between_steps_is_a_discard():
    """mu_k[3] = 0.3 > mu_s[3] = 0.2, set between steps (each value alone is in range), makes
    the next step impossible: it returns fmi2Discard (the step the engine cannot complete; not
    fmi2Error, after which an FMI 2.0 master may only reset, restore a state or free the
    instance), with fmi2LastSuccessfulTime at the last good point."""
    with reference_slave("mu") as s:
        s.run_reference(0, K)
        s.set("mu_k[3]", 0.3)
        e = _discarded_step(s, K)
        assert e.status == fmi2Discard
        assert abs(s.fmu.getRealStatus(fmi2LastSuccessfulTime) - K * 1e-3) <= 1e-12


def test_mu_k_above_mu_s_refused_and_correctable(clean):
    """The step after setting mu_k[3] = 0.3 > mu_s[3] = 0.2 is refused with a message naming
    mu_s and mu_k; time and outputs are unchanged and
    nothing of the refused step remains: after the master sets mu_k[3] back to 0.2 and
    repeats the step, the 50 steps equal the clean run bit for bit."""
    with reference_slave("mu2") as s:
        s.run_reference(0, K)
        before = s.outputs()
        s.set("mu_k[3]", 0.3)
        s.log.clear()
        e = _discarded_step(s, K)
        assert e.status == fmi2Discard
        assert any("mu_s" in m and "mu_k" in m for m in s.log.messages()), s.log.text()
        assert np.array_equal(s.outputs(), before)
        assert abs(s.fmu.getRealStatus(fmi2LastSuccessfulTime) - K * 1e-3) <= 1e-12
        s.set("mu_k[3]", 0.2)
        assert s.run_reference(K, MORE).tobytes() == clean[K + 1 :].tobytes()
