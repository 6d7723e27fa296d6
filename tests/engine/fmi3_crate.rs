//! The FMI 3.0 FMU through an independent FMI 3.0 importer written in Rust: the
//! `fmi` crate (rust-fmi 0.8, feature `fmi3`). It unzips the `.fmu`, parses the
//! modelDescription with its own strict schema (fmi-schema 0.8), loads
//! `binaries/x86_64-linux/StickSlipManipulator.so` with libloading and calls the
//! C functions. 100 communication steps of 1 ms of the reference motion, the
//! inputs set as the arrays `q_star`, `qd_star`, `qdd_star` with
//! `fmi3SetFloat64`, must equal a direct `Simulator` run of the engine bit for
//! bit: every output array but the stepper statistics, after initialization and
//! after each step.
//!
//! The crate reads the FMU as shipped: its schema has no `unit` on a
//! `<Float64>` variable, and the FMU's variables name their units'
//! `Float64Type` in `declaredType` instead ([`import`] checks that the crate
//! sees them). One thing the crate cannot do, and what is done instead: its
//! FMI 3.0 instance has no FMU-state functions (`get_fmu_state` and
//!   `set_fmu_state` are behind `#[cfg(false)]` in its `fmi3/traits.rs` and
//!   `fmi3/instance/common.rs`) and keeps the instance pointer private: the
//!   state test calls the C functions through the crate's raw bindings
//!   (`fmi::fmi3::binding::Fmi3Binding`, loaded by `FmiImport::binding`), on
//!   instances it creates with them.
//!
//! Which FMU: `$STICKSLIP_FMU3` if set (it must exist), otherwise
//! `target/fmu/StickSlipManipulator-fmi3.fmu` (built by `bash
//! scripts/build_fmu.sh`). Without it, or if it is older than the engine
//! library of this build (then it may hold an older engine), the tests print
//! why and return (skip): `cargo test` does not build the FMI 3.0 library
//! (the workspace crate `fmi3/`), so it cannot pack one of its own as
//! tests/engine/fmi_crate.rs does.

use std::ffi::{c_char, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::instance::InstanceCS;
use fmi::fmi3::{binding, CoSimulation, Common, Fmi3Model, GetSet};
use fmi::schema::fmi3::{Causality, Float64Type, TypeDefinition, Variable, VariableType};
use fmi::traits::FmiImport;
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{DriveInputs, Model, Simulator, State};

const STEP: f64 = 1e-3;
const STEPS: usize = 100;
/// Outputs that count the error control's decisions: not compared with the
/// direct run (as in tests/engine/fmi_crate.rs, which does not compare them either).
const STATISTICS: [&str; 3] = ["n_substeps", "n_rejected", "h_last"];

/// The FMU under test, or why there is none (the tests then skip).
fn fmu3_file() -> Option<PathBuf> {
    static FMU: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let found = FMU.get_or_init(|| {
        if let Some(p) = std::env::var_os("STICKSLIP_FMU3") {
            let p = PathBuf::from(p);
            assert!(p.is_file(), "$STICKSLIP_FMU3 = {} does not exist", p.display());
            return Ok(p);
        }
        let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fmu/StickSlipManipulator-fmi3.fmu");
        if !built.is_file() {
            return Err(format!(
                "no FMI 3.0 FMU to test: {} does not exist; build it with `bash scripts/build_fmu.sh` \
                 (or set $STICKSLIP_FMU3)",
                built.display()
            ));
        }
        // The engine's cdylib of this build (as in tests/engine/fmi_crate.rs) is relinked whenever
        // the library changes: an FMU older than it may hold an older engine, which would
        // differ from the direct run for that reason alone.
        let packager = PathBuf::from(env!("CARGO_BIN_EXE_package_fmu"));
        let lib = packager.parent().expect("target/<profile>").join("deps/libstick_slip_manipulator.so");
        let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
        match (modified(&built), modified(&lib)) {
            (Some(fmu), Some(engine)) if fmu < engine => Err(format!(
                "{} is older than this build's library {}: it may hold an older engine; rebuild it with \
                 `bash scripts/build_fmu.sh` (or set $STICKSLIP_FMU3)",
                built.display(),
                lib.display()
            )),
            _ => Ok(built),
        }
    });
    match found {
        Ok(p) => Some(p.clone()),
        Err(reason) => {
            eprintln!("SKIPPED: {reason}");
            None
        }
    }
}

/// The FMU as the `fmi` crate's importer, as shipped. The units the crate
/// reads come through `declaredType`: every Float64 variable that names a
/// type finds it among the `Float64Type`s, with a unit; the reference arm's
/// `x_E` is in m (displayed in mm), `f` in N.
fn import(path: &Path) -> Fmi3Import {
    let import = fmi::import::from_path::<Fmi3Import>(path)
        .unwrap_or_else(|e| panic!("the fmi crate cannot import {} as shipped: {e:?}", path.display()));
    let md = import.model_description();
    let types: Vec<&Float64Type> = md
        .type_definitions
        .iter()
        .flat_map(|t| &t.type_definitions)
        .filter_map(|t| if let TypeDefinition::Float64(f) = t { Some(f) } else { None })
        .collect();
    let mut units = Vec::new();
    for v in &md.model_variables.variables {
        let Variable::Float64(x) = v else { continue };
        let Some(declared) = x.declared_type.as_deref() else { continue };
        let t = types.iter().find(|t| t.name == declared).unwrap_or_else(|| panic!("`{}`: no type {declared}", x.name));
        units.push((x.name.as_str(), t.unit.as_deref().expect("a type with a unit"), t.display_unit.as_deref()));
    }
    for expected in [("x_E", "m", Some("mm")), ("f", "N", None)] {
        assert!(units.contains(&expected), "{expected:?} not among the units the crate reads: {units:?}");
    }
    eprintln!(
        "fmi3_crate: the fmi crate imports {} as shipped; {} Float64 variables with a unit through {} types",
        path.display(),
        units.len(),
        types.len()
    );
    import
}

fn vr(import: &Fmi3Import, name: &str) -> u32 {
    import
        .model_description()
        .model_variables
        .find_by_name(name)
        .unwrap_or_else(|| panic!("no variable `{name}` in the modelDescription"))
        .value_reference()
}

/// The value references of `q_star`, `qd_star`, `qdd_star` (arrays of 4).
fn input_vrs(import: &Fmi3Import) -> [u32; 3] {
    ["q_star", "qd_star", "qdd_star"].map(|name| vr(import, name))
}

/// The reference motion's 12 inputs at t, serialized as the three arrays.
fn inputs_at(t: f64) -> [f64; 12] {
    let (q, qd, qdd) = reference_inputs(t);
    let mut x = [0.0; 12];
    x[..4].copy_from_slice(&q);
    x[4..8].copy_from_slice(&qd);
    x[8..].copy_from_slice(&qdd);
    x
}

fn drive(x: &[f64; 12]) -> DriveInputs<'_> {
    DriveInputs { q_star: &x[..4], qd_star: &x[4..8], qdd_star: &x[8..] }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Float64,
    Int32,
    Boolean,
}

/// The FMI 3.0 output arrays computed from an engine state, by name, with
/// their elements in serialization order (`f`, `n`: row-major [joint, component]).
fn outputs_of(s: &State) -> Vec<(&'static str, Kind, Vec<f64>)> {
    use Kind::*;
    let n = s.nq();
    let joints = |f: &dyn Fn(usize) -> f64| (0..n).map(f).collect::<Vec<f64>>();
    let matrix = |m: &dyn Fn(usize, usize) -> f64| {
        (0..n).flat_map(|i| (0..3).map(move |k| (i, k))).map(|(i, k)| m(i, k)).collect()
    };
    let e = &s.energy;
    vec![
        ("q", Float64, joints(&|i| s.q[i])),
        ("qd", Float64, joints(&|i| s.qd[i])),
        ("qdd", Float64, joints(&|i| s.qdd[i])),
        ("stick", Boolean, joints(&|i| f64::from(u8::from(s.is_stuck(i))))),
        ("n_stick", Int32, joints(&|i| s.stick_count[i] as f64)),
        ("t_stick", Float64, joints(&|i| s.stuck_time[i])),
        ("F_drive", Float64, joints(&|i| s.drive_force[i])),
        ("F_friction", Float64, joints(&|i| s.friction_force[i])),
        ("N_normal", Float64, joints(&|i| s.normal_load[i])),
        ("f", Float64, matrix(&|i, k| s.reaction_force[i][k])),
        ("n", Float64, matrix(&|i, k| s.reaction_moment[i][k])),
        ("eps_joint", Float64, joints(&|i| s.joint_error(i))),
        ("eps", Float64, vec![s.end_point_error()]),
        ("x_E", Float64, (0..3).map(|k| s.end_point[k]).collect()),
        ("E_kin", Float64, vec![e.kinetic]),
        ("E_pot", Float64, vec![e.potential]),
        ("E_spring", Float64, vec![e.spring]),
        ("W_drive", Float64, vec![e.drive_work]),
        ("Q_friction", Float64, vec![e.friction_heat]),
        ("Q_damping", Float64, vec![e.damping_heat]),
    ]
}

/// One output array of the FMU, as f64 (Int32 and Boolean converted exactly).
fn get(inst: &mut InstanceCS, vr: u32, kind: Kind, n: usize) -> Vec<f64> {
    match kind {
        Kind::Float64 => {
            let mut x = vec![0.0; n];
            inst.get_float64(&[vr], &mut x).expect("fmi3GetFloat64");
            x
        }
        Kind::Int32 => {
            let mut x = vec![0; n];
            inst.get_int32(&[vr], &mut x).expect("fmi3GetInt32");
            x.into_iter().map(f64::from).collect()
        }
        Kind::Boolean => {
            let mut x = vec![false; n];
            inst.get_boolean(&[vr], &mut x).expect("fmi3GetBoolean");
            x.into_iter().map(|b| f64::from(u8::from(b))).collect()
        }
    }
}

fn step(inst: &mut InstanceCS, t: f64) {
    let (mut event, mut terminate, mut early, mut last) = (false, false, false, f64::NAN);
    inst.do_step(t, STEP, true, &mut event, &mut terminate, &mut early, &mut last).expect("fmi3DoStep");
    assert!(
        !event && !terminate && !early,
        "fmi3DoStep at t = {t}: event {event}, terminate {terminate}, early {early}"
    );
    assert!((last - (t + STEP)).abs() <= 1e-15, "lastSuccessfulTime {last} after the step from {t}");
}

/// An instance through the crate's `InstanceCS`, initialized with the inputs at t = 0.
fn initialized(import: &Fmi3Import, name: &str) -> InstanceCS {
    let inputs = input_vrs(import);
    let mut inst = import.instantiate_cs(name, false, false, false, false, &[]).expect("fmi3InstantiateCoSimulation");
    inst.enter_initialization_mode(None, 0.0, None).expect("fmi3EnterInitializationMode");
    inst.set_float64(&inputs, &inputs_at(0.0)).expect("fmi3SetFloat64 of q_star, qd_star, qdd_star");
    inst.exit_initialization_mode().expect("fmi3ExitInitializationMode");
    inst
}

/// 100 steps of the reference motion through the `fmi` crate equal a direct
/// `Simulator` run bit for bit: every output array (Float64, the Int32
/// `n_stick` and the Boolean `stick`) but the stepper statistics, after
/// initialization and after each step.
#[test]
fn fmi3_crate_runs_the_fmu_like_the_engine() {
    let Some(path) = fmu3_file() else { return };
    let import = import(&path);
    let md = import.model_description();
    assert_eq!(md.fmi_version, "3.0");
    let cs = md.co_simulation.as_ref().expect("CoSimulation");
    assert_eq!(cs.model_identifier, "StickSlipManipulator");
    assert_eq!(cs.can_get_and_set_fmu_state, Some(true));
    let inputs = input_vrs(&import);

    let mut inst = initialized(&import, "fmi3_crate");
    assert_eq!(inst.get_version(), "3.0");
    let mut sim = Simulator::new(Model::reference_rrpr()).expect("reference model");
    sim.initialize(0.0, &drive(&inputs_at(0.0)), None).expect("initialize");

    // every output of the modelDescription is compared, but the statistics
    let layout: Vec<(&str, Kind, usize)> = outputs_of(sim.state()).iter().map(|(n, k, v)| (*n, *k, v.len())).collect();
    let md_outputs: Vec<(String, VariableType)> = md
        .model_variables
        .iter_abstract()
        .filter(|v| v.causality() == Causality::Output)
        .map(|v| (v.name().to_owned(), v.data_type()))
        .collect();
    for (name, ty) in &md_outputs {
        if STATISTICS.contains(&name.as_str()) {
            continue;
        }
        let (_, kind, _) =
            layout.iter().find(|(n, ..)| n == name).unwrap_or_else(|| panic!("output `{name}` not compared"));
        let expected = match kind {
            Kind::Float64 => VariableType::FmiFloat64,
            Kind::Int32 => VariableType::FmiInt32,
            Kind::Boolean => VariableType::FmiBoolean,
        };
        assert_eq!(*ty, expected, "type of `{name}`");
    }
    assert_eq!(md_outputs.len(), layout.len() + STATISTICS.len());
    let vrs: Vec<u32> = layout.iter().map(|(name, ..)| vr(&import, name)).collect();

    let mut compared = 0usize;
    let mut compare = |inst: &mut InstanceCS, sim: &Simulator, k: usize| {
        for ((name, kind, expected), vr) in outputs_of(sim.state()).into_iter().zip(&vrs) {
            let got = get(inst, *vr, kind, expected.len());
            for (j, (a, b)) in got.iter().zip(&expected).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "{name}[{j}] after {k} steps: FMU {a:e}, engine {b:e} (differ by {:e})",
                    a - b
                );
            }
            compared += expected.len();
        }
    };
    compare(&mut inst, &sim, 0);
    let stick1_before = get(&mut inst, vr(&import, "stick"), Kind::Boolean, 4)[0];
    for k in 0..STEPS {
        let t = k as f64 * STEP;
        let x = inputs_at(t);
        inst.set_float64(&inputs, &x).expect("fmi3SetFloat64 of the inputs");
        step(&mut inst, t);
        sim.advance(&drive(&x), STEP).expect("advance");
        compare(&mut inst, &sim, k + 1);
    }
    let stick1_after = get(&mut inst, vr(&import, "stick"), Kind::Boolean, 4)[0];
    inst.terminate().expect("fmi3Terminate");
    eprintln!(
        "fmi crate (FMI 3.0) vs engine, {STEPS} steps: {} output arrays, {compared} values, all bit for bit",
        layout.len()
    );
    // the run is not trivial: joint 1 breaks away within the 100 ms
    assert_eq!((stick1_before, stick1_after), (1.0, 0.0));
}

// ---- FMU states through the crate's raw bindings ------------------------------------

unsafe extern "C" fn log_message(
    _env: binding::fmi3InstanceEnvironment,
    status: binding::fmi3Status,
    category: binding::fmi3String,
    message: binding::fmi3String,
) {
    let text = |p: *const c_char| if p.is_null() { "" } else { unsafe { CStr::from_ptr(p) }.to_str().unwrap_or("?") };
    eprintln!("FMU log (status {status}, {}): {}", text(category), text(message));
}

/// An FMI 3.0 co-simulation instance made and driven with the C functions of
/// the crate's `Fmi3Binding` (the crate's `InstanceCS` has no state functions).
struct Raw {
    lib: binding::Fmi3Binding,
    ptr: binding::fmi3Instance,
    inputs: [u32; 3],
    outputs: [u32; 2],
}

fn ok(status: binding::fmi3Status, what: &str) {
    assert_eq!(status, binding::fmi3Status_fmi3OK, "{what} returned status {status}");
}

impl Raw {
    fn new(import: &Fmi3Import, name: &str) -> Raw {
        let md = import.model_description();
        let id = &md.co_simulation.as_ref().expect("CoSimulation").model_identifier;
        let lib = import.binding(id).expect("load the FMU's library");
        let name = CString::new(name).unwrap();
        let token = CString::new(md.instantiation_token.as_str()).unwrap();
        let resources = CString::new(import.canonical_resource_path_string()).unwrap();
        let ptr = unsafe {
            lib.fmi3InstantiateCoSimulation(
                name.as_ptr(),
                token.as_ptr(),
                resources.as_ptr(),
                false,
                false,
                false,
                false,
                std::ptr::null(),
                0,
                std::ptr::null_mut(),
                Some(log_message),
                None,
            )
        };
        assert!(!ptr.is_null(), "fmi3InstantiateCoSimulation returned NULL");
        Raw { lib, ptr, inputs: input_vrs(import), outputs: [vr(import, "q"), vr(import, "qd")] }
    }

    fn set_inputs(&mut self, t: f64) {
        let x = inputs_at(t);
        ok(unsafe { self.lib.fmi3SetFloat64(self.ptr, self.inputs.as_ptr(), 3, x.as_ptr(), 12) }, "fmi3SetFloat64");
    }

    fn initialize(&mut self) {
        ok(
            unsafe { self.lib.fmi3EnterInitializationMode(self.ptr, false, 0.0, 0.0, false, 0.0) },
            "fmi3EnterInitializationMode",
        );
        self.set_inputs(0.0);
        ok(unsafe { self.lib.fmi3ExitInitializationMode(self.ptr) }, "fmi3ExitInitializationMode");
    }

    /// Steps `from..from + n`; q and qd (8 values) after each.
    fn run(&mut self, from: usize, n: usize) -> Vec<[f64; 8]> {
        (from..from + n)
            .map(|k| {
                let t = k as f64 * STEP;
                self.set_inputs(t);
                let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                let status = unsafe {
                    self.lib.fmi3DoStep(self.ptr, t, STEP, true, &mut event, &mut terminate, &mut early, &mut last)
                };
                ok(status, "fmi3DoStep");
                let mut x = [0.0; 8];
                ok(unsafe { self.lib.fmi3GetFloat64(self.ptr, self.outputs.as_ptr(), 2, x.as_mut_ptr(), 8) }, "get");
                x
            })
            .collect()
    }

    fn get_state(&mut self) -> binding::fmi3FMUState {
        let mut state: binding::fmi3FMUState = std::ptr::null_mut();
        ok(unsafe { self.lib.fmi3GetFMUState(self.ptr, &mut state) }, "fmi3GetFMUState");
        assert!(!state.is_null());
        state
    }

    fn set_state(&mut self, state: binding::fmi3FMUState) {
        ok(unsafe { self.lib.fmi3SetFMUState(self.ptr, state) }, "fmi3SetFMUState");
    }

    fn free_state(&mut self, mut state: binding::fmi3FMUState) {
        ok(unsafe { self.lib.fmi3FreeFMUState(self.ptr, &mut state) }, "fmi3FreeFMUState");
    }

    fn serialize(&mut self, state: binding::fmi3FMUState) -> Vec<u8> {
        let mut size = 0usize;
        ok(unsafe { self.lib.fmi3SerializedFMUStateSize(self.ptr, state, &mut size) }, "fmi3SerializedFMUStateSize");
        let mut bytes = vec![0u8; size];
        ok(
            unsafe { self.lib.fmi3SerializeFMUState(self.ptr, state, bytes.as_mut_ptr(), size) },
            "fmi3SerializeFMUState",
        );
        bytes
    }

    /// The state of `bytes`, or the status fmi3DeserializeFMUState returned.
    fn deserialize(&mut self, bytes: &[u8]) -> Result<binding::fmi3FMUState, binding::fmi3Status> {
        let mut state: binding::fmi3FMUState = std::ptr::null_mut();
        let status = unsafe { self.lib.fmi3DeserializeFMUState(self.ptr, bytes.as_ptr(), bytes.len(), &mut state) };
        if status == binding::fmi3Status_fmi3OK {
            Ok(state)
        } else {
            Err(status)
        }
    }
}

impl Drop for Raw {
    fn drop(&mut self) {
        unsafe { self.lib.fmi3FreeInstance(self.ptr) };
    }
}

/// An FMU state got after 50 steps: set back into the same instance, and
/// serialized and deserialized into a second one, it gives the next 20 steps
/// bit for bit; those equal the crate's `InstanceCS` run of the same steps.
/// A truncated serialized state is refused with fmi3Error.
#[test]
fn fmi3_crate_state_round_trip() {
    let Some(path) = fmu3_file() else { return };
    let import = import(&path);

    // the reference: steps 51..=70 through the crate's own instance
    let mut inst = initialized(&import, "crate");
    let inputs = input_vrs(&import);
    let q_qd = [vr(&import, "q"), vr(&import, "qd")];
    let mut expected = Vec::new();
    for k in 0..70 {
        let t = k as f64 * STEP;
        inst.set_float64(&inputs, &inputs_at(t)).expect("fmi3SetFloat64");
        step(&mut inst, t);
        if k >= 50 {
            let mut x = [0.0; 8];
            inst.get_float64(&q_qd, &mut x).expect("fmi3GetFloat64");
            expected.push(x);
        }
    }
    inst.terminate().expect("fmi3Terminate");
    drop(inst);
    let bits = |rows: &[[f64; 8]]| rows.iter().map(|r| r.map(f64::to_bits)).collect::<Vec<_>>();

    let mut a = Raw::new(&import, "a");
    a.initialize();
    a.run(0, 50);
    let state = a.get_state();
    assert_eq!(bits(&a.run(50, 20)), bits(&expected), "raw bindings vs the crate's InstanceCS");
    a.set_state(state);
    assert_eq!(bits(&a.run(50, 20)), bits(&expected), "fmi3SetFMUState into the same instance");
    let bytes = a.serialize(state);
    a.free_state(state);

    let mut b = Raw::new(&import, "b");
    let restored = b.deserialize(&bytes).expect("fmi3DeserializeFMUState");
    b.set_state(restored);
    assert_eq!(bits(&b.run(50, 20)), bits(&expected), "serialized state restored in a new instance");
    b.free_state(restored);
    assert_eq!(b.deserialize(&bytes[..bytes.len() / 2]), Err(binding::fmi3Status_fmi3Error), "truncated state");
    eprintln!("fmi3_crate: FMU state after 50 steps ({} bytes serialized) continues bit for bit", bytes.len());
}
