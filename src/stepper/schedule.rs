//! The sub-step schedule of a run, for internal numerical differentiation
//! (Bock 1981): a primal run records where each of its sub-steps was aimed
//! and whether it ended at a located event; runs of nearby parameters then
//! replay that schedule — the same sub-step targets, no error control — with
//! the Newmark iteration and the event location taken to rounding level.
//! With the step sizes and the stick/slip decisions frozen, the discrete
//! scheme is a smooth function of the parameters (an event's instant still
//! moves with them: it is located afresh inside the same sub-step, which is
//! its saltation), so differences over a small parameter change are its
//! exact derivative up to rounding, not the error control's noise.
//!
//! A replay whose event pattern departs from the plan (an event in a
//! sub-step that had none, none where one was, a sub-step solved with other
//! phases) counts a departure: its differences are then not a derivative
//! of the primal's scheme, and the caller falls back.

use super::state::Phase;
use std::sync::Arc;

/// One sub-step of a recorded run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedSubStep {
    /// The time the sub-step was solved to before an event shortened it:
    /// the error control's choice, the interval's end, or a point of the
    /// fixed grid.
    pub target: f64,
    /// It ended at a located event.
    pub event: bool,
    /// The phases of every coordinate it was solved with ([`phase_code`]).
    pub phases: u64,
}

/// The Newmark iteration's relative residual in a replay, where the
/// settings' is larger (the f64 run's is 10⁻⁴ of the error tolerance, 5·10⁻⁸
/// by default): differences over a parameter change of 10⁻⁶ then carry an
/// iteration error of about 10⁻⁴ of their value, well below what a
/// Gauss–Newton step or a standard error notices. Iterating to 10⁻¹² costs
/// more (measured once, 2 s of motion on a loaded machine: a run and two
/// replays on 2 threads 0.73 s at 10⁻¹², 0.41 s at the run's own tolerance,
/// the run alone 0.19 s).
pub(crate) const REPLAY_ITERATION_TOLERANCE: f64 = 1e-10;
/// The fraction of a sub-step to which a replay locates an event (the f64
/// run's: 10⁻⁷).
pub(crate) const REPLAY_EVENT_RESOLUTION: f64 = 1e-12;

/// What the integrator does with its sub-steps' targets.
#[derive(Debug, Clone, Default)]
pub(crate) enum Schedule {
    /// The targets are chosen as usual and not kept.
    #[default]
    Free,
    /// Chosen as usual and appended.
    Recording(Vec<PlannedSubStep>),
    /// Taken from the plan, in order; `departures` counts where the run's
    /// events left it.
    Replaying { plan: Arc<[PlannedSubStep]>, next: usize, departures: usize },
}

impl Schedule {
    /// Notes a solved sub-step aimed at `target`, with an event inside it
    /// or not, solved with `phases`: appended while recording; compared
    /// with the plan while replaying.
    #[inline(always)]
    pub(crate) fn note(&mut self, target: f64, event: bool, phases: &[Phase]) {
        match self {
            Schedule::Free => {}
            Schedule::Recording(plan) => plan.push(PlannedSubStep { target, event, phases: phase_code(phases) }),
            // A sub-step halved for want of convergence was aimed elsewhere.
            Schedule::Replaying { plan, next, departures } => match plan.get(*next) {
                Some(p)
                    if p.event == event
                        && p.phases == phase_code(phases)
                        && (p.target - target).abs() <= 1e-12 * p.target.abs().max(1.0) => {}
                _ => *departures += 1,
            },
        }
    }

    pub(crate) fn is_replaying(&self) -> bool {
        matches!(self, Schedule::Replaying { .. })
    }

    /// The next planned sub-step of a replay, if any is left.
    pub(crate) fn planned(&self) -> Option<PlannedSubStep> {
        match self {
            Schedule::Replaying { plan, next, .. } => plan.get(*next).copied(),
            _ => None,
        }
    }

    /// On to the next planned sub-step.
    pub(crate) fn advance(&mut self) {
        if let Schedule::Replaying { next, .. } = self {
            *next += 1;
        }
    }

    /// The replay left its plan here.
    pub(crate) fn depart(&mut self) {
        if let Schedule::Replaying { departures, .. } = self {
            *departures += 1;
        }
    }

    /// The departures of a replay so far (0 otherwise).
    pub(crate) fn departures(&self) -> usize {
        match self {
            Schedule::Replaying { departures, .. } => *departures,
            _ => 0,
        }
    }
}

/// The phases of every coordinate as one number: two bits a coordinate
/// (prescribed, stuck, slipping −, slipping +), the 33rd and later folded
/// in by rotation, so that equal phases give equal codes and a change of one
/// coordinate's phase always changes the code.
pub(crate) fn phase_code(phases: &[Phase]) -> u64 {
    let mut code = 0u64;
    for (i, p) in phases.iter().enumerate() {
        let bits = match p {
            Phase::Prescribed => 0u64,
            Phase::Stuck => 1,
            Phase::Slipping(d) if *d < 0 => 2,
            Phase::Slipping(_) => 3,
        };
        code ^= bits.rotate_left((2 * (i % 32)) as u32);
    }
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_single_phase_change_changes_the_code() {
        let all = [Phase::Prescribed, Phase::Stuck, Phase::Slipping(-1), Phase::Slipping(1)];
        for n in [1, 3, 7, 32, 40] {
            let base = vec![Phase::Stuck; n];
            let c0 = phase_code(&base);
            for i in 0..n {
                for p in all {
                    if p == Phase::Stuck {
                        continue;
                    }
                    let mut other = base.clone();
                    other[i] = p;
                    assert_ne!(phase_code(&other), c0, "n = {n}, coordinate {i} → {p:?}");
                }
            }
        }
    }
}
