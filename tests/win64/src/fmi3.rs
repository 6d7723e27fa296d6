//! The FMI 3.0 master of the cross-platform tests: the `fmi` crate (feature
//! `fmi3`), compiled for Linux and for Windows, imports `$STICKSLIP_FMU3`
//! (it picks `binaries/x86_64-linux/…so` or `binaries/x86_64-windows/…dll`
//! for the platform it runs on and passes the `resources` directory as a plain
//! path, `C:\…` under wine) and drives the reference motion with the inputs
//! set as the arrays `q_star`, `qd_star`, `qdd_star`:
//!
//! * [`run_reference3`]: the 2 s reference motion in 1 ms steps, no early
//!   return, every output array after each step ([`Record`], as FMI 2.0);
//! * [`run_early_return`]: the first 0.2 s with `earlyReturnAllowed` and
//!   `eventModeUsed`: every `fmi3DoStep` that ends early (at a stick-slip
//!   event located inside the step) is followed by Event Mode and a step
//!   from `lastSuccessfulTime` to the next communication point; inputs are
//!   set at the communication points only. Its [`Stops`] (time, kind and
//!   outputs of every return) travel between the platforms like a `Record`.
//!
//! The crate reads the FMU as shipped ([`import3`]): its units come through
//! the variables' `declaredType` (the crate's schema, fmi-schema 0.8, has no
//! `unit` on a variable). The crate's FMI 3.0 instance has no FMU-state
//! functions, so no state travels here (the FMI 2.0 stages exchange the same
//! serialized form, `src/fmi/snapshot.rs`).

use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::instance::InstanceCS;
use fmi::fmi3::{CoSimulation, Common, Fmi3Model, GetSet};
use fmi::schema::fmi3::{ArrayableVariableTrait, Causality, Float64Type, TypeDefinition, Variable};
use fmi::traits::FmiImport;
use fmi::EventFlags;

use crate::{hex, platform, required_env, unhex, xplat_file, Record, STEP, STEPS};

/// Communication steps of the early-return run (0.2 s).
pub const EARLY_RETURN_STEPS: usize = 200;

/// Stepper statistics: not compared (see `STATISTICS` in lib.rs).
const STATISTICS: [&str; 3] = ["n_substeps", "n_rejected", "h_last"];

/// The FMI 3.0 FMU under test, `$STICKSLIP_FMU3`, imported for this platform
/// as shipped. Its units come through the variables' `declaredType`, as the
/// crate reads them ([`float64_units`]); the reference arm's `x_E` is in m.
pub fn import3() -> Fmi3Import {
    let path = required_env("STICKSLIP_FMU3");
    let import = fmi::import::from_path::<Fmi3Import>(&path)
        .unwrap_or_else(|e| panic!("the fmi crate cannot import {} as shipped: {e:?}", path.display()));
    let units = float64_units(&import);
    assert!(units.iter().any(|(name, unit)| name == "x_E" && unit == "m"), "units of {}: {units:?}", path.display());
    eprintln!(
        "{}: the fmi crate imports {} as shipped; {} Float64 variables have a unit through their declaredType",
        platform(),
        path.display(),
        units.len()
    );
    import
}

/// (name, unit) of every Float64 variable with a unit, as the `fmi` crate
/// reads the modelDescription: the variable names a `Float64Type` of the
/// `TypeDefinitions` in `declaredType`, which carries the unit (the crate's
/// schema has no `unit` on a variable).
pub fn float64_units(import: &Fmi3Import) -> Vec<(String, String)> {
    let md = import.model_description();
    let types: Vec<&Float64Type> = md
        .type_definitions
        .iter()
        .flat_map(|t| &t.type_definitions)
        .filter_map(|t| if let TypeDefinition::Float64(f) = t { Some(f) } else { None })
        .collect();
    md.model_variables
        .variables
        .iter()
        .filter_map(|v| if let Variable::Float64(x) = v { Some(x) } else { None })
        .filter_map(|x| {
            let declared = x.declared_type.as_deref()?;
            let t =
                types.iter().find(|t| t.name == declared).unwrap_or_else(|| panic!("`{}`: no type {declared}", x.name));
            Some((x.name.clone(), t.unit.clone().unwrap_or_else(|| panic!("type {declared} without a unit"))))
        })
        .collect()
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Float64,
    Int32,
    Boolean,
}

/// Value references and element names of the FMI 3.0 variables the master uses.
pub struct Layout3 {
    /// `q_star`, `qd_star`, `qdd_star` (4 elements each).
    pub inputs: [u32; 3],
    /// The output arrays' elements, `q[1]`, …, `f[4,3]`, …, in the
    /// modelDescription's order (the stepper statistics left out).
    pub names: Vec<String>,
    outputs: Vec<(u32, Kind, usize)>,
}

impl Layout3 {
    pub fn of(import: &Fmi3Import) -> Layout3 {
        let md = import.model_description();
        let vr = |name: &str| {
            md.model_variables.find_by_name(name).unwrap_or_else(|| panic!("no variable `{name}`")).value_reference()
        };
        let inputs = ["q_star", "qd_star", "qdd_star"].map(vr);
        let mut names = Vec::new();
        let mut outputs = Vec::new();
        let mut statistics = 0;
        for v in &md.model_variables.variables {
            let (var, kind): (&dyn ArrayableVariableTrait, Kind) = match v {
                Variable::Float64(x) => (x, Kind::Float64),
                Variable::Int32(x) => (x, Kind::Int32),
                Variable::Boolean(x) => (x, Kind::Boolean),
                _ => continue,
            };
            if var.causality() != Causality::Output {
                continue;
            }
            if STATISTICS.contains(&var.name()) {
                statistics += 1;
                continue;
            }
            let dims: Vec<usize> =
                var.dimensions().iter().map(|d| d.as_fixed().expect("fixed dimensions") as usize).collect();
            let elements = match dims[..] {
                [] => vec![var.name().to_owned()],
                [n] => (1..=n).map(|i| format!("{}[{i}]", var.name())).collect(),
                [n, m] => (1..=n)
                    .flat_map(|i| (1..=m).map(move |k| (i, k)))
                    .map(|(i, k)| format!("{}[{i},{k}]", var.name()))
                    .collect(),
                _ => panic!("`{}`: {} dimensions", var.name(), dims.len()),
            };
            outputs.push((var.value_reference(), kind, elements.len()));
            names.extend(elements);
        }
        let all = md.model_variables.iter_abstract().filter(|v| v.causality() == Causality::Output).count();
        assert_eq!(all, outputs.len() + statistics, "outputs of other types than Float64, Int32, Boolean");
        assert!(names.len() > 50 && names.iter().filter(|n| n.starts_with("stick[")).count() == 4, "{names:?}");
        Layout3 { inputs, names, outputs }
    }

    /// One row: every output element in `names` order, Int32 and Boolean as f64 (exact).
    fn row(&self, inst: &mut InstanceCS) -> Vec<f64> {
        let mut row = Vec::with_capacity(self.names.len());
        for &(vr, kind, n) in &self.outputs {
            match kind {
                Kind::Float64 => {
                    let mut x = vec![0.0; n];
                    inst.get_float64(&[vr], &mut x).expect("fmi3GetFloat64");
                    row.extend(x);
                }
                Kind::Int32 => {
                    let mut x = vec![0; n];
                    inst.get_int32(&[vr], &mut x).expect("fmi3GetInt32");
                    row.extend(x.into_iter().map(f64::from));
                }
                Kind::Boolean => {
                    let mut x = vec![false; n];
                    inst.get_boolean(&[vr], &mut x).expect("fmi3GetBoolean");
                    row.extend(x.into_iter().map(|b| f64::from(u8::from(b))));
                }
            }
        }
        row
    }

    fn set_inputs(&self, inst: &mut InstanceCS, x: &[f64; 12]) {
        inst.set_float64(&self.inputs, x).expect("fmi3SetFloat64 of q_star, qd_star, qdd_star");
    }
}

/// The result of one fmi3DoStep.
struct StepResult {
    event_handling_needed: bool,
    early_return: bool,
    last_successful_time: f64,
}

fn do_step(inst: &mut InstanceCS, t: f64, h: f64) -> StepResult {
    let (mut event, mut terminate, mut early, mut last) = (false, false, false, f64::NAN);
    inst.do_step(t, h, true, &mut event, &mut terminate, &mut early, &mut last)
        .unwrap_or_else(|e| panic!("fmi3DoStep({t}, {h}): {e}"));
    assert!(!terminate, "fmi3DoStep({t}, {h}): terminateSimulation");
    StepResult { event_handling_needed: event, early_return: early, last_successful_time: last }
}

/// The 2 s reference motion with `inputs` (set before each step), no early
/// return: outputs after initialization and after each step.
pub fn run_reference3(import: &Fmi3Import, inputs: &[[f64; 12]]) -> Record {
    let layout = Layout3::of(import);
    let mut inst =
        import.instantiate_cs(platform(), false, false, false, false, &[]).expect("fmi3InstantiateCoSimulation");
    inst.enter_initialization_mode(None, 0.0, None).expect("fmi3EnterInitializationMode");
    layout.set_inputs(&mut inst, &inputs[0]);
    inst.exit_initialization_mode().expect("fmi3ExitInitializationMode");
    let mut rows = vec![layout.row(&mut inst)];
    for (k, x) in inputs.iter().enumerate() {
        layout.set_inputs(&mut inst, x);
        let r = do_step(&mut inst, k as f64 * STEP, STEP);
        assert!(!r.early_return && !r.event_handling_needed, "step {k}: early return without earlyReturnAllowed");
        rows.push(layout.row(&mut inst));
    }
    inst.terminate().expect("fmi3Terminate");
    Record { names: layout.names, inputs: inputs.to_vec(), rows }
}

/// Asserts that the FMI 3.0 run `fmi3` (of [`run_reference3`]) equals the
/// FMI 2.0 run `fmi2` (of `run_reference`, same inputs, same platform) bit
/// for bit: the FMI 2.0 scalars are the FMI 3.0 arrays' elements, named alike.
pub fn assert_equals_fmi2(what: &str, fmi3: &Record, fmi2: &Record) {
    let mut names = (fmi3.names.clone(), fmi2.names.clone());
    names.0.sort();
    names.1.sort();
    assert_eq!(names.0, names.1, "{what}: the FMI 3.0 outputs' elements are the FMI 2.0 outputs");
    assert_eq!(fmi3.rows.len(), fmi2.rows.len());
    for (j, name) in fmi3.names.iter().enumerate() {
        let i = fmi2.names.iter().position(|n| n == name).expect("FMI 2.0 output");
        for (k, (a, b)) in fmi3.rows.iter().zip(&fmi2.rows).enumerate() {
            assert_eq!(
                a[j].to_bits(),
                b[i].to_bits(),
                "{what}: {name} after {k} steps: FMI 3.0 {}, FMI 2.0 {}",
                a[j],
                b[i]
            );
        }
    }
    eprintln!(
        "{what}: FMI 3.0 and FMI 2.0 FMUs, reference motion: all {} outputs equal bit for bit at all {} rows",
        fmi3.names.len(),
        fmi3.rows.len()
    );
}

/// How an fmi3DoStep of the early-return run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopKind {
    /// At the communication point it was asked for.
    Grid,
    /// Early, at an event, with `eventHandlingNeeded` (then Event Mode).
    Event,
    /// Early without `eventHandlingNeeded`.
    Early,
}

impl StopKind {
    fn code(self) -> &'static str {
        match self {
            StopKind::Grid => "g",
            StopKind::Event => "e",
            StopKind::Early => "r",
        }
    }

    fn of(code: &str) -> StopKind {
        match code {
            "g" => StopKind::Grid,
            "e" => StopKind::Event,
            "r" => StopKind::Early,
            _ => panic!("bad stop kind `{code}`"),
        }
    }
}

/// Every return of fmi3DoStep in the early-return run, in order.
pub struct Stops {
    pub names: Vec<String>,
    /// The inputs set at each communication point.
    pub inputs: Vec<[f64; 12]>,
    /// (kind, lastSuccessfulTime, outputs there).
    pub stops: Vec<(StopKind, f64, Vec<f64>)>,
}

impl Stops {
    /// The early returns: (lastSuccessfulTime, eventHandlingNeeded).
    pub fn early_returns(&self) -> Vec<(f64, bool)> {
        self.stops.iter().filter(|s| s.0 != StopKind::Grid).map(|s| (s.1, s.0 == StopKind::Event)).collect()
    }

    /// `names` line, one `i` line per communication point (inputs), one
    /// `s <kind> <time> <outputs>` line per return of fmi3DoStep.
    pub fn write(&self, name: &str) {
        let mut text = format!("names {}\n", self.names.join(" "));
        for x in &self.inputs {
            text += &format!("i {}\n", hex(x));
        }
        for (kind, t, row) in &self.stops {
            text += &format!("s {} {:016x} {}\n", kind.code(), t.to_bits(), hex(row));
        }
        let path = xplat_file(name);
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
    }

    pub fn read(name: &str) -> Stops {
        let path = xplat_file(name);
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("read {}: {e} (written by the other platform's stage)", path.display()));
        let mut stops = Stops { names: Vec::new(), inputs: Vec::new(), stops: Vec::new() };
        for line in text.lines() {
            match line.split_once(' ') {
                Some(("names", rest)) => stops.names = rest.split(' ').map(String::from).collect(),
                Some(("i", rest)) => stops.inputs.push(unhex(rest).try_into().expect("12 inputs")),
                Some(("s", rest)) => {
                    let mut parts = rest.splitn(3, ' ');
                    let kind = StopKind::of(parts.next().expect("kind"));
                    let t = unhex(parts.next().expect("time"))[0];
                    stops.stops.push((kind, t, unhex(parts.next().expect("outputs"))));
                }
                _ => panic!("{}: bad line `{line}`", path.display()),
            }
        }
        assert_eq!(stops.inputs.len(), EARLY_RETURN_STEPS, "{}", path.display());
        stops
    }
}

/// The first `inputs.len()` communication steps with early return allowed
/// and Event Mode used (FMI 3.0, 4.2.4): inputs set at the communication
/// points only, every early return followed by Event Mode (when
/// `eventHandlingNeeded`) and a step from `lastSuccessfulTime` to the next
/// communication point.
pub fn run_early_return(import: &Fmi3Import, inputs: &[[f64; 12]]) -> Stops {
    let layout = Layout3::of(import);
    let mut inst =
        import.instantiate_cs(platform(), false, false, true, true, &[]).expect("fmi3InstantiateCoSimulation");
    inst.enter_initialization_mode(None, 0.0, None).expect("fmi3EnterInitializationMode");
    layout.set_inputs(&mut inst, &inputs[0]);
    inst.exit_initialization_mode().expect("fmi3ExitInitializationMode");
    // eventModeUsed: Event Mode after initialization
    let event_mode = |inst: &mut InstanceCS| {
        let mut flags = EventFlags::default();
        inst.update_discrete_states(&mut flags).expect("fmi3UpdateDiscreteStates");
        assert!(!flags.discrete_states_need_update && !flags.terminate_simulation, "{flags:?}");
        inst.enter_step_mode().expect("fmi3EnterStepMode");
    };
    event_mode(&mut inst);
    let mut stops = Vec::new();
    let (mut t, mut k) = (0.0, 0);
    while k < inputs.len() {
        if t == k as f64 * STEP {
            layout.set_inputs(&mut inst, &inputs[k]);
        }
        let end = (k + 1) as f64 * STEP;
        let r = do_step(&mut inst, t, end - t);
        let kind = if r.early_return {
            let last = r.last_successful_time;
            assert!(t < last && last < end, "early return at {last}, outside ({t}, {end})");
            if r.event_handling_needed {
                StopKind::Event
            } else {
                StopKind::Early
            }
        } else {
            assert!(!r.event_handling_needed, "eventHandlingNeeded without early return at {t}");
            k += 1;
            StopKind::Grid
        };
        t = if r.early_return { r.last_successful_time } else { k as f64 * STEP };
        stops.push((kind, t, layout.row(&mut inst)));
        if kind == StopKind::Event {
            inst.enter_event_mode().expect("fmi3EnterEventMode");
            event_mode(&mut inst);
        }
        assert!(stops.len() <= 20 * inputs.len(), "more than 20 returns per communication step");
    }
    inst.terminate().expect("fmi3Terminate");
    Stops { names: layout.names, inputs: inputs.to_vec(), stops }
}

/// Asserts the early-return run `actual` returned where `expected` did: the
/// same sequence of returns (grid points and early returns, with or without
/// eventHandlingNeeded), each at the same lastSuccessfulTime bit for bit.
/// The outputs at the returns are compared by the caller (`assert_agree`).
/// Returns the number of early returns.
pub fn assert_same_returns(what: &str, actual: &Stops, expected: &Stops) -> usize {
    assert_eq!(actual.names, expected.names, "{what}: outputs");
    let kinds = |s: &Stops| s.stops.iter().map(|x| x.0).collect::<Vec<_>>();
    let (a, b) = (kinds(actual), kinds(expected));
    let first = a.iter().zip(&b).position(|(x, y)| x != y);
    assert!(
        a.len() == b.len() && first.is_none(),
        "{what}: {} returns against {}, the first different one is number {first:?}: {:?} against {:?}",
        a.len(),
        b.len(),
        first.map(|i| (a[i], actual.stops[i].1)),
        first.map(|i| (b[i], expected.stops[i].1))
    );
    let mut worst = 0.0_f64;
    let mut differing = 0;
    for (x, y) in actual.stops.iter().zip(&expected.stops) {
        if x.1.to_bits() != y.1.to_bits() {
            differing += 1;
            worst = worst.max((x.1 - y.1).abs());
        }
    }
    let early = actual.early_returns();
    eprintln!(
        "{what}: {} returns, {} early ({} with eventHandlingNeeded), first at t = {:?}; \
         instants differing in bits: {differing} (largest difference {worst:e} s)",
        a.len(),
        early.len(),
        early.iter().filter(|e| e.1).count(),
        early.first().map(|e| e.0)
    );
    assert_eq!(differing, 0, "{what}: {differing} returns at other instants, by up to {worst:e} s");
    early.len()
}

/// `STEPS` is the length of a reference record; the early-return run is shorter.
const _: () = assert!(EARLY_RETURN_STEPS <= STEPS);
