//! The simulator: a model, its workspace and its state, advanced over
//! communication intervals by the iterative Newmark stepper.

use super::inputs::{check_input_values, DriveInputs, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES};
use super::integrator::{AfterSubStep, Flow, Integrator, NoObserver, Transition};
use super::isa::InstructionSet;
use super::reported::{update_energies, update_reported};
use super::schedule::{PlannedSubStep, Schedule, REPLAY_EVENT_RESOLUTION, REPLAY_ITERATION_TOLERANCE};
use super::state::{Phase, State};
use crate::algorithms::kinematics::{forget_joint_transforms, update_joint_transforms};
use crate::algorithms::rnea::rnea;
use crate::data::Data;
use crate::error::{ModelError, StepError};
use crate::forces::friction::holds_statically;
use crate::forces::rotor::rotor_holds_statically;
use crate::model::{Drive, Model};
use std::sync::Arc;

/// Where the rotors of motor drives start (see [`Simulator::set_rotor_start`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub enum RotorStart {
    /// At rest, with the gear spring unloaded: θ_m = N·q, θ̇_m = 0.
    #[default]
    Unloaded,
    /// At rest, turned so that the gear spring holds its link at rest
    /// against gravity and the other loads at the start:
    /// θ_m = N·(q + F/k + sgn(F)·Δ) with F the joint's inverse-dynamics
    /// force with every spring-driven joint at rest. The motor torque that
    /// holds it there is F/N ([`State::drive_force`] / N).
    StaticEquilibrium,
    /// At the given angles θ_m (rad) and speeds θ̇_m (rad/s), one value per
    /// joint (joints without a motor drive ignore theirs).
    At {
        /// Rotor angles, rad.
        theta_m: Vec<f64>,
        /// Rotor speeds, rad/s.
        omega_m: Vec<f64>,
    },
}

/// Start values that override the default initial state (q = q*, at rest).
#[derive(Debug, Clone, Copy)]
pub struct InitialState<'a> {
    /// Joint coordinates of the flexible joints (values of rigid joints are ignored).
    pub q: &'a [f64],
    /// Joint velocities of the flexible joints (values of rigid joints are ignored).
    pub qd: &'a [f64],
}

/// Forward dynamics of one manipulator: owns the model, the workspace and the
/// state (in its [`Integrator`]). Every method that advances time either
/// succeeds or leaves the state as it was.
#[derive(Debug, Clone)]
pub struct Simulator {
    /// The model, workspace, state and sub-step machinery.
    pub(crate) core: Integrator,
    pub(crate) model_checked: bool,
    /// Snapshot at the start of the current interval, restored on error.
    pub(crate) saved: State,
    /// Where the rotors start at the next initialization.
    pub(crate) rotor_start: RotorStart,
    /// Scratch joint vector.
    pub(crate) scratch: Vec<f64>,
    pub(crate) initialized: bool,
    /// The variant of the stepping loop that runs (see [`InstructionSet`]).
    pub(crate) instruction_set: InstructionSet,
}

impl Simulator {
    /// A simulator for `model` (validated), not yet initialized.
    pub fn new(model: Model) -> Result<Simulator, ModelError> {
        model.validate()?;
        let n = model.nq();
        let core = Integrator::new(model);
        Ok(Simulator {
            saved: core.state.clone(),
            core,
            rotor_start: RotorStart::Unloaded,
            scratch: vec![0.0; n],
            initialized: false,
            instruction_set: InstructionSet::best_available(),
            model_checked: true,
        })
    }

    /// The instruction set the stepping loop runs with: the best this
    /// processor supports unless [`Simulator::set_instruction_set`] chose
    /// another. Results do not depend on it, only speed.
    pub fn instruction_set(&self) -> InstructionSet {
        self.instruction_set
    }

    /// Runs the stepping loop with `set` from now on; an error if this
    /// processor lacks it.
    pub fn set_instruction_set(&mut self, set: InstructionSet) -> Result<(), StepError> {
        if !set.is_available() {
            return Err(StepError::UnsupportedInstructionSet { name: set.name() });
        }
        self.instruction_set = set;
        Ok(())
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.core.model
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.core.state
    }

    /// The workspace (reactions, mass matrix … of the last evaluation).
    pub fn data(&self) -> &Data {
        &self.core.data
    }

    /// Newmark iterations spent in the last interval.
    pub fn iterations(&self) -> u64 {
        self.core.solver.iterations()
    }

    /// Restores a state taken from [`Simulator::state`] of a simulator of the
    /// same model.
    pub fn set_state(&mut self, state: &State) -> Result<(), ModelError> {
        if !state.fits(&self.core.model) {
            return Err(ModelError::Invalid { field: "state".into(), reason: "does not fit this model".into() });
        }
        self.core.state.copy_from(state);
        forget_joint_transforms(&mut self.core.data);
        self.initialized = true;
        Ok(())
    }

    /// Runs with `model` from the next interval on: the same chain with other
    /// parameter values (a new [`Model`], e.g. from [`Model::set_parameter`]
    /// on a copy of [`Simulator::model`]); the model in use is never changed
    /// in place. A model of another structure is refused at once; relations
    /// between parameters (μ_s ≥ μ_k, …) are checked before the next interval,
    /// since a caller may change them one at a time.
    pub fn set_model(&mut self, model: Model) -> Result<(), ModelError> {
        if !model.has_layout_of(&self.core.model) {
            return Err(ModelError::Invalid {
                field: "model".into(),
                reason: "another chain: joints, drives and contacts must stay those of the running model".into(),
            });
        }
        self.core.model = model;
        self.model_checked = false;
        Ok(())
    }

    /// Records the targets of the sub-steps from now on (see
    /// [`Simulator::take_schedule`]); the run itself is unchanged, bit for
    /// bit.
    pub fn record_schedule(&mut self) {
        self.core.schedule = Schedule::Recording(Vec::new());
    }

    /// The sub-steps recorded since [`Simulator::record_schedule`]; recording
    /// stops.
    pub fn take_schedule(&mut self) -> Vec<PlannedSubStep> {
        match std::mem::take(&mut self.core.schedule) {
            Schedule::Recording(plan) => plan,
            _ => Vec::new(),
        }
    }

    /// Takes the sub-steps of `plan` from now on, in order, without error
    /// control, with the Newmark iteration and the event location taken to
    /// rounding level: internal numerical differentiation of the run that
    /// recorded it (see [`PlannedSubStep`]). Must follow
    /// [`Simulator::initialize`], which starts a run afresh.
    pub fn replay_schedule(&mut self, plan: Arc<[PlannedSubStep]>) {
        self.core.schedule = Schedule::Replaying { plan, next: 0, departures: 0 };
        self.core.event_resolution = REPLAY_EVENT_RESOLUTION;
        self.core.solver.replay_tolerance = Some(REPLAY_ITERATION_TOLERANCE);
    }

    /// How often a replay left its plan so far: an event the plan does not
    /// have, one it has that did not happen, a sub-step solved with other
    /// phases, or sub-steps past the plan's end. 0 when not replaying.
    pub fn schedule_departures(&self) -> usize {
        self.core.schedule.departures()
    }

    /// Phase transitions since the last [`Simulator::clear_transitions`], and
    /// how many more were not kept.
    pub fn transitions(&self) -> (&[Transition], usize) {
        (&self.core.transitions, self.core.transitions_dropped)
    }

    /// Forgets the logged transitions.
    pub fn clear_transitions(&mut self) {
        self.core.transitions.clear();
        self.core.transitions_dropped = 0;
    }

    /// Sets the motor torques τ_m of the motor drives and their first two
    /// time derivatives, one value per joint (joints without a motor drive
    /// ignore theirs), held as their Taylor polynomial from the current time
    /// over the next intervals until set again; before
    /// [`Simulator::initialize`], the torques at its start. Checked like the
    /// drive inputs: a wrong length, a value that is not finite or outside
    /// [`MOTOR_TORQUE_RANGES`] is refused and nothing changes.
    pub fn set_motor_torques(&mut self, torques: &MotorTorques) -> Result<(), StepError> {
        let values = [torques.tau_m, torques.tau_m_rate, torques.tau_m_accel];
        check_input_values(self.core.model.nq(), MOTOR_TORQUE_RANGES, values)?;
        self.core.torques.set_values(self.core.state.time, values);
        Ok(())
    }

    /// Where the rotors of motor drives start at the next
    /// [`Simulator::initialize`] (default [`RotorStart::Unloaded`]).
    pub fn set_rotor_start(&mut self, start: RotorStart) -> Result<(), ModelError> {
        if let RotorStart::At { theta_m, omega_m } = &start {
            let n = self.core.model.nq();
            for (field, v) in [("theta_m_start", theta_m), ("omega_m_start", omega_m)] {
                if v.len() != n {
                    return Err(ModelError::Invalid {
                        field: field.into(),
                        reason: format!("{} values for {n} joints", v.len()),
                    });
                }
                if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err(ModelError::InvalidParameter {
                        field: format!("{field}[{}]", i + 1),
                        value: *x,
                        reason: "must be a finite number".into(),
                    });
                }
            }
        }
        self.rotor_start = start;
        Ok(())
    }

    fn check_model(&mut self) -> Result<(), StepError> {
        if !self.model_checked {
            self.core.model.validate().map_err(|e| StepError::InvalidModel { reason: e.to_string() })?;
            self.model_checked = true;
        }
        Ok(())
    }

    fn check_inputs(&self, inputs: &DriveInputs) -> Result<(), StepError> {
        check_input_values(self.core.model.nq(), INPUT_RANGES, [inputs.q_star, inputs.qd_star, inputs.qdd_star])
    }

    /// Starts a simulation at time `t0` with the drive inputs at t0. Flexible
    /// joints start at q = q*, at rest and stuck (when they have friction)
    /// unless `initial` gives other start values.
    pub fn initialize(
        &mut self,
        t0: f64,
        inputs: &DriveInputs,
        initial: Option<InitialState>,
    ) -> Result<(), StepError> {
        self.initialize_checked(t0, inputs, initial, State::check_finite)
    }

    /// [`Simulator::initialize`], with `check` of the initial state in place
    /// of [`State::check_finite`]: an `Err((quantity, value))` of it is a
    /// [`StepError::NonFiniteOutput`] and the simulator stays as it was.
    pub fn initialize_checked(
        &mut self,
        t0: f64,
        inputs: &DriveInputs,
        initial: Option<InitialState>,
        check: impl FnOnce(&State) -> Result<(), (String, f64)>,
    ) -> Result<(), StepError> {
        self.check_model()?;
        self.check_inputs(inputs)?;
        if !t0.is_finite() {
            return Err(StepError::InvalidInterval { interval: t0 });
        }
        if let Some(init) = initial {
            let n = self.core.model.nq();
            for (field, v) in [("q_start", init.q), ("qd_start", init.qd)] {
                if v.len() != n {
                    return Err(StepError::InputLength { field, expected: n, got: v.len() });
                }
                if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err(StepError::NonFiniteInput { field, joint: i + 1, value: *x });
                }
            }
        }
        let previous = self.core.state.clone();
        let result = self.initialize_inner(t0, inputs, initial).and_then(|()| self.checked(check));
        if result.is_err() {
            self.initialized = false;
            self.core.state = previous;
        }
        result
    }

    fn initialize_inner(
        &mut self,
        t0: f64,
        inputs: &DriveInputs,
        initial: Option<InitialState>,
    ) -> Result<(), StepError> {
        self.core.inputs.set(t0, inputs);
        self.core.torques.t0 = t0;
        forget_joint_transforms(&mut self.core.data);
        let st = &mut self.core.state;
        st.time = t0;
        st.energy = Default::default();
        st.steps = Default::default();
        st.stuck_time.fill(0.0);
        for (i, joint) in self.core.model.joints.iter().enumerate() {
            match joint.drive {
                Drive::Rigid => {
                    st.phase[i] = Phase::Prescribed;
                    st.q[i] = inputs.q_star[i];
                    st.qd[i] = inputs.qd_star[i];
                }
                Drive::Flexible { .. } | Drive::Motor { .. } => {
                    let (q, qd) = initial.map_or((inputs.q_star[i], 0.0), |s| (s.q[i], s.qd[i]));
                    st.q[i] = q;
                    st.qd[i] = qd;
                    st.phase[i] = phase_at_start(qd, holds_statically(joint.friction.as_ref()));
                }
            }
            st.qdd[i] = 0.0;
        }
        self.start_rotors(inputs);
        let st = &mut self.core.state;
        for (count, phase) in st.stick_count.iter_mut().zip(&st.phase) {
            *count = u64::from(*phase == Phase::Stuck);
        }
        self.clear_transitions();
        self.core.evaluate()?;
        self.core.instant += 1;
        self.core.settle_phases()?;
        self.update_reported();
        self.initialized = true;
        Ok(())
    }

    /// Places the rotors of the motor drives as [`Simulator::rotor_start`]
    /// says, from the joints' start state in `self.core.state`, and sets their
    /// phases and the drive positions q* = θ_m/N.
    fn start_rotors(&mut self, inputs: &DriveInputs) {
        let rotors = self.core.solver.rotors();
        if rotors.is_empty() {
            return;
        }
        let n = self.core.model.nq();
        if self.rotor_start == RotorStart::StaticEquilibrium {
            // The forces that hold every spring-driven joint at rest, the
            // rigid ones moving as prescribed.
            for (i, joint) in self.core.model.joints.iter().enumerate() {
                self.scratch[i] = if joint.drive.is_flexible() { 0.0 } else { inputs.qdd_star[i] };
            }
            let st = &self.core.state;
            let qd: Vec<f64> =
                (0..n).map(|i| if self.core.model.joints[i].drive.is_flexible() { 0.0 } else { st.qd[i] }).collect();
            update_joint_transforms(&self.core.model, &mut self.core.data, &st.q[..n]);
            rnea(&self.core.model, &mut self.core.data, &st.q[..n], &qd, &self.scratch);
            forget_joint_transforms(&mut self.core.data);
        }
        let st = &mut self.core.state;
        for (r, &j) in rotors.iter().enumerate() {
            let drive = self.core.model.joints[j].drive;
            let (Some(spring), Some(rotor)) = (drive.spring(), drive.rotor()) else { continue };
            let ratio = rotor.gear_ratio;
            let c = n + r;
            let (theta, omega) = match &self.rotor_start {
                RotorStart::Unloaded => (ratio * st.q[j], 0.0),
                RotorStart::StaticEquilibrium => {
                    // (2.1) at rest: F = k·(e − σΔ) with e = q* − q.
                    let force = self.core.data.tau[j];
                    let deflection =
                        if force == 0.0 { 0.0 } else { force / spring.stiffness + spring.clearance.copysign(force) };
                    (ratio * (st.q[j] + deflection), 0.0)
                }
                RotorStart::At { theta_m, omega_m } => (theta_m[j], omega_m[j]),
            };
            st.q[c] = theta;
            st.qd[c] = omega;
            st.qdd[c] = 0.0;
            st.phase[c] = phase_at_start(omega, rotor_holds_statically(&rotor));
            st.q_star[j] = theta / ratio;
            st.qd_star[j] = omega / ratio;
        }
    }

    /// Advances the state over one communication interval of length
    /// `interval` (s) with the drive inputs at its start, held as their Taylor
    /// polynomial. The interval is covered by sub-steps of fixed length or of
    /// the length the error control chooses (see
    /// [`IntegratorSettings`](crate::model::IntegratorSettings)),
    /// each shortened where a joint sticks or slips or a drive's clearance
    /// closes or opens, so that the event falls on a sub-step boundary. On error the state is left as
    /// it was.
    pub fn advance(&mut self, inputs: &DriveInputs, interval: f64) -> Result<(), StepError> {
        self.advance_checked(inputs, interval, State::check_finite)
    }

    /// [`Simulator::advance`], with `check` of the state at the end of the
    /// interval in place of [`State::check_finite`] (an FMU checks its
    /// outputs by name): an `Err((quantity, value))` of it is a
    /// [`StepError::NonFiniteOutput`] and the state stays at the interval's
    /// start.
    pub fn advance_checked(
        &mut self,
        inputs: &DriveInputs,
        interval: f64,
        check: impl FnOnce(&State) -> Result<(), (String, f64)>,
    ) -> Result<(), StepError> {
        self.begin_interval(inputs, interval)?;
        let result = self.advance_inner(inputs, interval, &mut NoObserver).and_then(|_| self.checked(check));
        if result.is_err() {
            self.core.state.copy_from(&self.saved);
        }
        result
    }

    /// The checks before an interval, and the snapshot its failure restores.
    pub(super) fn begin_interval(&mut self, inputs: &DriveInputs, interval: f64) -> Result<(), StepError> {
        if !(interval.is_finite() && interval > 0.0) {
            return Err(StepError::InvalidInterval { interval });
        }
        self.check_inputs(inputs)?;
        if !self.initialized {
            return Err(StepError::NotInitialized);
        }
        self.check_model()?;
        self.saved.copy_from(&self.core.state);
        self.core.solver.reset_count();
        Ok(())
    }

    pub(super) fn advance_inner<F: AfterSubStep>(
        &mut self,
        inputs: &DriveInputs,
        interval: f64,
        after: &mut F,
    ) -> Result<Flow, StepError> {
        let t0 = self.core.state.time;
        self.core.inputs.set(t0, inputs);
        // Inputs may differ from the previous interval's extrapolation: make
        // accelerations and phases consistent with them before stepping. The
        // drives did the work of that jump of q* (or of a rigid joint's q, q̇).
        let before = self.core.state.energy.total();
        self.core.evaluate()?;
        self.core.instant += 1;
        self.core.settle_phases()?;
        update_energies(&mut self.core);
        self.core.state.energy.drive_work += self.core.state.energy.total() - before;
        let flow = match self.instruction_set {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `instruction_set` is Avx2 only if the processor has AVX2
            // (`best_available`, `set_instruction_set`).
            InstructionSet::Avx2 => unsafe { self.core.step_interval_avx2(t0, interval, after) }?,
            _ => self.core.step_interval_baseline(t0, interval, after)?,
        };
        self.update_reported();
        Ok(flow)
    }

    /// `check` of the current state as a step result.
    pub(super) fn checked(&self, check: impl FnOnce(&State) -> Result<(), (String, f64)>) -> Result<(), StepError> {
        check(&self.core.state).map_err(|(quantity, value)| StepError::NonFiniteOutput {
            quantity,
            value,
            time: self.core.state.time,
        })
    }

    /// Recomputes the reported quantities that are not needed while stepping:
    /// energies, all joint reactions and end points.
    pub(crate) fn update_reported(&mut self) {
        update_reported(&mut self.core, &mut self.scratch);
    }
}

/// The phase a spring-driven joint or a rotor starts in at velocity `qd`:
/// slipping in its direction if it moves, else stuck if its friction
/// `holds` it, else slipping (its direction decided by the first evaluation).
fn phase_at_start(qd: f64, holds: bool) -> Phase {
    if qd != 0.0 {
        Phase::Slipping(if qd > 0.0 { 1 } else { -1 })
    } else if holds {
        Phase::Stuck
    } else {
        Phase::Slipping(1)
    }
}
