//! The end of a sub-step as a caller of
//! [`Simulator::advance_observed`](super::Simulator::advance_observed) sees
//! it: FMI 3.0's intermediate update (outputs and inputs at the engine's own
//! sub-steps) and early return (the interval ends at an event).
//!
//! Nothing here changes the trajectory unless the caller sets inputs: the
//! reported quantities (reactions, end points, energies) are computed on a
//! copy of the state and workspace, since the workspace's cached joint
//! transforms are part of how the next sub-step is computed.

use super::inputs::{check_input_values, held, DriveInputs, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES};
use super::integrator::{AfterSubStep, Flow, Integrator};
use super::reported::{report, update_energies};
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
