//! The sub-step integrator: the Newmark sub-steps of a communication
//! interval, of fixed length or error-controlled, with stick–slip switching
//! (study eqs. 3.16–3.18), the edges of the drive clearances and the release
//! of a damped drive's flank (2.1) each located inside the sub-step; the
//! phase decisions and their log; and the energy account of accepted
//! sub-steps. [`Integrator`] owns what this needs (model, workspace, state,
//! inputs, the Newmark solver); the [`Simulator`](super::Simulator) owns an
//! integrator and adds initialization, checks and the reported quantities.

use super::error_control::{error_ratio, optimal_factor, GROWTH_MAX};
use super::inputs::InputPolynomial;
use super::newmark::{NewmarkSolver, SubStep};
use super::schedule::Schedule;
use super::state::{Phase, State};
use crate::data::Data;
use crate::error::StepError;
use crate::forces::drive::drive_force;
use crate::model::{IntegratorSettings, Model};

/// A phase change of one coordinate, for event logs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Time of the change, s.
    pub time: f64,
    /// Coordinate, 0-based: joint `joint` for `joint` < n, else the rotor
    /// of the (`joint` − n)-th motor drive (see [`State`]).
    pub joint: usize,
    /// Phase before.
    pub from: Phase,
    /// Phase after.
    pub to: Phase,
    /// Drive force F^d at the transition; for a rotor the motor torque τ_m.
    pub drive_force: f64,
}

/// How many transitions are kept between two calls of
/// [`Simulator::clear_transitions`]; later ones are only counted.
pub const TRANSITION_LOG_CAPACITY: usize = 256;

/// The model in use, its workspace, the state and everything a sub-step
/// reads or keeps: the input polynomials, the Newmark solver, the phase
/// decisions of the current instant and the transition log.
#[derive(Debug, Clone)]
pub(crate) struct Integrator {
    pub(crate) model: Model,
    pub(crate) data: Data,
    pub(crate) state: State,
    /// Snapshot at the start of the current sub-step: only the fields that
    /// [`State::take_step_start`] takes are current.
    pub(crate) start: State,
    /// The drive inputs q*, q̇*, q̈* (prescribed q of rigid joints), per joint.
    pub(crate) inputs: InputPolynomial,
    /// The motor torques τ_m of the motor drives, per joint.
    pub(crate) torques: InputPolynomial,
    /// The Newmark iteration's workspace.
    pub(crate) solver: NewmarkSolver,
    /// For each coordinate, the instant (see `instant`) at which its phase was
    /// last decided.
    pub(crate) decided: Vec<u64>,
    /// Number of the current instant of phase decisions; a new one starts
    /// when time moves on, so no joint counts as decided there.
    pub(crate) instant: u64,
    pub(crate) transitions: Vec<Transition>,
    pub(crate) transitions_dropped: usize,
    /// The last sub-step ended at a located event: the decisions of the
    /// current instant are of the current time (read by FMI 3.0's
    /// `carry_decisions`, src/stepper/substep.rs).
    #[cfg_attr(not(feature = "fmi3"), allow(dead_code))]
    pub(crate) located_now: bool,
    /// Whether the sub-steps' targets are chosen, recorded or replayed
    /// (see [`Schedule`]).
    pub(crate) schedule: Schedule,
    /// A transition is located to this fraction of the sub-step:
    /// [`EVENT_RESOLUTION`], or [`REPLAY_EVENT_RESOLUTION`](super::schedule::REPLAY_EVENT_RESOLUTION) in a replay.
    pub(crate) event_resolution: f64,
}

/// A transition is located to this fraction of the sub-step.
const EVENT_RESOLUTION: f64 = 1e-7;
/// How often a sub-step is halved when its iteration does not converge.
const MAX_HALVINGS: usize = 12;
/// Bound on the regula falsi iterations that locate a transition.
const MAX_LOCATE_ITERATIONS: usize = 60;

/// Something that ends a sub-step at the instant it happens.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Event {
    /// Joint `.0`'s phase margin (3.16) turns negative: a slipping joint's
    /// velocity crosses zero, or a stuck joint's static friction is exceeded.
    Phase(usize),
    /// Joint `.0`'s deflection crosses an edge of its clearance, where δ of
    /// (2.1) switches; `.1` is the sign of the clearance margin before.
    Clearance(usize, f64),
    /// The flank force σ·F of joint `.0`'s drive changes sign with the
    /// clearance taken up: the flank releases (or engages again) where (2.1)
    /// would pull (see [`crate::forces::drive`]); `.1` is its sign before.
    Release(usize, f64),
}

/// Whether a communication interval goes on after a sub-step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// On to the interval's end.
    Continue,
    /// The interval ends here (FMI 3.0's early return).
    Stop,
}

/// What runs after each accepted sub-step inside a communication interval
/// (not after the last one, which ends the interval): see
/// [`Simulator::advance_observed`](super::Simulator::advance_observed).
pub(crate) trait AfterSubStep {
    /// False for [`NoObserver`]: the stepping loop then compiles to what it
    /// is without an observer.
    const ACTIVE: bool = true;
    /// Called with the integrator at the end of a sub-step; `event` when the
    /// sub-step ended at an event (see [`Integrator::substep`]).
    fn substep_finished(&mut self, core: &mut Integrator, event: bool) -> Result<Flow, StepError>;
}

/// The observer of [`Simulator::advance`](super::Simulator::advance): none.
pub(crate) struct NoObserver;

impl AfterSubStep for NoObserver {
    const ACTIVE: bool = false;
    #[inline(always)]
    fn substep_finished(&mut self, _: &mut Integrator, _: bool) -> Result<Flow, StepError> {
        Ok(Flow::Continue)
    }
}

/// How [`Integrator::substep`] chooses its length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum StepControl {
    /// A sub-step of the fixed grid: its length is not controlled.
    Fixed,
    /// Error-controlled; `shortened` when the interval's end (not the error
    /// control) set the target.
    Adaptive { shortened: bool },
}

impl Integrator {
    /// An integrator for `model` (validated by the caller), at rest at q = 0.
    pub(crate) fn new(model: Model) -> Integrator {
        let n = model.nq();
        let state = State::new(&model);
        Integrator {
            data: Data::new(&model),
            start: state.clone(),
            state,
            inputs: InputPolynomial::new(n),
            torques: InputPolynomial::new(n),
            solver: NewmarkSolver::new(&model),
            decided: vec![0; model.n_coordinates()],
            instant: 1,
            transitions: Vec::with_capacity(TRANSITION_LOG_CAPACITY),
            transitions_dropped: 0,
            located_now: false,
            schedule: Schedule::Free,
            event_resolution: EVENT_RESOLUTION,
            model,
        }
    }

    /// Takes one sub-step towards time `t_target`. With error control, a
    /// sub-step whose local error exceeds the tolerance is retried shorter
    /// (down to h_min), and the next length is proposed. If a joint's margin
    /// changes sign inside it (a slipping joint's velocity crosses zero, a
    /// stuck joint's static friction is exceeded, a drive's deflection
    /// crosses an edge of its clearance), the sub-step is shortened to end
    /// just past that instant, located by Illinois regula falsi; a joint's
    /// phase is decided there.
    ///
    /// Returns whether the sub-step ended at an event: a located phase,
    /// clearance or release event, or a phase change at its start.
    #[inline(always)]
    pub(crate) fn substep(&mut self, t_target: f64, control: StepControl) -> Result<bool, StepError> {
        let changes = self.transition_count();
        // A phase change that could not happen at the previous instant (a
        // marginal slip) is tried again at this one.
        self.instant += 1;
        self.settle_phases()?;
        self.start.take_step_start(&mut self.state);
        let t0 = self.start.time;
        let settings = self.model.integrator;
        let mut h = t_target - t0;
        // Where the friction loads change their piecewise form the iteration
        // may not settle; a shorter sub-step starts it closer to the solution.
        let mut halvings = 0;
        let mut rejected = false;
        let factor = loop {
            if let Err(mut e) = self.solve(t0 + h) {
                if !matches!(e, StepError::NotConverged { .. }) || halvings == MAX_HALVINGS {
                    if let StepError::NotConverged { halvings: ref mut done, .. } = e {
                        *done = halvings;
                    }
                    return Err(e);
                }
                halvings += 1;
                h *= 0.5;
                continue;
            }
            if control == StepControl::Fixed {
                break 1.0;
            }
            let ratio = error_ratio(&self.model, &self.start, &self.state, h, self.solver.previous_sub_step());
            let factor = optimal_factor(ratio);
            // At the floor (up to the rounding of t0 + h − t0) the step is taken.
            if ratio > 1.0 && h > settings.h_min * (1.0 + 1e-9) {
                self.state.steps.rejected += 1;
                rejected = true;
                h = (h * factor).max(settings.h_min);
                continue;
            }
            break factor;
        };
        if let StepControl::Adaptive { shortened } = control {
            let steps = &mut self.state.steps;
            // No growth right after a rejection: the error is near its limit
            // here, and growing at once would be rejected again.
            let growth = if rejected { 1.0 } else { GROWTH_MAX };
            let proposal = if shortened { steps.next_h.min(h * factor) } else { h * factor.min(growth) };
            steps.next_h = proposal.clamp(settings.h_min, settings.h_max);
        }
        let event = self.earliest_event();
        self.schedule.note(t0 + h, event.is_some(), &self.state.phase);
        let Some(event) = event else {
            self.located_now = false;
            return self.accept().map(|()| self.transition_count() != changes);
        };
        self.located_now = true;
        let (mut lo, mut hi) = (0.0, 1.0);
        let (mut g_lo, mut g_hi) = (self.event_value(event, &self.start), self.event_value(event, &self.state));
        let mut solved_at_hi = true;
        let mut side = 0;
        for _ in 0..MAX_LOCATE_ITERATIONS {
            if hi - lo <= self.event_resolution {
                break;
            }
            // Regula falsi; a margin that is infinite at an end (a drive
            // whose clearance opened there has no flank force) bisects.
            let secant = lo + (hi - lo) * g_lo / (g_lo - g_hi);
            let theta = if secant.is_finite() { secant } else { 0.5 * (lo + hi) };
            let theta = theta.clamp(lo + 0.01 * self.event_resolution, hi - 0.01 * self.event_resolution);
            self.solve_out_of_line(t0 + theta * h)?;
            let g = self.event_value(event, &self.state);
            if g < 0.0 {
                (hi, g_hi, solved_at_hi) = (theta, g, true);
                if side == -1 {
                    g_lo *= 0.5;
                }
                side = -1;
            } else {
                (lo, g_lo, solved_at_hi) = (theta, g, false);
                if side == 1 {
                    g_hi *= 0.5;
                }
                side = 1;
            }
        }
        if !solved_at_hi {
            self.solve_out_of_line(t0 + hi * h)?;
        }
        self.accept()?;
        self.instant += 1;
        match event {
            Event::Phase(joint) => {
                let breakaway = self.state.phase[joint] == Phase::Stuck;
                self.decide_at_rest(joint, breakaway)?;
            }
            // A damped drive's force jumps by h·δ̇ where its clearance closes:
            // the sub-step was solved with it open (`drive_force_over_substep`);
            // accelerations and margins now follow the engaged drive.
            Event::Clearance(joint, sign) if sign < 0.0 && self.model.joints[joint].drive.damping() != 0.0 => {
                self.evaluate()?;
            }
            _ => {}
        }
        self.settle_phases().map(|()| true)
    }

    /// Phase changes so far, kept or only counted.
    #[inline(always)]
    fn transition_count(&self) -> usize {
        self.transitions.len() + self.transitions_dropped
    }

    /// The value of `event`'s margin in `state`: positive before the event,
    /// negative after it.
    #[inline(always)]
    fn event_value(&self, event: Event, state: &State) -> f64 {
        match event {
            Event::Phase(i) => state.margin[i],
            Event::Clearance(i, sign) => sign * state.clearance_margin[i],
            Event::Release(i, sign) => sign * self.flank_force(i, state),
        }
    }

    /// σ·F of (2.1) of joint `i`'s drive in `state` ([`DriveForce::flank`](crate::forces::drive::DriveForce::flank)):
    /// +∞ for a joint whose drive cannot release.
    #[inline(always)]
    fn flank_force(&self, i: usize, state: &State) -> f64 {
        match self.model.joints[i].drive.spring() {
            Some(s) => {
                drive_force(
                    s.stiffness,
                    s.damping,
                    s.clearance,
                    state.q_star[i],
                    state.qd_star[i],
                    state.q[i],
                    state.qd[i],
                )
                .flank
            }
            None => f64::INFINITY,
        }
    }

    /// The event that happens first in the solved sub-step, by linear
    /// interpolation of the margins at its ends: a phase margin that turns
    /// negative, or a clearance margin that changes sign.
    #[inline(always)]
    fn earliest_event(&self) -> Option<Event> {
        let n = self.model.nq();
        let nc = self.state.n_coordinates();
        let (start, end) = (&self.start.margin[..nc], &self.state.margin[..nc]);
        let (c_start, c_end) = (&self.start.clearance_margin[..n], &self.state.clearance_margin[..n]);
        let clearances = self.model.has_clearance();
        let releases = self.model.has_damped_clearance();
        let (mut best, mut best_theta) = (None, f64::INFINITY);
        for i in 0..nc {
            let (g0, g1) = (start[i], end[i]);
            if g1 < 0.0 && (0.0..f64::INFINITY).contains(&g0) {
                let theta = g0 / (g0 - g1);
                if theta < best_theta {
                    (best, best_theta) = (Some(Event::Phase(i)), theta);
                }
            }
            if !clearances || i >= n {
                continue;
            }
            let (c0, c1) = (c_start[i], c_end[i]);
            // Infinite for joints without clearance; a sign change otherwise.
            if c0.is_finite() && c1.is_finite() && (c0 > 0.0) != (c1 > 0.0) && c0 != 0.0 {
                let theta = c0 / (c0 - c1);
                if theta < best_theta {
                    (best, best_theta) = (Some(Event::Clearance(i, c0.signum())), theta);
                }
            }
            if !releases {
                continue;
            }
            let (f0, f1) = (self.flank_force(i, &self.start), self.flank_force(i, &self.state));
            // Infinite inside the clearance and where no release can happen.
            if f0.is_finite() && f1.is_finite() && (f0 > 0.0) != (f1 > 0.0) && f0 != 0.0 {
                let theta = f0 / (f0 - f1);
                if theta < best_theta {
                    (best, best_theta) = (Some(Event::Release(i, f0.signum())), theta);
                }
            }
        }
        best
    }

    /// Accepts the solved sub-step: checks it is finite and books the works.
    /// Work of a force over a sub-step is its mean times the displacement,
    /// the form in which average-acceleration Newmark balances energy.
    #[inline(always)]
    #[allow(clippy::eq_op)] // x − x below is the finiteness test
    fn accept(&mut self) -> Result<(), StepError> {
        let (s, st) = (&self.start, &mut self.state);
        let n = self.model.nq();
        let nc = st.n_coordinates();
        let joints = &self.model.joints[..n];
        // Slices of known length let the compiler drop the per-index bounds checks.
        let (q, qd, qdd, q_star) = (&st.q[..nc], &st.qd[..nc], &st.qdd[..nc], &st.q_star[..n]);
        let (drive, friction, damping) = (&st.drive_force[..n], &st.friction_force[..nc], &st.damping_force[..n]);
        let (s_q, s_qd, s_q_star) = (&s.q[..nc], &s.qd[..nc], &s.q_star[..n]);
        let (s_drive, s_friction, s_damping) = (&s.drive_force[..n], &s.friction_force[..nc], &s.damping_force[..n]);
        let (phase, stuck_time) = (&st.phase[..nc], &mut st.stuck_time[..nc]);
        let dt = st.time - s.time;
        // The drive moves its end q* (for a rigid drive q* = q): it works
        // through Δq*, its damper dissipates over Δq* − Δq (zero when rigid).
        // A motor drive's end is moved by its rotor, and the motor works
        // through Δθ_m instead.
        let (mut drive_work, mut friction_heat, mut damping_heat, mut motor_heat) = (0.0, 0.0, 0.0, 0.0);
        // x − x is 0 for every finite x and NaN otherwise.
        let mut finite = 0.0;
        for i in 0..nc {
            finite += (q[i] - q[i]) + (qd[i] - qd[i]) + (qdd[i] - qdd[i]);
            if matches!(phase[i], Phase::Stuck) {
                stuck_time[i] += dt;
            }
            if i >= n {
                continue;
            }
            let dq = q[i] - s_q[i];
            let dq_star = q_star[i] - s_q_star[i];
            if !joints[i].drive.is_motor() {
                drive_work += (s_drive[i] + drive[i]) * dq_star;
            }
            friction_heat += (s_friction[i] + friction[i]) * dq;
            damping_heat += (s_damping[i] + damping[i]) * (dq_star - dq);
        }
        for (r, &j) in self.solver.rotors().iter().enumerate() {
            let c = n + r;
            let Some(rotor) = joints[j].drive.rotor() else { continue };
            let dtheta = q[c] - s_q[c];
            drive_work += (s.motor_torque[r] + st.motor_torque[r]) * dtheta;
            motor_heat += (s_friction[c] + friction[c] + rotor.viscous * (s_qd[c] + qd[c])) * dtheta;
        }
        if finite != 0.0 {
            // `advance` restores the state of the interval's start.
            return Err(StepError::NonFiniteState { time: st.time });
        }
        // The end of this sub-step is the start of the next one.
        self.solver.accepted(dt);
        st.steps.accepted += 1;
        st.steps.last_h = dt;
        let e = &mut st.energy;
        e.drive_work += 0.5 * drive_work;
        e.friction_heat += 0.5 * friction_heat;
        e.damping_heat += 0.5 * damping_heat;
        e.motor_heat += 0.5 * motor_heat;
        Ok(())
    }

    /// Decides the phase of joint `i`, which is at rest or just past a zero
    /// of its velocity: it sticks if static friction can hold it (3.16);
    /// otherwise it slips in the direction of the unbalanced force (3.18),
    /// provided that this motion is consistent (it accelerates that way). At
    /// a located `breakaway` the unbalanced force has just reached the static
    /// limit and the slip acceleration is zero up to the iteration tolerance:
    /// the joint slips without that check.
    fn decide_at_rest(&mut self, i: usize, breakaway: bool) -> Result<(), StepError> {
        let before = self.state.phase[i];
        self.decided[i] = self.instant;
        self.state.qd[i] = 0.0;
        self.state.phase[i] = Phase::Stuck;
        self.evaluate()?;
        if self.state.margin[i] < 0.0 {
            // While stuck, the friction is what holds the coordinate: the
            // unbalanced force F^d − F* of a joint (3.18), τ_m − F/N of a rotor.
            let unbalanced = self.state.friction_force[i];
            let d: i8 = if unbalanced > 0.0 { 1 } else { -1 };
            self.state.phase[i] = Phase::Slipping(d);
            self.evaluate()?;
            if !breakaway && d as f64 * self.state.qdd[i] <= 0.0 {
                // Friction that grows with the load it causes can leave no
                // consistent slip: the joint stays stuck for now.
                self.state.phase[i] = Phase::Stuck;
                self.evaluate()?;
            }
        }
        let after = self.state.phase[i];
        if after == Phase::Stuck && before != Phase::Stuck {
            self.state.stick_count[i] += 1;
        }
        self.log_transition(i, before, after);
        Ok(())
    }

    /// Makes every joint's phase consistent with the current state: a stuck
    /// joint whose static friction is exceeded breaks away, a slipping joint
    /// at rest that accelerates against its direction is decided anew. Each
    /// joint is decided at most once per instant (`self.instant` moves on
    /// when time moves on).
    #[inline(always)]
    pub(crate) fn settle_phases(&mut self) -> Result<(), StepError> {
        while let Some(i) = self.pending_phase_change() {
            self.decide_at_rest(i, false)?;
        }
        Ok(())
    }

    /// A joint, not yet decided at this instant, whose phase disagrees with
    /// the state: stuck with its static friction exceeded, or slipping against
    /// its direction.
    #[inline(always)]
    fn pending_phase_change(&self) -> Option<usize> {
        let st = &self.state;
        let n = st.n_coordinates();
        // Slices of length n let the compiler drop the per-index bounds checks.
        let (decided, phase, margin, qd, qdd) =
            (&self.decided[..n], &st.phase[..n], &st.margin[..n], &st.qd[..n], &st.qdd[..n]);
        for i in 0..n {
            // `>=`: a decision carried to later instants of the same time
            // (`carry_decisions`).
            if decided[i] >= self.instant {
                continue;
            }
            let pending = match phase[i] {
                Phase::Stuck => margin[i] < 0.0,
                Phase::Slipping(d) => {
                    let d = d as f64;
                    margin[i].is_finite() && (d * qd[i] < 0.0 || (qd[i] == 0.0 && d * qdd[i] < 0.0))
                }
                Phase::Prescribed => false,
            };
            if pending {
                return Some(i);
            }
        }
        None
    }

    /// [`Integrator::step_interval`] compiled for the baseline instruction set.
    #[inline(never)]
    pub(crate) fn step_interval_baseline<F: AfterSubStep>(
        &mut self,
        t0: f64,
        interval: f64,
        after: &mut F,
    ) -> Result<Flow, StepError> {
        self.step_interval(t0, interval, after)
    }

    /// [`Integrator::step_interval`] compiled with AVX2.
    ///
    /// # Safety
    /// The processor must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    pub(crate) unsafe fn step_interval_avx2<F: AfterSubStep>(
        &mut self,
        t0: f64,
        interval: f64,
        after: &mut F,
    ) -> Result<Flow, StepError> {
        self.step_interval(t0, interval, after)
    }

    /// The sub-steps of the interval from `t0` of length `interval`.
    /// Fixed sub-steps (h_min = h_max): ceil(interval / h_max) equal ones.
    /// Error-controlled: each of the length the last one proposed (h_min at
    /// the start), the last one shortened to end at the interval's end, and a
    /// remainder below two proposals split in halves so that no sliver is
    /// left. Either way a sub-step ends early at an event. After each
    /// sub-step that ends before the interval's end, `after` is told (FMI
    /// 3.0's intermediate update) and may end the interval there
    /// ([`Flow::Stop`], FMI 3.0's early return). Inlined into its two
    /// instruction-set variants, as is everything it calls per sub-step.
    #[inline(always)]
    fn step_interval<F: AfterSubStep>(&mut self, t0: f64, interval: f64, after: &mut F) -> Result<Flow, StepError> {
        if self.schedule.is_replaying() {
            return self.step_interval_replayed(t0, interval, after);
        }
        let settings = self.model.integrator;
        let budget = work_budget(&settings, interval);
        let t_end = t0 + interval;
        if settings.fixed_step() {
            let h_max = settings.h_max;
            let steps = (interval / h_max).ceil().max(1.0);
            let h = interval / steps;
            let steps = steps as u64;
            for k in 1..=steps {
                let t_grid = if k == steps { t_end } else { t0 + k as f64 * h };
                // An event shortens a sub-step; the rest of it up to the grid
                // point is taken next.
                while t_grid - self.state.time > 1e-9 * h {
                    let event = self.substep(t_grid, StepControl::Fixed)?;
                    self.check_work(budget)?;
                    if F::ACTIVE
                        && t_end - self.state.time > 1e-9 * h
                        && after.substep_finished(self, event)? == Flow::Stop
                    {
                        return Ok(Flow::Stop);
                    }
                }
                self.state.time = t_grid;
            }
            return Ok(Flow::Continue);
        }
        loop {
            let remaining = t_end - self.state.time;
            if remaining <= 1e-9 * settings.h_min {
                break;
            }
            let next = self.state.steps.next_h;
            let h = if next > 0.0 { next.clamp(settings.h_min, settings.h_max) } else { settings.h_min };
            // The last sub-step, cut to the interval's end, keeps the proposal
            // (it may only lower it); the halves of a remainder below two
            // proposals propose from their own error like any sub-step, or the
            // length could never grow past an interval shorter than 2h.
            let (target, shortened) = if remaining <= h {
                (t_end, true)
            } else if remaining < 2.0 * h {
                (self.state.time + 0.5 * remaining, false)
            } else {
                (self.state.time + h, false)
            };
            let event = self.substep(target, StepControl::Adaptive { shortened })?;
            self.check_work(budget)?;
            if F::ACTIVE
                && t_end - self.state.time > 1e-9 * settings.h_min
                && after.substep_finished(self, event)? == Flow::Stop
            {
                return Ok(Flow::Stop);
            }
        }
        self.state.time = t_end;
        Ok(Flow::Continue)
    }

    /// The sub-steps of the interval from `t0` of length `interval` as a
    /// replay takes them (see [`Schedule`]): each aimed at the next planned
    /// target, without error control, ended early by an event as any
    /// sub-step is. A sub-step whose event the plan does not have, or that
    /// misses the plan's, or that is solved with other phases, is a
    /// departure; a planned target the run has already passed is skipped as
    /// one.
    #[inline(never)]
    fn step_interval_replayed<F: AfterSubStep>(
        &mut self,
        t0: f64,
        interval: f64,
        after: &mut F,
    ) -> Result<Flow, StepError> {
        let settings = self.model.integrator;
        let budget = work_budget(&settings, interval);
        let t_end = t0 + interval;
        let close = 1e-9 * settings.h_min;
        while t_end - self.state.time > close {
            let planned = self.schedule.planned();
            let target = match planned {
                Some(p) if p.target <= self.state.time + close => {
                    // An event moved past this target: the plan is left.
                    self.schedule.depart();
                    self.schedule.advance();
                    continue;
                }
                Some(p) if p.target <= t_end + close => p.target.min(t_end),
                _ => {
                    self.schedule.depart();
                    t_end
                }
            };
            // `substep` compares what it finds with the plan (`Schedule::note`).
            let event = self.substep(target, StepControl::Fixed)?;
            self.check_work(budget)?;
            if let Some(p) = planned {
                // An event the plan has ends its sub-step; one it lacks
                // leaves the rest up to the planned target to be taken next.
                if self.state.time >= target - close || (self.located_now && p.event) {
                    self.schedule.advance();
                }
            }
            if F::ACTIVE && t_end - self.state.time > close && after.substep_finished(self, event)? == Flow::Stop {
                return Ok(Flow::Stop);
            }
        }
        self.state.time = t_end;
        Ok(Flow::Continue)
    }

    /// [`StepError::TooMuchWork`] once the interval has cost more than
    /// `budget` evaluations.
    #[inline(always)]
    fn check_work(&self, budget: u64) -> Result<(), StepError> {
        let evaluations = self.solver.iterations();
        if evaluations <= budget {
            return Ok(());
        }
        Err(StepError::TooMuchWork {
            time: self.state.time,
            evaluations,
            substeps: self.state.steps.accepted,
            h_min: self.model.integrator.h_min,
        })
    }

    /// Solves the state at the current time with the current phases, without
    /// advancing (a zero-length sub-step): used at initialization, at the start
    /// of an interval and after a phase change. The solver starts afresh, so
    /// that everything after it depends only on the state and the inputs (an
    /// exact continuation after a state is restored).
    pub(crate) fn evaluate(&mut self) -> Result<(), StepError> {
        self.start.take_step_start(&mut self.state);
        self.solver.restart(&self.start.qdd);
        self.solve_out_of_line(self.start.time)?;
        self.solver.seed_history();
        Ok(())
    }

    /// Solves the sub-step from `self.start` to time `t` with the phases in
    /// `self.state` (see [`NewmarkSolver::solve`]).
    #[inline(always)]
    pub(crate) fn solve(&mut self, t: f64) -> Result<(), StepError> {
        let step = SubStep {
            model: &self.model,
            data: &mut self.data,
            inputs: &self.inputs,
            torques: &self.torques,
            start: &self.start,
        };
        self.solver.solve(step, &mut self.state, t)
    }

    /// [`Integrator::solve`] as a call, for the solves outside the stepping
    /// loop's common path (evaluations, locating a transition), which need
    /// not be inlined into it.
    #[inline(never)]
    pub(crate) fn solve_out_of_line(&mut self, t: f64) -> Result<(), StepError> {
        self.solve(t)
    }

    pub(crate) fn log_transition(&mut self, joint: usize, from: Phase, to: Phase) {
        if from == to {
            return;
        }
        if self.transitions.len() < TRANSITION_LOG_CAPACITY {
            let n = self.model.nq();
            let drive_force =
                if joint < n { self.state.drive_force[joint] } else { self.state.motor_torque[joint - n] };
            self.transitions.push(Transition { time: self.state.time, joint, from, to, drive_force });
        } else {
            self.transitions_dropped += 1;
        }
    }
}

/// The most evaluations an interval of length `interval` may cost: four
/// times the iteration limit for every sub-step of length h_min it spans
/// (at least one). A converging run costs one to three evaluations per
/// sub-step and a few dozen per located event; a model whose time constants
/// lie far below h_min (a rotor of vanishing reflected inertia against a
/// strong damper) can otherwise halve and iterate for minutes within one
/// communication step, and a master would hang.
fn work_budget(settings: &IntegratorSettings, interval: f64) -> u64 {
    let substeps = (interval / settings.h_min).ceil().max(1.0);
    (4.0 * settings.max_iterations as f64 * substeps).min(u64::MAX as f64 / 2.0) as u64
}
