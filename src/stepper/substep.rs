//! FMI 3.0's path through the engine (compiled with the feature `fmi3`
//! only): a communication interval observed at the end of every sub-step
//! ([`Simulator::advance_observed`]), the end of a sub-step as the observer
//! sees it ([`SubStep`]: FMI 3.0's intermediate update, outputs and inputs at
//! the engine's own sub-steps, and early return, the interval ends at an
//! event), and the decisions of an event's instant carried through the
//! inputs set there ([`Integrator::carry_decisions`]). The stepping loop is
//! the FMI 2.0 one, generic over its observer ([`AfterSubStep`]): here it is
//! monomorphized for [`Observer`].
//!
//! Nothing here changes the trajectory unless the caller sets inputs: the
//! reported quantities (reactions, end points, energies) are computed on a
//! copy of the state and workspace, since the workspace's cached joint
//! transforms are part of how the next sub-step is computed.

use super::inputs::{
    check_input_values, DriveInputs, InputPolynomial, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES,
};
use super::integrator::{AfterSubStep, Flow, Integrator};
use super::reported::{report, update_energies};
use super::simulator::Simulator;
use super::state::State;
use crate::data::Data;
use crate::error::StepError;

/// One sub-step's end inside a communication interval.
pub(crate) struct SubStep<'a> {
    core: &'a mut Integrator,
    event: bool,
    report: &'a mut Option<(Data, State)>,
    scratch: &'a mut [f64],
}

impl SubStep<'_> {
    /// Whether the sub-step ended at an event: a located stick→slip,
    /// slip→stick, clearance or flank-release instant, or a phase change.
    pub(crate) fn event(&self) -> bool {
        self.event
    }

    /// The time, s.
    pub(crate) fn time(&self) -> f64 {
        self.core.state.time
    }

    /// The state with its reported quantities (reactions, end points,
    /// energies) at this instant, computed on a copy.
    pub(crate) fn reported(&mut self) -> &State {
        let core = &*self.core;
        let (data, state) = self.report.get_or_insert_with(|| (core.data.clone(), core.state.clone()));
        data.clone_from(&core.data);
        state.copy_from(&core.state);
        report(&core.model, data, state, core.solver.rotors(), self.scratch);
        state
    }

    /// The drive inputs q*, q̇*, q̈* the engine holds at this instant (its
    /// Taylor polynomial), into `out`, one value per joint each.
    pub(crate) fn held_drive_inputs(&self, out: [&mut [f64]; 3]) {
        held(&self.core.inputs, self.core.state.time, out);
    }

    /// The motor torques τ_m and their rates the engine holds at this instant.
    pub(crate) fn held_motor_torques(&self, out: [&mut [f64]; 3]) {
        held(&self.core.torques, self.core.state.time, out);
    }

    /// Takes new drive inputs and motor torques from this instant on, as at
    /// the start of a communication interval: checked against their ranges,
    /// then accelerations and phases made consistent with them; the drives
    /// did the work of the jump. On error nothing changed.
    pub(crate) fn set_inputs(&mut self, drive: &DriveInputs, torques: &MotorTorques) -> Result<(), StepError> {
        let n = self.core.model.nq();
        let drive = [drive.q_star, drive.qd_star, drive.qdd_star];
        let torques = [torques.tau_m, torques.tau_m_rate, torques.tau_m_accel];
        check_input_values(n, INPUT_RANGES, drive)?;
        check_input_values(n, MOTOR_TORQUE_RANGES, torques)?;
        let t = self.core.state.time;
        self.core.inputs.set_values(t, drive);
        self.core.torques.set_values(t, torques);
        let before = self.core.state.energy.total();
        self.core.evaluate()?;
        // The same instant as the sub-step's end: a joint whose phase was
        // decided there (a breakaway just located) keeps it, also at the
        // next sub-step's start; new inputs there must not make it stick
        // again for a sliver.
        self.core.settle_phases()?;
        self.core.carry_decisions(1);
        update_energies(self.core);
        self.core.state.energy.drive_work += self.core.state.energy.total() - before;
        Ok(())
    }
}

/// The [`AfterSubStep`] of [`Simulator::advance_observed`](super::Simulator::advance_observed):
/// a closure of the caller's and the scratch space of [`SubStep::reported`].
pub(crate) struct Observer<F> {
    pub(crate) after: F,
    pub(crate) scratch: Vec<f64>,
    pub(crate) report: Option<(Data, State)>,
}

impl<F: FnMut(&mut SubStep<'_>) -> Result<Flow, StepError>> AfterSubStep for Observer<F> {
    fn substep_finished(&mut self, core: &mut Integrator, event: bool) -> Result<Flow, StepError> {
        let mut step = SubStep { core, event, report: &mut self.report, scratch: &mut self.scratch };
        (self.after)(&mut step)
    }
}

impl Simulator {
    /// [`Simulator::advance_checked`] with `after` told at the end of every
    /// sub-step before the interval's end (FMI 3.0's intermediate update),
    /// which may end the interval there ([`Flow::Stop`], FMI 3.0's early
    /// return): then the state is at that sub-step's end, and the interval
    /// was shorter than `interval`. The inputs `after` sets through
    /// [`SubStep`] hold from the sub-step's end on.
    pub(crate) fn advance_observed<F: FnMut(&mut SubStep<'_>) -> Result<Flow, StepError>>(
        &mut self,
        inputs: &DriveInputs,
        interval: f64,
        check: impl FnOnce(&State) -> Result<(), (String, f64)>,
        after: F,
    ) -> Result<Flow, StepError> {
        self.begin_interval(inputs, interval)?;
        let mut observer = Observer { after, scratch: self.scratch.clone(), report: None };
        let result = self.advance_inner(inputs, interval, &mut observer);
        let result = result.and_then(|flow| self.checked(check).map(|()| flow));
        match result {
            // The next interval starts at this instant (its start and its
            // first sub-step's): the phases decided here stand through both.
            Ok(Flow::Stop) => self.core.carry_decisions(2),
            Ok(Flow::Continue) => {}
            Err(_) => self.core.state.copy_from(&self.saved),
        }
        result
    }

    /// The drive inputs and motor torques the engine holds at the current
    /// time (their Taylor polynomials), into `drive` and `torques`.
    pub(crate) fn held_inputs(&self, drive: [&mut [f64]; 3], torques: [&mut [f64]; 3]) {
        held(&self.core.inputs, self.core.state.time, drive);
        held(&self.core.torques, self.core.state.time, torques);
    }
}

impl Integrator {
    /// The joints decided at the current instant stay decided through the
    /// next `instants` instants: those of the same physical time that new
    /// inputs (FMI 3.0's intermediate update, the step after an early return)
    /// begin. A joint that just broke away with q̇ = 0 would otherwise stick
    /// again for a sliver when the inputs move by their rounding.
    pub(crate) fn carry_decisions(&mut self, instants: u64) {
        if !self.located_now {
            return;
        }
        let now = self.instant;
        for d in self.decided.iter_mut().filter(|d| **d >= now) {
            *d = (*d).max(now + instants);
        }
    }
}

/// `p`'s value and first two derivatives at `t`, per joint, into `out`.
fn held(p: &InputPolynomial, t: f64, [x, xd, xdd]: [&mut [f64]; 3]) {
    for i in 0..p.q.len() {
        (x[i], xd[i], xdd[i]) = p.eval(i, t);
    }
}
