"""Debug logging: stick-slip transitions are logged in category logEvents.

A transition message reads "t = <time> s: joint <j> <from> -> <to>" with the phases
"stuck", "slipping (+)", "slipping (-)".
"""

import re

import numpy as np

from helpers import Slave

STEPS = 300  # 0.3 s of the reference motion: both joints break away, joint 3 sticks again
TRANSITION = re.compile(r"t = (\S+) s: joint (\d+) (stuck|slipping \([+-]\)) -> (stuck|slipping \([+-]\))")


def _run(s):
    """Steps of the reference motion; for each step, (outputs, log records made during it)."""
    per_step = []
    for k in range(STEPS):
        n = len(s.log.records)
        out = s.run_reference(k, 1)[0]
        per_step.append((out, s.log.records[n:]))
    return per_step


def test_transitions_logged_with_log_events_on():
    """With fmi2SetDebugLogging(on, ["logEvents"]) each doStep logs, in category logEvents and
    with status fmi2OK, the stick-slip transitions located inside it (time inside the step,
    1-based joint index). Replaying the logged transitions from the initial phases (joints 1
    and 3 stuck) gives exactly the stick[1], stick[3] outputs at every communication point;
    over 0.3 s both joints break away and joint 3 sticks again."""
    with Slave("events") as s:
        s.initialize()
        s.fmu.setDebugLogging(True, ["logEvents"])
        names = s.output_names()
        phase = {1: "stuck", 3: "stuck"}
        assert s.get("stick[1]") and s.get("stick[3]")
        seen = []
        for k, (out, records) in enumerate(_run(s)):
            t0, t1 = k * 1e-3, (k + 1) * 1e-3
            for _, status, category, message in records:
                m = TRANSITION.fullmatch(message)
                assert m, message
                assert category == "logEvents" and status == 0, (category, status, message)
                t, j, a, b = float(m.group(1)), int(m.group(2)), m.group(3), m.group(4)
                assert t0 - 1e-12 <= t <= t1 + 1e-12, message
                assert j in phase and phase[j] == a, (message, phase)
                phase[j] = b
                seen.append((j, a, b))
            for j in (1, 3):
                stuck = out[names.index(f"stick[{j}]")] == 1.0
                assert stuck == (phase[j] == "stuck"), (k, j, phase)
        assert (1, "stuck", "slipping (+)") in seen
        assert (3, "stuck", "slipping (+)") in seen
        assert (3, "slipping (+)", "stuck") in seen


def test_no_event_messages_without_debug_logging():
    """With debug logging off (the default of fmi2Instantiate with loggingOn = false) the
    first 0.1 s, which hold 4 transitions, send no message at all; after fmi2Reset and
    fmi2SetDebugLogging(on, []) the same 0.1 s send the 4 transitions (category logEvents);
    after another reset and fmi2SetDebugLogging(off, []) (the setting is kept across
    fmi2Reset) nothing again."""
    with Slave("quiet") as s:
        s.initialize()
        s.run_reference(0, 100)
        assert s.log.records == []

        s.fmu.reset()
        s.initialize()
        s.fmu.setDebugLogging(True, [])
        s.run_reference(0, 100)
        on = list(s.log.records)
        assert len(on) == 4 and all(c == "logEvents" for (_, _, c, _) in on), s.log.text()
        assert all(TRANSITION.fullmatch(m) for (_, _, _, m) in on)

        s.log.clear()
        s.fmu.reset()
        s.fmu.setDebugLogging(False, [])
        s.initialize()
        s.run_reference(0, 100)
        assert s.log.records == []


def test_logging_on_at_instantiation_and_log_all():
    """loggingOn = true at fmi2Instantiate gives the same event messages (the initial phases,
    then the transitions) as fmi2SetDebugLogging(on, ["logAll"]) right after a quiet
    instantiation, in the same order, and the outputs are not affected by logging."""
    with Slave("on", logging_on=True) as a, Slave("all") as b:
        b.fmu.setDebugLogging(True, ["logAll"])
        a.initialize()
        b.initialize()
        ra = a.run_reference(0, 120)
        rb = b.run_reference(0, 120)
        assert np.array_equal(ra, rb)
        ma = [m for m in a.log.messages("logEvents")]
        mb = [m for m in b.log.messages("logEvents")]
        assert len(ma) == 5 and ma == mb, (ma, mb)
        assert ma[0].startswith("t = 0 s: initialized")
