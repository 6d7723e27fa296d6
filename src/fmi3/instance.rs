//! One FMI 3.0 co-simulation instance: the FMI 2.0 [`Instance`] (life cycle,
//! values, engine, FMU states) with FMI 3.0's modes on top, the arrays'
//! value references, and `fmi3DoStep` with early return and intermediate
//! update. Safe Rust except for calling the master's callback.

use super::frame::Reentry;
use super::values::{no_variables_of, scalar_slots, slots, variable, Held, Slot};
use crate::error::StepError;
use crate::fmi::description::{variables3, Type3, Variable, Variable3};
use crate::fmi::instance::Instance;
use crate::fmi::lifecycle::LifeCycle;
use crate::fmi::status::{Fault, Outcome, Status};
use crate::stepper::{Flow, SubStep};
use fmi_sys::fmi2::fmi2Boolean;
use fmi_sys::fmi3::{fmi3InstanceEnvironment, fmi3IntermediateUpdateCallback};
use std::sync::Arc;

/// The FMI 3.0 co-simulation modes an instance can be in (FMI's names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(clippy::enum_variant_names)]
pub(crate) enum Mode {
    Instantiated,
    InitializationMode,
    EventMode,
    StepMode,
    Terminated,
    /// After an internal failure (a caught panic): reset, FMU state, free.
    Error,
}

impl Mode {
    const ALL: [Mode; 6] =
        [Mode::Instantiated, Mode::InitializationMode, Mode::EventMode, Mode::StepMode, Mode::Terminated, Mode::Error];

    fn name(self) -> &'static str {
        match self {
            Mode::Instantiated => "Instantiated",
            Mode::InitializationMode => "Initialization Mode",
            Mode::EventMode => "Event Mode",
            Mode::StepMode => "Step Mode",
            Mode::Terminated => "Terminated",
            Mode::Error => "error",
        }
    }
}

/// A set of modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Modes(u8);

impl Modes {
    pub(crate) const fn of(list: &[Mode]) -> Modes {
        let mut bits = 0;
        let mut i = 0;
        while i < list.len() {
            bits |= 1 << list[i] as u8;
            i += 1;
        }
        Modes(bits)
    }

    fn contains(self, mode: Mode) -> bool {
        self.0 & (1 << mode as u8) != 0
    }

    fn names(self) -> String {
        Mode::ALL.iter().filter(|m| self.contains(**m)).map(|m| m.name()).collect::<Vec<_>>().join(", ")
    }
}

/// What one `fmi3DoStep` reports besides its status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepReport {
    pub(crate) event_handling_needed: bool,
    pub(crate) early_return: bool,
    pub(crate) last_successful_time: f64,
}

/// One FMI 3.0 instance.
pub(crate) struct Instance3 {
    pub(crate) inner: Instance,
    /// The FMI 3.0 variables; value reference = index.
    pub(crate) vars: Arc<[Variable3]>,
    /// The FMI 2.0 variables they group.
    pub(crate) scalars: Arc<[Variable]>,
    /// In Event Mode rather than Step Mode (when running).
    event_mode: bool,
    event_mode_used: bool,
    early_return_allowed: bool,
    intermediate: fmi3IntermediateUpdateCallback,
    environment: fmi3InstanceEnvironment,
    /// After an early return: its instant and the master's communication
    /// interval it fell in (the step that resumes there continues the held
    /// inputs the master re-sampled: [`Instance::continue_held_inputs`]).
    resume: Option<(f64, f64)>,
}

impl Instance3 {
    pub(crate) fn new(
        inner: Instance,
        event_mode_used: bool,
        early_return_allowed: bool,
        intermediate: fmi3IntermediateUpdateCallback,
        environment: fmi3InstanceEnvironment,
    ) -> Instance3 {
        let scalars: Arc<[Variable]> = inner.variables().into();
        let vars: Arc<[Variable3]> = variables3(&scalars).into();
        debug_assert!(vars.iter().enumerate().all(|(i, v)| v.value_reference as usize == i));
        Instance3 {
            inner,
            vars,
            scalars,
            event_mode: false,
            event_mode_used,
            early_return_allowed,
            intermediate,
            environment,
            resume: None,
        }
    }

    /// The current mode.
    pub(crate) fn mode(&self) -> Mode {
        match self.inner.lifecycle() {
            LifeCycle::Instantiated => Mode::Instantiated,
            LifeCycle::InitializationMode => Mode::InitializationMode,
            LifeCycle::StepComplete | LifeCycle::StepFailed if self.event_mode => Mode::EventMode,
            LifeCycle::StepComplete | LifeCycle::StepFailed => Mode::StepMode,
            LifeCycle::Terminated => Mode::Terminated,
            LifeCycle::Error => Mode::Error,
        }
    }

    /// Checks the call sequence.
    pub(crate) fn check_mode(&self, allowed: Modes) -> Result<(), Fault> {
        let mode = self.mode();
        if allowed.contains(mode) {
            return Ok(());
        }
        Err(Fault::error(format!(
            "illegal call sequence: not allowed in {} (allowed in: {})",
            mode.name(),
            allowed.names()
        )))
    }

    // ---- life cycle -------------------------------------------------------------

    /// fmi3EnterInitializationMode: fmi2SetupExperiment and
    /// fmi2EnterInitializationMode in one.
    pub(crate) fn enter_initialization_mode(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Outcome {
        let status = self.inner.setup_experiment(tolerance, start, stop)?;
        Ok(status.max(self.inner.enter_initialization_mode()?))
    }

    /// fmi3ExitInitializationMode: into Event Mode if the master uses it,
    /// else Step Mode.
    pub(crate) fn exit_initialization_mode(&mut self) -> Outcome {
        let status = self.inner.exit_initialization_mode()?;
        self.event_mode = self.event_mode_used;
        Ok(status)
    }

    /// fmi3EnterEventMode.
    pub(crate) fn enter_event_mode(&mut self) -> Outcome {
        if !self.event_mode_used {
            return Err(Fault::error("the instance was made with eventModeUsed = false"));
        }
        self.event_mode = true;
        Ok(Status::Ok)
    }

    /// fmi3EnterStepMode.
    pub(crate) fn enter_step_mode(&mut self) -> Outcome {
        self.event_mode = false;
        Ok(Status::Ok)
    }

    /// fmi3Reset.
    pub(crate) fn reset(&mut self) -> Outcome {
        self.event_mode = false;
        self.resume = None;
        self.inner.reset()
    }

    /// fmi3SetFMUState: the instance at the state's time, no early return
    /// pending.
    pub(crate) fn restore(&mut self, bytes: &[u8]) -> Outcome {
        self.resume = None;
        self.inner.restore(bytes)
    }

    // ---- values -------------------------------------------------------------------

    /// The FMI 3.0 variable `vr`.
    fn variable(&self, vr: u32) -> Result<&Variable3, Fault> {
        variable(&self.vars, vr)
    }

    /// The elements of `vrs`, of type `ty` each, `n_values` of them in all.
    fn slots(&self, vrs: &[u32], ty: Type3, n_values: usize) -> Result<Vec<Slot>, Fault> {
        slots(&self.vars, vrs, ty, n_values)
    }

    /// fmi3GetFloat64.
    pub(crate) fn get_float64(&mut self, vrs: &[u32], values: &mut [f64]) -> Outcome {
        let slots = self.slots(vrs, Type3::Float64, values.len())?;
        self.get_reals(&slots, values)
    }

    /// fmi3GetInt32: the counts.
    pub(crate) fn get_int32(&mut self, vrs: &[u32], values: &mut [i32]) -> Outcome {
        let slots = self.slots(vrs, Type3::Int32, values.len())?;
        let mut reals = vec![0.0; values.len()];
        let status = self.get_reals(&slots, &mut reals)?;
        for (out, x) in values.iter_mut().zip(reals) {
            *out = x as i32;
        }
        Ok(status)
    }

    fn get_reals(&mut self, slots: &[Slot], values: &mut [f64]) -> Outcome {
        let scalars: Vec<u32> =
            slots.iter().filter_map(|s| if let Slot::Scalar(vr) = s { Some(*vr) } else { None }).collect();
        let mut got = vec![0.0; scalars.len()];
        let status = self.inner.get_real(&scalars, &mut got)?;
        let time = self.inner.time();
        let mut got = got.into_iter();
        for (slot, out) in slots.iter().zip(values) {
            *out = match slot {
                Slot::Time => time,
                Slot::Scalar(_) => got.next().unwrap_or(f64::NAN),
            };
        }
        Ok(status)
    }

    /// fmi3GetBoolean.
    pub(crate) fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> Outcome {
        let scalars = scalar_slots(self.slots(vrs, Type3::Boolean, values.len())?);
        let mut got: Vec<fmi2Boolean> = vec![0; scalars.len()];
        let status = self.inner.get_boolean(&scalars, &mut got)?;
        for (out, b) in values.iter_mut().zip(got) {
            *out = b != 0;
        }
        Ok(status)
    }

    /// fmi3SetFloat64.
    pub(crate) fn set_float64(&mut self, vrs: &[u32], values: &[f64]) -> Outcome {
        let slots = self.slots(vrs, Type3::Float64, values.len())?;
        if slots.contains(&Slot::Time) {
            return Err(Fault::error("`time` (value reference 0) is the independent variable: it cannot be set"));
        }
        self.inner.set_real(&scalar_slots(slots), values)
    }

    /// fmi3SetInt32: every Int32 variable is an output, which the FMI 2.0
    /// instance refuses by name.
    pub(crate) fn set_int32(&mut self, vrs: &[u32], values: &[i32]) -> Outcome {
        let slots = self.slots(vrs, Type3::Int32, values.len())?;
        let reals: Vec<f64> = values.iter().map(|x| f64::from(*x)).collect();
        self.inner.set_real(&scalar_slots(slots), &reals)
    }

    /// fmi3SetBoolean.
    pub(crate) fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> Outcome {
        let slots = self.slots(vrs, Type3::Boolean, values.len())?;
        let ints: Vec<fmi2Boolean> = values.iter().map(|b| fmi2Boolean::from(*b)).collect();
        self.inner.set_boolean(&scalar_slots(slots), &ints)
    }

    /// A getter or setter of a type the FMU has no variable of: fine for no
    /// value references, an error naming the type otherwise.
    pub(crate) fn no_variables_of(&self, kind: &str, vrs: &[u32]) -> Outcome {
        no_variables_of(&self.vars, kind, vrs)
    }

    /// fmi3GetOutputDerivatives: dq/dt = qd and d²q/dt² = qdd of the joint
    /// coordinates `q`, dqd/dt = qdd of the velocities `qd`, at the current
    /// communication point (the engine's own values, not a difference).
    pub(crate) fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> Outcome {
        let mut scalars = Vec::with_capacity(values.len());
        for (vr, order) in vrs.iter().zip(orders) {
            let v = self.variable(*vr)?;
            let derivative = match (v.name.as_str(), order) {
                ("q", 1) => "qd",
                ("q", 2) | ("qd", 1) => "qdd",
                (name, order) => {
                    return Err(Fault::error(format!(
                        "no derivative of order {order} of `{name}` (value reference {vr}): the FMU provides those \
                         of `q` (orders 1 and 2) and `qd` (order 1)"
                    )))
                }
            };
            let d = self.vars.iter().find(|w| w.name == derivative).ok_or_else(|| Fault::error("no `qd`/`qdd`"))?;
            scalars.extend_from_slice(&d.elements);
        }
        if scalars.len() != values.len() {
            return Err(Fault::error(format!(
                "nValues = {} but the variables have {} elements",
                values.len(),
                scalars.len()
            )));
        }
        self.inner.get_real(&scalars, values)
    }

    // ---- stepping -------------------------------------------------------------------

    /// fmi3DoStep. Without early return and intermediate update this is the
    /// FMI 2.0 step, bit for bit. With them, the step is observed at every
    /// sub-step: the master's callback is called at each (with the outputs
    /// and held inputs there in `reentry`'s frame, and the inputs it sets
    /// taken from there on), and the step ends at the first event if early
    /// return is allowed, or where the master asks for it.
    pub(crate) fn do_step(&mut self, t: f64, h: f64, reentry: &Reentry<'_>) -> Result<(Status, StepReport), Fault> {
        if self.intermediate.is_none() && !self.early_return_allowed {
            let status = self.inner.do_step(t, h)?;
            let report = StepReport {
                event_handling_needed: false,
                early_return: false,
                last_successful_time: self.inner.time(),
            };
            return Ok((status, report));
        }
        // A step that resumes at an early return's instant: inputs the master
        // set there that re-sample the held signal continue it (docs/fmi3.md,
        // early return): a drive does not jump at an instant the FMU chose.
        let interval = match self.resume.take() {
            Some((at, interval)) if (t - at).abs() <= 1e-9 * at.abs().max(1.0) => {
                self.inner.continue_held_inputs(interval);
                interval
            }
            _ => h,
        };
        let (callback, environment, early_allowed) = (self.intermediate, self.environment, self.early_return_allowed);
        let scalars = Arc::clone(&self.scalars);
        let n = self.inner.simulator().model().nq();
        let mut held = Held::new(n);
        let mut stopped_at_event = false;
        let mut inputs_set = false;
        let mut after = |step: &mut SubStep<'_>| -> Result<Flow, StepError> {
            let event = step.event();
            let mut stop = event && early_allowed;
            if let Some(callback) = callback {
                let time = step.time();
                held.take(step);
                reentry.fill(time, &scalars, step.reported(), &held);
                let (mut requested, mut requested_time) = (false, time);
                reentry.enter();
                // SAFETY: the master's callback, given at instantiation, with
                // its own environment; the output arguments live through the call.
                unsafe { callback(environment, time, true, true, true, stop, &mut requested, &mut requested_time) };
                reentry.leave();
                if reentry.take_inputs(&scalars, &mut held) {
                    step.set_inputs(&held.drive(), &held.torques())?;
                    inputs_set = true;
                }
                stop |= requested && early_allowed;
            }
            stopped_at_event = stop && event;
            Ok(if stop { Flow::Stop } else { Flow::Continue })
        };
        let (status, flow) = self.inner.do_step_observed(t, h, &mut after)?;
        let early_return = flow == Flow::Stop;
        if early_return || inputs_set {
            self.inner.hold_inputs_now();
        }
        if early_return {
            self.resume = Some((self.inner.time(), interval));
        }
        let report = StepReport {
            event_handling_needed: early_return && stopped_at_event && self.event_mode_used,
            early_return,
            last_successful_time: self.inner.time(),
        };
        Ok((status, report))
    }
}
