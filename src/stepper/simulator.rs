//! The simulator: a model, its workspace and its state, advanced over
//! communication intervals by the iterative Newmark stepper.

use super::inputs::{DriveInputs, InputPolynomial, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES};
use super::isa::InstructionSet;
use super::state::{Phase, State};
use super::switching::StepControl;
use crate::algorithms::energy::{kinetic_energy, potential_energy};
use super::newmark::{NewmarkSolver, SubStep};
use crate::algorithms::kinematics::{end_point, forget_joint_transforms, forward_kinematics, update_joint_transforms};
use crate::algorithms::rnea::{joint_reactions, rnea};
use crate::data::Data;
use crate::error::{ModelError, StepError};
use crate::forces::drive::spring_energy;
use crate::forces::friction::holds_statically;
use crate::forces::rotor::rotor_holds_statically;
use crate::model::{Drive, Model, Range};

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

/// How many transitions are kept between two calls of
/// [`Simulator::clear_transitions`]; later ones are only counted.
pub const TRANSITION_LOG_CAPACITY: usize = 256;

/// Start values that override the default initial state (q = q*, at rest).
#[derive(Debug, Clone, Copy)]
pub struct InitialState<'a> {
    /// Joint coordinates of the flexible joints (values of rigid joints are ignored).
    pub q: &'a [f64],
    /// Joint velocities of the flexible joints (values of rigid joints are ignored).
    pub qd: &'a [f64],
}

/// Forward dynamics of one manipulator: owns the model, the workspace and the
/// state. Every method that advances time either succeeds or leaves the state
/// as it was.
#[derive(Debug, Clone)]
pub struct Simulator {
    pub(crate) model: Model,
    pub(crate) model_checked: bool,
    pub(crate) data: Data,
    pub(crate) state: State,
    /// Snapshot at the start of the current sub-step: only the fields that
    /// [`State::take_step_start`] takes are current.
    pub(crate) start: State,
    /// Snapshot at the start of the current interval, restored on error.
    pub(crate) saved: State,
    pub(crate) inputs: InputPolynomial,
    /// The motor torques τ_m of the motor drives, per joint.
    pub(crate) torques: InputPolynomial,
    /// Where the rotors start at the next initialization.
    pub(crate) rotor_start: RotorStart,
    /// The Newmark iteration's workspace.
    pub(crate) solver: NewmarkSolver,
    /// Scratch joint vector.
    pub(crate) scratch: Vec<f64>,
    /// For each coordinate, the instant (see `instant`) at which its phase was
    /// last decided.
    pub(crate) decided: Vec<u64>,
    /// Number of the current instant of phase decisions; a new one starts
    /// when time moves on, so no joint counts as decided there.
    pub(crate) instant: u64,
    pub(crate) transitions: Vec<Transition>,
    pub(crate) transitions_dropped: usize,
    pub(crate) initialized: bool,
    /// The variant of the stepping loop that runs (see [`InstructionSet`]).
    pub(crate) instruction_set: InstructionSet,
}

impl Simulator {
    /// A simulator for `model` (validated), not yet initialized.
    pub fn new(model: Model) -> Result<Simulator, ModelError> {
        model.validate()?;
        let n = model.nq();
        let state = State::new(&model);
        Ok(Simulator {
            data: Data::new(&model),
            start: state.clone(),
            saved: state.clone(),
            state,
            inputs: InputPolynomial::new(n),
            torques: InputPolynomial::new(n),
            rotor_start: RotorStart::Unloaded,
            solver: NewmarkSolver::new(&model),
            scratch: vec![0.0; n],
            decided: vec![0; model.n_coordinates()],
            instant: 1,
            transitions: Vec::with_capacity(TRANSITION_LOG_CAPACITY),
            transitions_dropped: 0,
            initialized: false,
            instruction_set: InstructionSet::best_available(),
            model_checked: true,
            model,
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
        &self.model
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The workspace (reactions, mass matrix … of the last evaluation).
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// Newmark iterations spent in the last interval.
    pub fn iterations(&self) -> u64 {
        self.solver.iterations()
    }

    /// Restores a state taken from [`Simulator::state`] of a simulator of the
    /// same model.
    pub fn set_state(&mut self, state: &State) -> Result<(), ModelError> {
        if !state.fits(&self.model) {
            return Err(ModelError::Invalid { field: "state".into(), reason: "does not fit this model".into() });
        }
        self.state.copy_from(state);
        forget_joint_transforms(&mut self.data);
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
        if !model.has_layout_of(&self.model) {
            return Err(ModelError::Invalid {
                field: "model".into(),
                reason: "another chain: joints, drives and contacts must stay those of the running model".into(),
            });
        }
        self.model = model;
        self.model_checked = false;
        Ok(())
    }

    /// Phase transitions since the last [`Simulator::clear_transitions`], and
    /// how many more were not kept.
    pub fn transitions(&self) -> (&[Transition], usize) {
        (&self.transitions, self.transitions_dropped)
    }

    /// Forgets the logged transitions.
    pub fn clear_transitions(&mut self) {
        self.transitions.clear();
        self.transitions_dropped = 0;
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
        check_input_values(self.model.nq(), MOTOR_TORQUE_RANGES, values)?;
        self.torques.set_values(self.state.time, values);
        Ok(())
    }

    /// Where the rotors of motor drives start at the next
    /// [`Simulator::initialize`] (default [`RotorStart::Unloaded`]).
    pub fn set_rotor_start(&mut self, start: RotorStart) -> Result<(), ModelError> {
        if let RotorStart::At { theta_m, omega_m } = &start {
            let n = self.model.nq();
            for (field, v) in [("theta_m_start", theta_m), ("omega_m_start", omega_m)] {
                if v.len() != n {
                    return Err(ModelError::Invalid { field: field.into(), reason: format!("{} values for {n} joints", v.len()) });
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
            self.model.validate().map_err(|e| StepError::InvalidModel { reason: e.to_string() })?;
            self.model_checked = true;
        }
        Ok(())
    }

    fn check_inputs(&self, inputs: &DriveInputs) -> Result<(), StepError> {
        check_input_values(self.model.nq(), INPUT_RANGES, [inputs.q_star, inputs.qd_star, inputs.qdd_star])
    }

    /// Starts a simulation at time `t0` with the drive inputs at t0. Flexible
    /// joints start at q = q*, at rest and stuck (when they have friction)
    /// unless `initial` gives other start values.
    pub fn initialize(&mut self, t0: f64, inputs: &DriveInputs, initial: Option<InitialState>) -> Result<(), StepError> {
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
            let n = self.model.nq();
            for (field, v) in [("q_start", init.q), ("qd_start", init.qd)] {
                if v.len() != n {
                    return Err(StepError::InputLength { field, expected: n, got: v.len() });
                }
                if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err(StepError::NonFiniteInput { field, joint: i + 1, value: *x });
                }
            }
        }
        let previous = self.state.clone();
        let result = self.initialize_inner(t0, inputs, initial).and_then(|()| self.checked(check));
        if result.is_err() {
            self.initialized = false;
            self.state = previous;
        }
        result
    }

    fn initialize_inner(&mut self, t0: f64, inputs: &DriveInputs, initial: Option<InitialState>) -> Result<(), StepError> {
        self.inputs.set(t0, inputs);
        self.torques.t0 = t0;
        forget_joint_transforms(&mut self.data);
        let st = &mut self.state;
        st.time = t0;
        st.energy = Default::default();
        st.steps = Default::default();
        st.stuck_time.fill(0.0);
        for (i, joint) in self.model.joints.iter().enumerate() {
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
        let st = &mut self.state;
        for (count, phase) in st.stick_count.iter_mut().zip(&st.phase) {
            *count = u64::from(*phase == Phase::Stuck);
        }
        self.clear_transitions();
        self.evaluate()?;
        self.instant += 1;
        self.settle_phases()?;
        self.update_reported();
        self.initialized = true;
        Ok(())
    }

    /// Places the rotors of the motor drives as [`Simulator::rotor_start`]
    /// says, from the joints' start state in `self.state`, and sets their
    /// phases and the drive positions q* = θ_m/N.
    fn start_rotors(&mut self, inputs: &DriveInputs) {
        let rotors = self.solver.rotors();
        if rotors.is_empty() {
            return;
        }
        let n = self.model.nq();
        if self.rotor_start == RotorStart::StaticEquilibrium {
            // The forces that hold every spring-driven joint at rest, the
            // rigid ones moving as prescribed.
            for (i, joint) in self.model.joints.iter().enumerate() {
                self.scratch[i] = if joint.drive.is_flexible() { 0.0 } else { inputs.qdd_star[i] };
            }
            let st = &self.state;
            let qd: Vec<f64> = (0..n).map(|i| if self.model.joints[i].drive.is_flexible() { 0.0 } else { st.qd[i] }).collect();
            update_joint_transforms(&self.model, &mut self.data, &st.q[..n]);
            rnea(&self.model, &mut self.data, &st.q[..n], &qd, &self.scratch);
            forget_joint_transforms(&mut self.data);
        }
        let st = &mut self.state;
        for (r, &j) in rotors.iter().enumerate() {
            let drive = self.model.joints[j].drive;
            let (Some(spring), Some(rotor)) = (drive.spring(), drive.rotor()) else { continue };
            let ratio = rotor.gear_ratio;
            let c = n + r;
            let (theta, omega) = match &self.rotor_start {
                RotorStart::Unloaded => (ratio * st.q[j], 0.0),
                RotorStart::StaticEquilibrium => {
                    // (2.1) at rest: F = k·(e − σΔ) with e = q* − q.
                    let force = self.data.tau[j];
                    let deflection = if force == 0.0 { 0.0 } else { force / spring.stiffness + spring.clearance.copysign(force) };
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
        if !(interval.is_finite() && interval > 0.0) {
            return Err(StepError::InvalidInterval { interval });
        }
        self.check_inputs(inputs)?;
        if !self.initialized {
            return Err(StepError::NotInitialized);
        }
        self.check_model()?;
        self.saved.copy_from(&self.state);
        self.solver.reset_count();
        let result = self.advance_inner(inputs, interval).and_then(|()| self.checked(check));
        if result.is_err() {
            self.state.copy_from(&self.saved);
        }
        result
    }

    fn advance_inner(&mut self, inputs: &DriveInputs, interval: f64) -> Result<(), StepError> {
        let t0 = self.state.time;
        self.inputs.set(t0, inputs);
        // The motor torques were set at this communication point (or before).
        self.torques.t0 = t0;
        // Inputs may differ from the previous interval's extrapolation: make
        // accelerations and phases consistent with them before stepping. The
        // drives did the work of that jump of q* (or of a rigid joint's q, q̇).
        let before = self.state.energy.total();
        self.evaluate()?;
        self.instant += 1;
        self.settle_phases()?;
        self.update_energies();
        self.state.energy.drive_work += self.state.energy.total() - before;
        match self.instruction_set {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `instruction_set` is Avx2 only if the processor has AVX2
            // (`best_available`, `set_instruction_set`).
            InstructionSet::Avx2 => unsafe { self.step_interval_avx2(t0, interval) }?,
            _ => self.step_interval_baseline(t0, interval)?,
        }
        self.update_reported();
        Ok(())
    }

    /// [`Simulator::step_interval`] compiled for the baseline instruction set.
    #[inline(never)]
    fn step_interval_baseline(&mut self, t0: f64, interval: f64) -> Result<(), StepError> {
        self.step_interval(t0, interval)
    }

    /// [`Simulator::step_interval`] compiled with AVX2.
    ///
    /// # Safety
    /// The processor must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    unsafe fn step_interval_avx2(&mut self, t0: f64, interval: f64) -> Result<(), StepError> {
        self.step_interval(t0, interval)
    }

    /// The sub-steps of the interval from `t0` of length `interval`.
    /// Fixed sub-steps (h_min = h_max): ceil(interval / h_max) equal ones.
    /// Error-controlled: each of the length the last one proposed (h_min at
    /// the start), the last one shortened to end at the interval's end, and a
    /// remainder below two proposals split in halves so that no sliver is
    /// left. Either way a sub-step ends early at an event. Inlined into its
    /// two instruction-set variants, as is everything it calls per sub-step.
    #[inline(always)]
    fn step_interval(&mut self, t0: f64, interval: f64) -> Result<(), StepError> {
        let settings = self.model.integrator;
        if settings.fixed_step() {
            let h_max = settings.h_max;
            let steps = (interval / h_max).ceil().max(1.0);
            let h = interval / steps;
            let steps = steps as u64;
            for k in 1..=steps {
                let t_grid = if k == steps { t0 + interval } else { t0 + k as f64 * h };
                // An event shortens a sub-step; the rest of it up to the grid
                // point is taken next.
                while t_grid - self.state.time > 1e-9 * h {
                    self.substep(t_grid, StepControl::Fixed)?;
                }
                self.state.time = t_grid;
            }
            return Ok(());
        }
        let t_end = t0 + interval;
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
            self.substep(target, StepControl::Adaptive { shortened })?;
        }
        self.state.time = t_end;
        Ok(())
    }

    /// `check` of the current state as a step result.
    fn checked(&self, check: impl FnOnce(&State) -> Result<(), (String, f64)>) -> Result<(), StepError> {
        check(&self.state).map_err(|(quantity, value)| StepError::NonFiniteOutput { quantity, value, time: self.state.time })
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
        let step =
            SubStep { model: &self.model, data: &mut self.data, inputs: &self.inputs, torques: &self.torques, start: &self.start };
        self.solver.solve(step, &mut self.state, t)
    }

    /// [`Simulator::solve`] as a call, for the solves outside the stepping
    /// loop's common path (evaluations, locating a transition), which need
    /// not be inlined into it.
    #[inline(never)]
    pub(crate) fn solve_out_of_line(&mut self, t: f64) -> Result<(), StepError> {
        self.solve(t)
    }

    /// Recomputes the reported quantities that are not needed while stepping:
    /// energies, all joint reactions and end points.
    pub(crate) fn update_reported(&mut self) {
        self.update_energies();
        joint_reactions(&self.model, &mut self.data);
        // Reported in the frame the user described each link in (URDF: the
        // child link frame); the identity for Denavit–Hartenberg joints.
        for (i, joint) in self.model.joints.iter().enumerate() {
            self.state.reaction_force[i] = joint.reported_axes * self.data.reaction_force[i];
            self.state.reaction_moment[i] = joint.reported_axes * self.data.reaction_moment[i];
        }
        let model = &self.model;
        let st = &mut self.state;
        st.end_point = end_point(model, &self.data);
        // q̂: q* for flexible joints, the prescribed q for rigid ones (= q*).
        self.scratch.copy_from_slice(&st.q_star);
        forward_kinematics(model, &mut self.data, &self.scratch);
        // The next interval starts from the library's sines of its own q.
        forget_joint_transforms(&mut self.data);
        st.end_point_rigid = end_point(model, &self.data);
    }

    /// Kinetic, gravity and spring energy of the current state; leaves the
    /// frame-0 kinematics of the current coordinates in the workspace.
    fn update_energies(&mut self) {
        let (model, st) = (&self.model, &mut self.state);
        let n = model.nq();
        forward_kinematics(model, &mut self.data, &st.q[..n]);
        st.energy.kinetic = kinetic_energy(model, &self.data, &st.qd[..n]);
        st.energy.potential = potential_energy(model, &self.data);
        st.energy.spring = model
            .joints
            .iter()
            .enumerate()
            .map(|(i, j)| j.drive.spring().map_or(0.0, |s| spring_energy(s.stiffness, s.clearance, st.q_star[i], st.q[i])))
            .sum();
        st.energy.rotor_kinetic = self
            .solver
            .rotors()
            .iter()
            .enumerate()
            .filter_map(|(r, &j)| model.joints[j].drive.rotor().map(|rotor| 0.5 * rotor.inertia * st.qd[n + r] * st.qd[n + r]))
            .sum();
    }

    pub(crate) fn log_transition(&mut self, joint: usize, from: Phase, to: Phase) {
        if from == to {
            return;
        }
        if self.transitions.len() < TRANSITION_LOG_CAPACITY {
            let n = self.model.nq();
            let drive_force = if joint < n { self.state.drive_force[joint] } else { self.state.motor_torque[joint - n] };
            self.transitions.push(Transition { time: self.state.time, joint, from, to, drive_force });
        } else {
            self.transitions_dropped += 1;
        }
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

/// Checks three input vectors (a value and its two derivatives) against
/// their names and ranges: n values each, finite, inside the range.
fn check_input_values(n: usize, ranges: [(&'static str, Range); 3], values: [&[f64]; 3]) -> Result<(), StepError> {
    for ((field, range), values) in ranges.into_iter().zip(values) {
        if values.len() != n {
            return Err(StepError::InputLength { field, expected: n, got: values.len() });
        }
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(StepError::NonFiniteInput { field, joint: i + 1, value: *v });
        }
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !range.contains(**v)) {
            return Err(StepError::InputOutOfRange { field, joint: i + 1, value: *v, range: range.to_string() });
        }
    }
    Ok(())
}
