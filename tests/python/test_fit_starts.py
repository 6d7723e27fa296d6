"""How the fit's stages end, its starts meet and its tolerance checks stop (stickslip.fit.solve,
stickslip.fit), no FMU involved:

* ``settled``: the Gauss-Newton step in standard errors is, on a linear model, exactly the
  distance to the least-squares solution over its closed-form standard errors; a parameter the
  gradient holds at a bound is left out; a singular model never counts as settled;
* ``robust_cost`` is scipy's cost for every robust loss (least_squares at its answer);
* ``_Meeting``: which start merges into which does not depend on the order in which their
  threads end a stage (the better start, by its cost at its start point, is kept); a merged start
  goes on from its own start point where that is lower than where the start it joined ended the
  continuation, and from where it merged where that start failed;
* ``_tighten``: a tighter error tolerance is tried again only where the estimates move there,
  or where the last tightening at least halved how much the standard errors depend on the
  Jacobian's step.
"""

from __future__ import annotations

import math
import random
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import least_squares

from stickslip.fit.solve import (
    BEHIND,
    MEET,
    SETTLED,
    STEP_FACTORS,
    StartResult,
    _continued,
    _Meeting,
    settled,
    single_factors,
)
from stickslip.fit.uncertainty import robust_cost


def _linear(seed: int, m: int = 200, p: int = 3):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, p)) * rng.uniform(0.5, 20.0, p)
    z_true = rng.uniform(0.3, 0.7, p)
    b = A @ z_true + rng.standard_normal(m)
    return A, b


@pytest.mark.parametrize("seed", range(5))
def test_settled_is_the_distance_to_the_least_squares_answer_in_its_standard_errors(seed):
    A, b = _linear(seed)
    z_hat = np.linalg.lstsq(A, b, rcond=None)[0]
    m, p = A.shape
    rng = np.random.default_rng(100 + seed)
    z = z_hat + 0.01 * rng.standard_normal(p)
    r = A @ z - b
    shift, se = settled(A, r, z)
    # σ̂² from the residuals at z (≥ the minimum's), capped at 1: the residuals are normalized.
    scale = min(1.0, float(r @ r) / (m - p))
    se_expected = np.sqrt(np.diag(np.linalg.inv(A.T @ A)) * scale)
    assert np.allclose(se, se_expected, rtol=1e-10, atol=0)
    assert shift == pytest.approx(float(np.max(np.abs(z_hat - z) / se_expected)), rel=1e-9)
    # At the answer itself the step is zero to rounding.
    shift0, _ = settled(A, A @ z_hat - b, z_hat)
    assert shift0 < 1e-9


def test_settled_leaves_out_a_parameter_the_gradient_holds_at_its_bound():
    A, b = _linear(7)
    z_hat = np.linalg.lstsq(A, b, rcond=None)[0]
    # Parameter 0 at its lower bound, the unconstrained answer below it: the gradient pushes
    # it out, so the step is that of the other two with parameter 0 held at 0.
    b = b + A[:, 0] * (-z_hat[0] - 0.2)
    z = np.array([0.0, 0.5, 0.5])
    r = A @ z - b
    assert (A.T @ r)[0] > 0  # the cost falls outward
    shift, se = settled(A, r, z)
    sub = np.linalg.lstsq(A[:, 1:], b, rcond=None)[0]
    assert math.isinf(se[0]) and np.all(np.isfinite(se[1:]))
    assert shift == pytest.approx(float(np.max(np.abs(sub - z[1:]) / se[1:])), rel=1e-9)
    # Pulled inward instead, parameter 0 is free again.
    r_in = A @ np.array([0.0, 0.5, 0.5]) - (b + A[:, 0] * 1.0)
    assert (A.T @ r_in)[0] < 0
    assert np.isfinite(settled(A, r_in, z)[1][0])


def test_a_singular_model_never_settles():
    A, b = _linear(3)
    A[:, 2] = A[:, 1]
    shift, _ = settled(A, A @ np.full(3, 0.5) - b, np.full(3, 0.5))
    assert math.isinf(shift) or shift > max(SETTLED.values())


@pytest.mark.parametrize("loss", ["linear", "soft_l1", "huber", "cauchy", "arctan"])
def test_robust_cost_is_least_squares_own(loss):
    A, b = _linear(11)
    b[::17] += 25.0  # outliers
    res = least_squares(lambda z: A @ z - b, np.full(3, 0.5), loss=loss, f_scale=1.7)
    assert robust_cost(res.fun, loss, 1.7) == pytest.approx(res.cost, rel=1e-12)


# ---------------------------------------------------------------------------
# The meeting of the starts


def _start(origin: str, start_cost: float, z, se=0.01) -> StartResult:
    s = StartResult({}, origin)
    s.start_cost = start_cost
    s.z_start = np.array([0.9, 0.9])
    s.z = np.array(z, dtype=np.float64)
    s.se = np.full(2, se)
    s.ms_cost = start_cost
    return s


def _stage(starts: list, order: list, seed: int) -> dict:
    """Each start ends stage 0 in its own thread, in ``order`` with random delays."""
    meeting = _Meeting(starts)
    outcome = {}
    rng = random.Random(seed)
    delays = {id(s): 0.002 * k + 0.001 * rng.random() for k, s in enumerate(order)}

    def end(s):
        time.sleep(delays[id(s)])
        outcome[s.origin] = meeting.after_stage(s, 0, 0.1, lambda line: None)
        if outcome[s.origin]:
            meeting.end(s)

    threads = [threading.Thread(target=end, args=(s,)) for s in starts]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    return {s.origin: (outcome[s.origin], s.merged_into.origin if s.merged_into else None) for s in starts}


@pytest.mark.parametrize("seed", range(6))
def test_which_start_merges_does_not_depend_on_which_thread_ends_first(seed):
    near = 0.4 * MEET * 0.01  # within MEET standard errors
    far = 3.0 * MEET * 0.01
    outcomes = []
    for order in ([0, 1, 2, 3], [3, 2, 1, 0], [2, 0, 3, 1]):
        starts = [
            _start("initial", 50.0, [0.5, 0.5]),
            _start("equation-error", 10.0, [0.5 + near, 0.5]),  # the best at its start
            _start("latin hypercube 1", 80.0, [0.5, 0.5 + far]),
            _start("latin hypercube 2", 30.0, [0.5 - near, 0.5 + far]),
        ]
        outcomes.append(_stage(starts, [starts[k] for k in order], seed))
    assert outcomes[0] == outcomes[1] == outcomes[2], outcomes
    got = outcomes[0]
    assert got["equation-error"] == (True, None)
    assert got["initial"] == (False, "equation-error")
    # 2 is 3 SE from everyone in z[1] but within MEET of 3... which is ranked before it (30 < 80).
    assert got["latin hypercube 2"] == (True, None)
    assert got["latin hypercube 1"] == (False, "latin hypercube 2")


def test_a_merged_start_goes_on_from_its_start_point_where_that_is_lower():
    kept = _start("equation-error", 10.0, [0.5, 0.5])
    merged = _start("initial", 5.0, [0.5, 0.5])  # ranked later by hand below
    meeting = _Meeting([kept, merged])
    meeting.ahead = {id(kept): [], id(merged): [kept]}
    assert meeting.after_stage(kept, 0, 0.1, lambda line: None)
    assert not meeting.after_stage(merged, 0, 0.1, lambda line: None)
    kept.continuation_cost = 7.0  # worse than the merged start's own start point (5)
    meeting.continued(kept)
    assert meeting.revive(merged, lambda line: None)
    assert merged.status == "" and merged.z is merged.z_start and merged.continuation_cost == 7.0
    # A start point worse than the continuation's end: it stays merged.
    again = _start("latin hypercube 1", 9.0, [0.5, 0.5])
    meeting = _Meeting([kept, again])
    meeting.ahead = {id(kept): [], id(again): [kept]}
    meeting.after_stage(kept, 0, 0.1, lambda line: None)
    assert not meeting.after_stage(again, 0, 0.1, lambda line: None)
    assert not meeting.revive(again, lambda line: None) and again.status == "merged"


def test_a_start_merged_into_one_that_failed_goes_on_from_where_it_merged():
    kept = _start("equation-error", 10.0, [0.5, 0.5])
    merged = _start("initial", 50.0, [0.5, 0.5])
    meeting = _Meeting([kept, merged])
    assert meeting.after_stage(kept, 0, 0.1, lambda line: None)
    assert not meeting.after_stage(merged, 0, 0.1, lambda line: None)
    at = merged.z.copy()
    kept.status = "failed"
    meeting.end(kept)
    assert meeting.revive(merged, lambda line: None)
    assert merged.status == "" and np.array_equal(merged.z, at)


@pytest.mark.parametrize(
    "se_change, previous, shift, expected",
    [
        (0.05, None, 0.1, (False, False)),  # nothing moves: the answer stands
        (0.05, None, 0.5, (True, False)),  # the estimates move at the tighter tolerance
        (0.5, None, 0.0, (True, False)),  # step-dependent at the first check: try the tighter one
        (0.2, 0.5, 0.0, (True, False)),  # it shrank to less than half: the FMU's noise, go on
        (0.3, 0.5, 0.0, (False, True)),  # it did not: not the noise, stop (warned)
        (0.99, 0.004, 0.0, (False, True)),  # it grew
        (0.3, 0.5, 0.4, (True, True)),  # the shift alone asks for the refit
        (0.08, 0.5, 0.0, (False, False)),  # below SE_STEP_CHANGE: done
    ],
)
def test_a_tighter_tolerance_is_tried_again_only_where_the_last_one_helped(se_change, previous, shift, expected):
    from stickslip.fit import SE_STEP_CHANGE, SHIFT_LIMIT, _tighten

    assert SE_STEP_CHANGE == 0.10 and SHIFT_LIMIT == 0.3
    assert _tighten(se_change, previous, shift) == expected


def test_a_start_far_behind_a_better_ranked_one_at_a_stage_is_abandoned():
    """Its stage cost more than BEHIND times that of a start ranked before it: abandoned, with
    both costs in its message; just under BEHIND times: it goes on; the best-ranked start is
    never abandoned, whatever the others' costs."""
    lead = _start("equation-error", 10.0, [0.5, 0.5])
    near = _start("initial", 20.0, [0.2, 0.2])
    far = _start("latin hypercube 1", 30.0, [0.8, 0.8])
    lead.ms_cost, near.ms_cost, far.ms_cost = 100.0, 0.99 * BEHIND * 100.0, 1.01 * BEHIND * 100.0
    meeting = _Meeting([lead, near, far])
    assert meeting.after_stage(lead, 0, 0.1, lambda line: None)
    assert meeting.after_stage(near, 0, 0.1, lambda line: None)
    assert not meeting.after_stage(far, 0, 0.1, lambda line: None)
    assert far.status == "abandoned" and math.isinf(far.cost)
    assert "cost 1010 is 10.1 times that of start 'equation-error' (100)" in far.message, far.message
    # The leader at a stage where a later start is far better: it goes on all the same.
    lead.ms_cost = 1e9
    assert meeting.after_stage(lead, 1, 0.3, lambda line: None)


def test_a_start_merged_into_one_later_abandoned_stays_merged():
    lead = _start("equation-error", 10.0, [0.1, 0.1])
    kept = _start("initial", 20.0, [0.5, 0.5])
    merged = _start("latin hypercube 1", 30.0, [0.5, 0.5])
    meeting = _Meeting([lead, kept, merged])
    for s in (lead, kept):
        assert meeting.after_stage(s, 0, 0.1, lambda line: None)
    assert not meeting.after_stage(merged, 0, 0.1, lambda line: None) and merged.merged_into is kept
    lead.ms_cost, kept.ms_cost = 1.0, 100.0
    assert meeting.after_stage(lead, 1, 0.3, lambda line: None)
    assert not meeting.after_stage(kept, 1, 0.3, lambda line: None) and kept.status == "abandoned"
    assert not meeting.revive(merged, lambda line: None) and merged.status == "merged"


@pytest.mark.parametrize(("continuation_cost", "from_continuation"), [(7.0, True), (10.0, True), (12.0, False)])
def test_single_shooting_skips_the_coarsest_step_only_from_where_the_continuation_ended(
    continuation_cost, from_continuation
):
    """A start whose continuation ended at a single-shooting cost no higher than its start
    point's goes on from there with the steps after the coarsest; one that goes back to its
    start point (the continuation made it worse) takes them all, as does a start never
    continued (a revived or single-shooting start)."""
    s = _start("equation-error", 10.0, [0.5, 0.5])
    assert single_factors(s) == STEP_FACTORS  # not continued
    _continued(SimpleNamespace(cost=lambda z: continuation_cost), s)
    assert s.from_continuation is from_continuation
    if from_continuation:
        assert np.array_equal(s.z, [0.5, 0.5]) and single_factors(s) == STEP_FACTORS[1:]
    else:
        assert s.z is s.z_start and single_factors(s) == STEP_FACTORS
