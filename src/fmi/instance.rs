//! One FMU instance: its life cycle, the values the master set, and the
//! simulator. Safe Rust only; `boundary.rs` turns pointers into slices and
//! results into `fmi2Status`, `exports.rs` says which states allow a call.

use super::description::{self, Causality, Output, Quantity, Setting, Type, Variability, Variable};
use super::lifecycle::{LifeCycle, States};
use super::logger::{Category, Logger};
use super::snapshot::{self, Snapshot};
use super::status::{Fault, Outcome, Status};
use crate::error::StepError;
use crate::model::{Model, ModelSource};
#[cfg(feature = "fmi3")]
use crate::stepper::SubStep;
use crate::stepper::{
    DriveInputs, Flow, InitialState, MotorTorques, Phase, RotorStart, Simulator, State, INPUT_RANGES,
    MOTOR_TORQUE_RANGES,
};
use fmi_sys::fmi2::{fmi2Boolean, fmi2Integer, fmi2ValueReference};

/// The value of a variable.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Value {
    Real(f64),
    Boolean(bool),
}

/// The result of [`finite_outputs`].
type FiniteCheck = Result<(), (String, f64)>;

/// Relative tolerance on the communication point, × max(1, |t|).
const TIME_TOLERANCE: f64 = 1e-9;

/// An instance of the FMU.
#[derive(Clone)]
pub(crate) struct Instance {
    variables: Vec<Variable>,
    model_hash: u128,
    guid: String,
    /// The model as read from `resources/model.toml` (what fmi2Reset returns to).
    base: Model,
    /// The engine; its model carries the parameter values the master set.
    sim: Simulator,
    lifecycle: LifeCycle,
    start_time: f64,
    stop_time: Option<f64>,
    /// q*, q̇*, q̈* as set by the master (index = `InputField::index`).
    inputs: [Vec<f64>; 3],
    /// τ_m and its first two derivatives as set by the master, per joint.
    torques: [Vec<f64>; 3],
    use_start_values: bool,
    q_start: Vec<f64>,
    qd_start: Vec<f64>,
    theta_m_start: Vec<f64>,
    omega_m_start: Vec<f64>,
    static_start: bool,
    /// Before step mode: the engine must be (re)started from the current
    /// values before outputs are read.
    stale: bool,
    /// Ignored higher input derivatives were reported (once per instance:
    /// masters such as fmpy send them at every step).
    ignored_derivatives_reported: bool,
    pub(crate) logger: Logger,
}

fn drive_inputs(inputs: &[Vec<f64>; 3]) -> DriveInputs<'_> {
    DriveInputs { q_star: &inputs[0], qd_star: &inputs[1], qdd_star: &inputs[2] }
}

fn motor_torques(torques: &[Vec<f64>; 3]) -> MotorTorques<'_> {
    MotorTorques { tau_m: &torques[0], tau_m_rate: &torques[1], tau_m_accel: &torques[2] }
}

fn output_value(s: &State, o: Output) -> Value {
    let x = o.value(s);
    if o.kind().boolean {
        Value::Boolean(x != 0.0)
    } else {
        Value::Real(x)
    }
}

/// Every output of `variables` is finite in `s`, and so is the rest of the
/// state; otherwise the first output (or state field) that is not, by name.
fn finite_outputs(variables: &[Variable], s: &State) -> Result<(), (String, f64)> {
    for v in variables {
        if let Quantity::Output(o) = v.quantity {
            let x = o.value(s);
            if !x.is_finite() {
                return Err((format!("output `{}`", v.name), x));
            }
        }
    }
    s.check_finite()
}

fn phase_name(p: Phase) -> &'static str {
    match p {
        Phase::Prescribed => "prescribed",
        Phase::Stuck => "stuck",
        Phase::Slipping(d) if d > 0 => "slipping (+)",
        Phase::Slipping(_) => "slipping (-)",
    }
}

/// "joint 3" for a joint's coordinate, "rotor of joint 1" for a motor's.
fn coordinate_name(model: &Model, coordinate: usize) -> String {
    let n = model.nq();
    if coordinate < n {
        format!("joint {}", coordinate + 1)
    } else {
        let joint = model.motor_joints().get(coordinate - n).copied().unwrap_or(0);
        format!("rotor of joint {}", joint + 1)
    }
}

fn type_error(v: &Variable, expected: &str) -> Fault {
    let actual = match v.ty {
        Type::Real { .. } => "Real",
        Type::Boolean { .. } => "Boolean",
    };
    Fault::error(format!("`{}` (value reference {}) is a {actual} variable, not {expected}", v.name, v.value_reference))
}

impl Instance {
    /// An instance of the model in `source` (a model file and the URDF it
    /// names), logging to `logger`; the model's warnings are logged.
    pub(crate) fn new(source: &ModelSource, logger: Logger) -> Result<Instance, String> {
        let model = source.model().map_err(|e| e.to_string())?;
        for warning in &model.warnings {
            logger.log(Status::Warning, Category::StatusWarning, &format!("model `{}`: {warning}", model.name));
        }
        let mut variables = description::variables(&model);
        let n = model.nq();
        let text = source.fingerprint_text();
        let model_hash = description::model_hash(&text, &variables);
        let guid = description::guid(&text, &variables);
        // The descriptions are modelDescription.xml's and the documentation's
        // (a third of an instance's heap); an instance never reads them.
        for v in &mut variables {
            v.description = String::new();
        }
        let mut instance = Instance {
            model_hash,
            guid,
            variables,
            sim: Simulator::new(model.clone()).map_err(|e| e.to_string())?,
            base: model,
            lifecycle: LifeCycle::Instantiated,
            start_time: 0.0,
            stop_time: None,
            inputs: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            torques: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            use_start_values: false,
            q_start: vec![0.0; n],
            qd_start: vec![0.0; n],
            theta_m_start: vec![0.0; n],
            omega_m_start: vec![0.0; n],
            static_start: false,
            stale: true,
            ignored_derivatives_reported: false,
            logger,
        };
        instance.reset().map_err(|f| f.message)?;
        Ok(instance)
    }

    /// The GUID of the model this instance runs.
    pub(crate) fn guid(&self) -> &str {
        &self.guid
    }

    /// Checks the call sequence.
    pub(crate) fn check_state(&self, allowed: States) -> Result<(), Fault> {
        if allowed.contains(self.lifecycle) {
            return Ok(());
        }
        Err(Fault::error(format!(
            "illegal call sequence: not allowed in state `{}` (allowed in: {})",
            self.lifecycle.name(),
            allowed.names()
        )))
    }

    /// After a caught panic: the instance may be inconsistent, so only
    /// reset, restore, terminate, getters and free remain.
    pub(crate) fn fail(&mut self, function: &str, reason: &str) {
        self.lifecycle = LifeCycle::Error;
        self.logger.log(
            Status::Error,
            Category::StatusError,
            &format!("{function}: internal error ({reason}); the instance is in the error state: call fmi2Reset, fmi2SetFMUstate, fmi2Terminate or fmi2FreeInstance"),
        );
    }

    /// The FMU's time: the engine's once it runs, else the start time.
    pub(crate) fn time(&self) -> f64 {
        if self.lifecycle.is_running() {
            self.sim.state().time
        } else {
            self.start_time
        }
    }

    fn variable(&self, vr: fmi2ValueReference) -> Result<&Variable, Fault> {
        self.variables.get(vr as usize).ok_or_else(|| {
            Fault::error(format!("unknown value reference {vr} (this FMU has 0 to {})", self.variables.len() - 1))
        })
    }

    // ---- life cycle -------------------------------------------------------

    /// fmi2Reset: back to the state after fmi2Instantiate.
    pub(crate) fn reset(&mut self) -> Outcome {
        let n = self.base.nq();
        self.sim = Simulator::new(self.base.clone()).map_err(|e| Fault::error(e.to_string()))?;
        self.lifecycle = LifeCycle::Instantiated;
        self.start_time = 0.0;
        self.stop_time = None;
        self.inputs = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        self.torques = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        self.use_start_values = false;
        self.q_start = vec![0.0; n];
        self.qd_start = vec![0.0; n];
        self.theta_m_start = vec![0.0; n];
        self.omega_m_start = vec![0.0; n];
        self.static_start = false;
        self.stale = true;
        self.ignored_derivatives_reported = false;
        Ok(Status::Ok)
    }

    /// fmi2SetDebugLogging.
    pub(crate) fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Outcome {
        self.logger.set_debug_logging(on, categories).map_err(Fault::error)?;
        Ok(Status::Ok)
    }

    /// fmi2SetupExperiment (the master's tolerance is not used: the Newmark
    /// tolerance is the `tolerance` parameter).
    ///
    /// A defined `tolerance` is the relative error tolerance of the
    /// error-controlled sub-steps, the `error_tolerance` parameter (FMI 2.0
    /// §4.2.4: the tolerance of an FMU's internal integrator).
    pub(crate) fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: Option<f64>) -> Outcome {
        if !start.is_finite() {
            return Err(Fault::error(format!("startTime = {start} s is not finite")));
        }
        if let Some(stop) = stop.filter(|s| !(s.is_finite() && *s >= start)) {
            return Err(Fault::error(format!(
                "stopTime = {stop} s is not a finite time at or after startTime = {start} s"
            )));
        }
        if let Some(tolerance) = tolerance {
            let setting = Setting::ErrorTolerance;
            setting.check(tolerance).map_err(|e| Fault::error(format!("fmi2SetupExperiment: tolerance sets {e}")))?;
            let mut model = self.sim.model().clone();
            setting.set(&mut model.integrator, tolerance);
            self.sim.set_model(model).map_err(|e| Fault::error(e.to_string()))?;
        }
        self.start_time = start;
        self.stop_time = stop;
        self.stale = true;
        Ok(Status::Ok)
    }

    /// fmi2EnterInitializationMode.
    pub(crate) fn enter_initialization_mode(&mut self) -> Outcome {
        self.lifecycle = LifeCycle::InitializationMode;
        self.stale = true;
        Ok(Status::Ok)
    }

    /// fmi2ExitInitializationMode: starts the engine from the inputs, start
    /// values and parameters. On failure the instance stays in
    /// initialization mode, so that the master can correct the values.
    pub(crate) fn exit_initialization_mode(&mut self) -> Outcome {
        self.start_engine()?;
        self.lifecycle = LifeCycle::StepComplete;
        if self.logger.enabled(Category::Events) {
            let s = self.sim.state();
            let phases: Vec<String> = s
                .phase
                .iter()
                .enumerate()
                .map(|(c, p)| format!("{} {}", coordinate_name(&self.base, c), phase_name(*p)))
                .collect();
            self.logger.log(
                Status::Ok,
                Category::Events,
                &format!("t = {} s: initialized; {}", s.time, phases.join(", ")),
            );
        }
        if self.use_start_values && !self.static_start && self.warn_loaded_gear_springs() {
            return Ok(Status::Warning);
        }
        Ok(Status::Ok)
    }

    /// Starts the engine at the start time if a value changed since.
    fn start_engine(&mut self) -> Result<(), Fault> {
        if !self.stale {
            return Ok(());
        }
        let mut sim = Simulator::new(self.sim.model().clone())
            .map_err(|e| Fault::error(format!("the model is not valid: {e}")))?;
        let initial = self.use_start_values.then_some(InitialState { q: &self.q_start, qd: &self.qd_start });
        let rotor_start = if self.static_start {
            RotorStart::StaticEquilibrium
        } else if self.use_start_values {
            RotorStart::At { theta_m: self.theta_m_start.clone(), omega_m: self.omega_m_start.clone() }
        } else {
            RotorStart::Unloaded
        };
        sim.set_rotor_start(rotor_start).map_err(|e| Fault::error(format!("start values: {e}")))?;
        sim.set_motor_torques(&motor_torques(&self.torques)).map_err(|e| Fault::error(e.to_string()))?;
        let variables = &self.variables;
        sim.initialize_checked(self.start_time, &drive_inputs(&self.inputs), initial, |s| finite_outputs(variables, s))
            .map_err(|e| Fault::error(format!("initialization at t = {} s failed: {e}", self.start_time)))?;
        self.sim = sim;
        self.stale = false;
        self.log_transitions();
        Ok(())
    }

    /// A rotor started at `theta_m_start[i]` whose gear spring is then
    /// deflected past its clearance (typically: `q_start[i]` set and
    /// `theta_m_start[i]` left at 0) starts with a gear force the user may not
    /// have meant; the log says so and how to start it unloaded. True if it
    /// warned (fmi2ExitInitializationMode then returns fmi2Warning).
    fn warn_loaded_gear_springs(&self) -> bool {
        let model = self.sim.model();
        let s = self.sim.state();
        let mut warned = false;
        for (r, &j) in model.motor_joints().iter().enumerate() {
            let drive = model.joints[j].drive;
            let (Some(spring), Some(rotor)) = (drive.spring(), drive.rotor()) else { continue };
            let n = rotor.gear_ratio;
            let units = description::joint_units(model.joints[j].kind);
            let deflection = s.theta_m(r) / n - s.q[j];
            if deflection.abs() > spring.clearance {
                warned = true;
                self.logger.log(
                    Status::Warning,
                    Category::StatusWarning,
                    &format!(
                        "joint {joint}: theta_m_start[{joint}] = {theta} rad with q = {q} {length} starts the gear spring \
                         deflected by {excess:.6e} {length} beyond its clearance, a gear force of {force:.6e} {force_unit}; for an \
                         unloaded start set theta_m_start[{joint}] = gear_ratio * q_start[{joint}] = {unloaded}, or \
                         static_start = true for a start that holds the arm",
                        joint = j + 1,
                        theta = s.theta_m(r),
                        q = s.q[j],
                        length = units.coordinate,
                        excess = deflection.abs() - spring.clearance,
                        force = s.drive_force[j].abs(),
                        force_unit = units.force,
                        unloaded = n * s.q[j],
                    ),
                );
            }
        }
        warned
    }

    /// fmi2Terminate.
    pub(crate) fn terminate(&mut self) -> Outcome {
        self.lifecycle = LifeCycle::Terminated;
        Ok(Status::Ok)
    }

    // ---- getters and setters ------------------------------------------------

    fn value(&self, q: Quantity) -> Value {
        match q {
            Quantity::Input(field, j) => Value::Real(self.inputs[field.index()][j]),
            Quantity::Output(o) => output_value(self.sim.state(), o),
            // The layout lists only the parameters a joint has.
            Quantity::Parameter(p, j) => Value::Real(self.sim.model().parameter(p, j).unwrap_or(f64::NAN)),
            Quantity::Setting(s) => Value::Real(s.get(&self.sim.model().integrator)),
            Quantity::UseStartValues => Value::Boolean(self.use_start_values),
            Quantity::StartQ(j) => Value::Real(self.q_start[j]),
            Quantity::StartQd(j) => Value::Real(self.qd_start[j]),
            Quantity::MotorTorque(j) => Value::Real(self.torques[0][j]),
            Quantity::StartThetaM(j) => Value::Real(self.theta_m_start[j]),
            Quantity::StartOmegaM(j) => Value::Real(self.omega_m_start[j]),
            Quantity::StaticStart => Value::Boolean(self.static_start),
        }
    }

    /// Before step mode, outputs come from starting the engine with the
    /// current values (initial unknowns).
    fn prepare_outputs(&mut self, vrs: &[fmi2ValueReference]) -> Result<(), Fault> {
        let wants_output =
            || vrs.iter().any(|vr| self.variables.get(*vr as usize).is_some_and(|v| v.causality == Causality::Output));
        if self.lifecycle.is_configuring() && wants_output() {
            self.start_engine()?;
        }
        Ok(())
    }

    /// fmi2GetReal.
    pub(crate) fn get_real(&mut self, vrs: &[fmi2ValueReference], values: &mut [f64]) -> Outcome {
        self.prepare_outputs(vrs)?;
        for (vr, out) in vrs.iter().zip(values) {
            let v = self.variable(*vr)?;
            match self.value(v.quantity) {
                Value::Real(x) => *out = x,
                Value::Boolean(_) => return Err(type_error(v, "Real")),
            }
        }
        Ok(Status::Ok)
    }

    /// fmi2GetBoolean.
    pub(crate) fn get_boolean(&mut self, vrs: &[fmi2ValueReference], values: &mut [fmi2Boolean]) -> Outcome {
        self.prepare_outputs(vrs)?;
        for (vr, out) in vrs.iter().zip(values) {
            let v = self.variable(*vr)?;
            match self.value(v.quantity) {
                Value::Boolean(b) => *out = fmi2Boolean::from(b),
                Value::Real(_) => return Err(type_error(v, "Boolean")),
            }
        }
        Ok(Status::Ok)
    }

    /// fmi2Get/SetInteger, fmi2Get/SetString: this FMU has no such variables.
    pub(crate) fn no_variables_of(&self, kind: &str, vrs: &[fmi2ValueReference]) -> Outcome {
        match vrs.first() {
            None => Ok(Status::Ok),
            Some(vr) => Err(self.variable(*vr).map_or_else(|f| f, |v| type_error(v, kind))),
        }
    }

    /// Whether the master may set `v` now.
    fn check_settable(&self, v: &Variable) -> Result<(), Fault> {
        match (v.causality, v.variability) {
            (Causality::Output, _) => Err(Fault::error(format!("`{}` is an output; outputs cannot be set", v.name))),
            (Causality::Parameter, Variability::Fixed) if !self.lifecycle.is_configuring() => Err(Fault::error(
                format!("`{}` is a fixed parameter: it can be set only before fmi2ExitInitializationMode", v.name),
            )),
            _ => Ok(()),
        }
    }

    /// fmi2SetReal: every value is checked before any is stored, so a
    /// rejected call changes nothing. Parameters and settings go into a new
    /// model that the engine runs with from its next step (the model in use
    /// is never changed in place).
    pub(crate) fn set_real(&mut self, vrs: &[fmi2ValueReference], values: &[f64]) -> Outcome {
        let mut trial: Option<Model> = None;
        for (vr, x) in vrs.iter().zip(values) {
            let v = self.variable(*vr)?;
            if !matches!(v.ty, Type::Real { .. }) {
                return Err(type_error(v, "Real"));
            }
            if !x.is_finite() {
                return Err(Fault::error(format!("`{}` = {x} is not a finite number", v.name)));
            }
            self.check_settable(v)?;
            match v.quantity {
                Quantity::Input(field, _) => {
                    let range = INPUT_RANGES[field.index()].1;
                    if !range.contains(*x) {
                        return Err(Fault::error(format!("`{}` = {x:e} lies outside its range {range}", v.name)));
                    }
                }
                Quantity::MotorTorque(_) => {
                    let range = MOTOR_TORQUE_RANGES[0].1;
                    if !range.contains(*x) {
                        return Err(Fault::error(format!("`{}` = {x:e} lies outside its range {range}", v.name)));
                    }
                }
                Quantity::Parameter(p, j) => trial
                    .get_or_insert_with(|| self.sim.model().clone())
                    .set_parameter(p, j, *x)
                    .map_err(|e| Fault::error(e.to_string()))?,
                Quantity::Setting(s) => {
                    s.check(*x).map_err(Fault::error)?;
                    s.set(&mut trial.get_or_insert_with(|| self.sim.model().clone()).integrator, *x);
                }
                _ => {}
            }
        }
        for (vr, x) in vrs.iter().zip(values) {
            let q = self.variables[*vr as usize].quantity;
            if !matches!(q, Quantity::Parameter(..) | Quantity::Setting(_)) {
                self.store(q, Value::Real(*x))?;
            }
        }
        if let Some(model) = trial {
            self.sim.set_model(model).map_err(|e| Fault::error(e.to_string()))?;
            if self.lifecycle.is_configuring() {
                self.stale = true;
            }
        }
        Ok(Status::Ok)
    }

    /// fmi2SetBoolean.
    pub(crate) fn set_boolean(&mut self, vrs: &[fmi2ValueReference], values: &[fmi2Boolean]) -> Outcome {
        for vr in vrs {
            let v = self.variable(*vr)?;
            if !matches!(v.ty, Type::Boolean { .. }) {
                return Err(type_error(v, "Boolean"));
            }
            self.check_settable(v)?;
        }
        for (vr, b) in vrs.iter().zip(values) {
            self.store(self.variables[*vr as usize].quantity, Value::Boolean(*b != 0))?;
        }
        Ok(Status::Ok)
    }

    /// Stores a checked value of an input or a start value (parameters go
    /// into the engine's model, see [`Instance::set_real`]).
    fn store(&mut self, q: Quantity, value: Value) -> Result<(), Fault> {
        match (q, value) {
            (Quantity::Input(field, j), Value::Real(x)) => self.inputs[field.index()][j] = x,
            (Quantity::StartQ(j), Value::Real(x)) => self.q_start[j] = x,
            (Quantity::StartQd(j), Value::Real(x)) => self.qd_start[j] = x,
            (Quantity::UseStartValues, Value::Boolean(b)) => self.use_start_values = b,
            (Quantity::MotorTorque(j), Value::Real(x)) => self.torques[0][j] = x,
            (Quantity::StartThetaM(j), Value::Real(x)) => self.theta_m_start[j] = x,
            (Quantity::StartOmegaM(j), Value::Real(x)) => self.omega_m_start[j] = x,
            (Quantity::StaticStart, Value::Boolean(b)) => self.static_start = b,
            (q, v) => return Err(Fault::error(format!("{v:?} cannot be stored in {q:?}"))),
        }
        if self.lifecycle.is_configuring() {
            self.stale = true;
        }
        Ok(())
    }

    /// fmi2SetRealInputDerivatives: derivative `order` of input `q_star[i]`
    /// (1: q̇*, 2: q̈*) or `qd_star[i]` (1: q̈*) sets that input. Higher
    /// derivatives have no place in the engine's second-order input
    /// polynomial: zero ones are accepted, others are ignored with
    /// fmi2Warning (the message is logged for the first one only).
    pub(crate) fn set_real_input_derivatives(
        &mut self,
        vrs: &[fmi2ValueReference],
        orders: &[fmi2Integer],
        values: &[f64],
    ) -> Outcome {
        let mut updates = Vec::with_capacity(vrs.len());
        let mut ignored = Vec::new();
        for ((vr, order), x) in vrs.iter().zip(orders).zip(values) {
            let v = self.variable(*vr)?;
            // Which polynomial the variable belongs to, and its place in it.
            let (is_torque, base, j) = match v.quantity {
                Quantity::Input(field, j) => (false, field.index(), j),
                Quantity::MotorTorque(j) => (true, 0, j),
                _ => {
                    return Err(Fault::error(format!(
                        "`{}` is not an input; only inputs have input derivatives",
                        v.name
                    )))
                }
            };
            if *order < 1 {
                return Err(Fault::error(format!("derivative order {order} of `{}`: orders start at 1", v.name)));
            }
            if !x.is_finite() {
                return Err(Fault::error(format!(
                    "derivative of order {order} of `{}` = {x} is not a finite number",
                    v.name
                )));
            }
            let ranges = if is_torque { MOTOR_TORQUE_RANGES } else { INPUT_RANGES };
            match base + *order as usize {
                k @ 0..=2 => {
                    let (name, range) = ranges[k];
                    if !range.contains(*x) {
                        return Err(Fault::error(format!(
                            "derivative of order {order} of `{}` sets `{name}[{}]` = {x:e}, outside its range {range}",
                            v.name,
                            j + 1
                        )));
                    }
                    updates.push((is_torque, k, j, *x))
                }
                _ if *x == 0.0 => {}
                _ => ignored.push(format!("order {order} of `{}`", v.name)),
            }
        }
        for (is_torque, k, j, x) in updates {
            if is_torque {
                self.torques[k][j] = x;
            } else {
                self.inputs[k][j] = x;
            }
        }
        if self.lifecycle.is_configuring() {
            self.stale = true;
        }
        if ignored.is_empty() {
            return Ok(Status::Ok);
        }
        if !self.ignored_derivatives_reported {
            self.ignored_derivatives_reported = true;
            self.logger.log(
                Status::Warning,
                Category::StatusWarning,
                &format!(
                    "fmi2SetRealInputDerivatives: ignored the derivative {}: the inputs are held as q* + q*' t + q*'' t^2/2 across a step (reported once; later calls return fmi2Warning without a message)",
                    ignored.join(", ")
                ),
            );
        }
        Ok(Status::Warning)
    }

    // ---- stepping ---------------------------------------------------------------

    /// fmi2DoStep.
    pub(crate) fn do_step(&mut self, t: f64, h: f64) -> Outcome {
        let advance = |sim: &mut Simulator, inputs: &DriveInputs<'_>, check: &dyn Fn(&State) -> FiniteCheck| {
            sim.advance_checked(inputs, h, check).map(|()| Flow::Continue)
        };
        self.step(t, h, advance).map(|(status, _)| status)
    }

    /// The checks and results of a step around `advance`: the FMI 2.0 step
    /// ([`Instance::do_step`]) or FMI 3.0's observed one
    /// (`Instance::do_step_observed`), one implementation monomorphized for
    /// each, and only for the first in the FMI 2.0 library (built without
    /// the feature `fmi3`).
    fn step(
        &mut self,
        t: f64,
        h: f64,
        advance: impl FnOnce(&mut Simulator, &DriveInputs<'_>, &dyn Fn(&State) -> FiniteCheck) -> Result<Flow, StepError>,
    ) -> Result<(Status, Flow), Fault> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Fault::error(format!("communicationStepSize = {h} s: must be positive and finite")));
        }
        let now = self.sim.state().time;
        let tolerance = TIME_TOLERANCE * now.abs().max(1.0);
        if !(t.is_finite() && (t - now).abs() <= tolerance) {
            return Err(Fault::error(format!("currentCommunicationPoint = {t} s is not the FMU's time {now} s")));
        }
        if let Some(stop) = self.stop_time {
            if now + h > stop + TIME_TOLERANCE * stop.abs().max(1.0) {
                return Err(Fault::error(format!("a step to t = {} s passes the stop time {stop} s", now + h)));
            }
        }
        // Checked when set: every value lies in its range.
        self.sim.set_motor_torques(&motor_torques(&self.torques)).map_err(|e| Fault::error(e.to_string()))?;
        let variables = &self.variables;
        let check = |s: &State| finite_outputs(variables, s);
        let result = advance(&mut self.sim, &drive_inputs(&self.inputs), &check);
        if result.is_err() {
            // Phase changes of a step that was not taken did not happen.
            self.sim.clear_transitions();
        }
        match result {
            Ok(flow) => {
                self.log_transitions();
                self.lifecycle = LifeCycle::StepComplete;
                Ok((Status::Ok, flow))
            }
            // The step cannot be completed, and the engine left the state at
            // its start: fmi2Discard, so that the master can react.
            Err(
                e @ (StepError::InvalidModel { .. }
                | StepError::NotConverged { .. }
                | StepError::TooMuchWork { .. }
                | StepError::SingularMassMatrix { .. }
                | StepError::NonFiniteState { .. }),
            ) => {
                self.lifecycle = LifeCycle::StepFailed;
                self.logger.log(Status::Ok, Category::Events, &format!("t = {now} s: step of {h} s discarded ({e})"));
                // The sub-steps do not depend on the communication step (a
                // failed one is halved down to h/4096 before the step fails),
                // so a shorter step does not help; other values or inputs can.
                let remedy = match e {
                    StepError::InvalidModel { .. } => "correct the parameters and repeat the step",
                    StepError::NotConverged { .. } | StepError::TooMuchWork { .. } => {
                        "a shorter communication step does not help; change the parameters or inputs named above, \
                         or restore an FMU state"
                    }
                    _ => "repeat it with other parameters or inputs, or restore an FMU state",
                };
                Err(Fault::discard(format!(
                    "step [{now}, {}] s not completed: {e}; the state stays at t = {now} s (fmi2LastSuccessfulTime); {remedy}",
                    now + h
                )))
            }
            // Excluded by the checks above and in fmi2SetReal.
            Err(e) => Err(Fault::error(e.to_string())),
        }
    }

    /// Logs the phase changes since the last call (category logEvents) and
    /// forgets them.
    fn log_transitions(&mut self) {
        if self.logger.enabled(Category::Events) {
            let (list, dropped) = self.sim.transitions();
            for t in list {
                let message = format!(
                    "t = {} s: {} {} -> {}",
                    t.time,
                    coordinate_name(&self.base, t.joint),
                    phase_name(t.from),
                    phase_name(t.to)
                );
                self.logger.log(Status::Ok, Category::Events, &message);
            }
            if dropped > 0 {
                self.logger.log(
                    Status::Ok,
                    Category::Events,
                    &format!("... and {dropped} more phase changes in this step"),
                );
            }
        }
        self.sim.clear_transitions();
    }

    /// fmi2GetRealStatus(fmi2LastSuccessfulTime): the engine's time, which
    /// a discarded step leaves at the last good communication point.
    pub(crate) fn last_successful_time(&self) -> f64 {
        self.time()
    }

    // ---- FMU states ---------------------------------------------------------------

    fn parameter_quantities(&self) -> impl Iterator<Item = Quantity> + '_ {
        self.variables
            .iter()
            .map(|v| v.quantity)
            .filter(|q| matches!(q, Quantity::Parameter(..) | Quantity::Setting(_)))
    }

    /// The variables of the FMU (the FMI 2.0 layout).
    pub(crate) fn variables(&self) -> &[Variable] {
        &self.variables
    }

    /// The engine.
    pub(crate) fn simulator(&self) -> &Simulator {
        &self.sim
    }

    /// Where the instance is in the FMI 2.0 life cycle.
    pub(crate) fn lifecycle(&self) -> LifeCycle {
        self.lifecycle
    }

    /// The engine (for `super::experiment`, which records and replays its
    /// sub-steps).
    pub(crate) fn simulator_mut(&mut self) -> &mut Simulator {
        &mut self.sim
    }

    /// A copy of this instance, values, life-cycle state and engine
    /// included, that logs nothing.
    pub(crate) fn silent_copy(&self) -> Instance {
        Instance { logger: Logger::silent(), ..self.clone() }
    }

    /// The current value of `vr`, a Real parameter or start value: what a
    /// sensitivity may be taken with respect to.
    pub(crate) fn sensitivity_variable(&self, vr: fmi2ValueReference) -> Result<(f64, &str), Fault> {
        let v = self.variable(vr)?;
        match (v.quantity, self.value(v.quantity)) {
            (
                Quantity::Parameter(..)
                | Quantity::StartQ(_)
                | Quantity::StartQd(_)
                | Quantity::StartThetaM(_)
                | Quantity::StartOmegaM(_),
                Value::Real(x),
            ) => Ok((x, &v.name)),
            _ => Err(Fault::error(format!(
                "`{}` is neither a Real parameter nor a start value: the outputs have no sensitivity to it",
                v.name
            ))),
        }
    }

    /// fmi2GetFMUstate: the serialized state.
    pub(crate) fn snapshot(&self) -> Vec<u8> {
        let parameters = self
            .parameter_quantities()
            .map(|q| match self.value(q) {
                Value::Real(x) => x,
                Value::Boolean(b) => f64::from(u8::from(b)),
            })
            .collect();
        let s = Snapshot {
            lifecycle: self.lifecycle,
            start_time: self.start_time,
            stop_time: self.stop_time,
            inputs: self.inputs.clone(),
            torques: self.torques.clone(),
            use_start_values: self.use_start_values,
            q_start: self.q_start.clone(),
            qd_start: self.qd_start.clone(),
            theta_m_start: self.theta_m_start.clone(),
            omega_m_start: self.omega_m_start.clone(),
            static_start: self.static_start,
            parameters,
            state: self.sim.state().clone(),
        };
        snapshot::encode(&s, self.model_hash)
    }

    /// Decodes `bytes` made by [`Instance::snapshot`] of an instance of the
    /// same model.
    pub(crate) fn check_snapshot(&self, bytes: &[u8]) -> Result<Snapshot, Fault> {
        let n_parameters = self.parameter_quantities().count();
        let motors = self.base.n_coordinates() - self.base.nq();
        snapshot::decode(bytes, self.model_hash, self.base.nq(), motors, n_parameters)
            .map_err(|e| Fault::error(format!("rejected FMU state: {e}")))
    }

    /// fmi2SetFMUstate: restores everything [`Instance::snapshot`] saved.
    /// Nothing changes if the bytes are rejected.
    pub(crate) fn restore(&mut self, bytes: &[u8]) -> Outcome {
        let s = self.check_snapshot(bytes)?;
        let rejected = |e: String| Fault::error(format!("rejected FMU state: {e}"));
        let mut model = self.base.clone();
        let mut tunables = Vec::new();
        for (q, x) in self.parameter_quantities().zip(&s.parameters) {
            match q {
                Quantity::Setting(setting) => {
                    setting.check(*x).map_err(rejected)?;
                    setting.set(&mut model.integrator, *x);
                }
                Quantity::Parameter(p, j) => tunables.push((p, j, *x)),
                _ => {}
            }
        }
        // Tunable parameters go in after validation, as with fmi2SetReal:
        // the saved values may break a relation that the next step reports.
        let mut sim = Simulator::new(model.clone()).map_err(|e| rejected(e.to_string()))?;
        for (p, j, x) in tunables {
            model.set_parameter(p, j, x).map_err(|e| rejected(e.to_string()))?;
        }
        sim.set_model(model).map_err(|e| rejected(e.to_string()))?;
        if s.lifecycle.is_running() {
            sim.set_state(&s.state).map_err(|e| rejected(e.to_string()))?;
        }
        let Snapshot {
            lifecycle,
            start_time,
            stop_time,
            inputs,
            torques,
            use_start_values,
            q_start,
            qd_start,
            theta_m_start,
            omega_m_start,
            static_start,
            ..
        } = s;
        self.sim = sim;
        self.lifecycle = lifecycle;
        self.start_time = start_time;
        self.stop_time = stop_time;
        self.inputs = inputs;
        self.torques = torques;
        self.use_start_values = use_start_values;
        self.q_start = q_start;
        self.qd_start = qd_start;
        self.theta_m_start = theta_m_start;
        self.omega_m_start = omega_m_start;
        self.static_start = static_start;
        self.stale = lifecycle.is_configuring();
        Ok(Status::Ok)
    }
}

/// [`Instance::continue_held_inputs`] for one group of inputs (value, rate,
/// acceleration per element).
#[cfg(feature = "fmi3")]
fn continue_within_reach(set: &mut [Vec<f64>; 3], held: &[Vec<f64>; 3], interval: f64) -> usize {
    let mut kept = 0;
    for i in 0..set[0].len() {
        let curvature = held[2][i].abs().max(set[2][i].abs());
        let reach = 0.25 * curvature * interval * interval + 1e-12 * held[0][i].abs().max(1.0);
        if (set[0][i] - held[0][i]).abs() <= reach {
            for k in 0..3 {
                set[k][i] = held[k][i];
            }
            kept += 1;
        }
    }
    kept
}

/// What FMI 3.0's layer runs at the end of each sub-step inside a step
/// ([`Instance::do_step_observed`]).
#[cfg(feature = "fmi3")]
pub(crate) type AfterSubStep<'a> = dyn FnMut(&mut SubStep<'_>) -> Result<Flow, StepError> + 'a;

/// What the FMI 3.0 layer (`crate::fmi3`) runs and reads of the FMI 2.0
/// instance underneath it.
#[cfg(feature = "fmi3")]
impl Instance {
    /// fmi3DoStep with an observer of the sub-steps (FMI 3.0's intermediate
    /// update and early return): `after` is told at the end of each sub-step
    /// before the step's end and may end the step there ([`Flow::Stop`]).
    pub(crate) fn do_step_observed(
        &mut self,
        t: f64,
        h: f64,
        after: &mut AfterSubStep<'_>,
    ) -> Result<(Status, Flow), Fault> {
        let advance = |sim: &mut Simulator, inputs: &DriveInputs<'_>, check: &dyn Fn(&State) -> FiniteCheck| {
            sim.advance_observed(inputs, h, check, |s| after(s))
        };
        self.step(t, h, advance)
    }

    /// The drive inputs and motor torques become the values the engine holds
    /// now (their Taylor polynomials at the current time): after a step that
    /// returned early, or took inputs at its sub-steps, the next step goes on
    /// with them unless the master sets others.
    pub(crate) fn hold_inputs_now(&mut self) {
        let [x, xd, xdd] = &mut self.inputs;
        let [u, ud, udd] = &mut self.torques;
        self.sim.held_inputs([x, xd, xdd], [u, ud, udd]);
    }

    /// At the instant of an early return, before the step that resumes
    /// there: each drive input (and motor torque) whose value the master set
    /// within `interval`'s interpolation reach of the held polynomial goes
    /// on as that polynomial (value, rate and acceleration held), and the
    /// others are taken as set. `interval` is the master's communication
    /// interval the return fell in. The reach is what a master's linear
    /// interpolation of the same signal between its communication points
    /// can differ from it: |ẍ|·H²/8 with the larger of the held and the set
    /// second derivative, doubled, plus 1e-12 of the value for rounding.
    /// Returns how many inputs went on held.
    pub(crate) fn continue_held_inputs(&mut self, interval: f64) -> usize {
        let n = self.inputs[0].len();
        let m = self.torques[0].len();
        let mut held = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut held_torques = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
        {
            let [x, xd, xdd] = &mut held;
            let [u, ud, udd] = &mut held_torques;
            self.sim.held_inputs([x, xd, xdd], [u, ud, udd]);
        }
        continue_within_reach(&mut self.inputs, &held, interval)
            + continue_within_reach(&mut self.torques, &held_torques, interval)
    }
}

#[cfg(all(test, feature = "fmi3"))]
mod continue_tests {
    use super::continue_within_reach;

    /// The reach of an interval H: |ẍ|·H²/4 (the larger of the held and set
    /// second derivatives) plus 1e-12 of the value; an input within it goes on
    /// held (all three of its values), one beyond it is taken as set.
    #[test]
    fn an_input_within_the_interpolation_reach_goes_on_held() {
        let h = 1e-3;
        let held = [vec![1.0, 1.0, 0.0], vec![0.5, 0.5, 0.0], vec![4.0, 4.0, 0.0]];
        let reach = 0.25 * 4.0 * h * h + 1e-12; // 1e-6 + rounding
        let mut set = [vec![1.0 + 0.99 * reach, 1.0 + 1.01 * reach, 2e-12], vec![0.6, 0.6, 0.0], vec![3.0, 3.0, 0.0]];
        let kept = continue_within_reach(&mut set, &held, h);
        assert_eq!(kept, 1, "only the first: the second is beyond reach, the third beyond rounding of a line");
        assert_eq!([set[0][0], set[1][0], set[2][0]], [1.0, 0.5, 4.0]);
        assert_eq!([set[0][1], set[1][1], set[2][1]], [1.0 + 1.01 * reach, 0.6, 3.0]);
        assert_eq!(set[0][2], 2e-12);
    }
}
