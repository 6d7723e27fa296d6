//! The master the cross-platform tests share: the same code, compiled for Linux
//! and for Windows, imports `$STICKSLIP_FMU` with the `fmi` crate (which picks
//! `binaries/linux64/…so` or `binaries/win64/…dll` for the platform it runs on,
//! unzips the FMU into a temporary directory and passes its `resources` folder
//! as a `file:` URI, `file:///C:/…` under wine) and drives the 2 s reference
//! motion through it in 1 ms communication steps.
//!
//! Results travel between the platforms as text files in `$STICKSLIP_XPLAT_DIR`
//! holding every f64 as its 16 hex digits of IEEE bits, so they compare exactly.

use std::path::PathBuf;

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::fmi2::Fmi2Error;
use fmi::schema::fmi2::{Causality, ScalarVariableElement};
use fmi::traits::{FmiImport, FmiStatus};

#[allow(dead_code)]
#[path = "../../../src/motion.rs"]
mod motion;

/// The FMI 3.0 master (`$STICKSLIP_FMU3`): tests/linux64_fmi3.rs, tests/win64_fmi3.rs.
pub mod fmi3;

/// Communication step, s.
pub const STEP: f64 = 1e-3;
/// Steps of the reference motion (2 s).
pub const STEPS: usize = 2000;
/// The FMU state is taken after this many steps (t = 1 s, joints in motion) …
pub const STATE_AT: usize = 1000;
/// … and this many steps after it are compared once it is restored.
pub const AFTER_STATE: usize = 200;
/// Relative agreement required between the platforms: per output, the largest
/// difference over the run divided by the output's largest magnitude. The
/// math libraries' sin/cos differ in the last bit for a few arguments, and the
/// error control's accept/reject decisions amplify that (1.4e-9 measured at
/// worst; README, "Platforms"), five orders below its promised accuracy.
pub const REL_TOL: f64 = 1e-8;

/// Stepper statistics (sub-steps taken and rejected, last sub-step length)
/// count the error control's decisions, which a last-bit difference of the
/// math library may change without changing the motion: not compared.
const STATISTICS: [&str; 3] = ["n_substeps", "n_rejected", "h_last"];

/// `linux64` or `win64`: the FMU binary this master loads.
pub fn platform() -> &'static str {
    if cfg!(windows) {
        "win64"
    } else {
        "linux64"
    }
}

fn required_env(name: &str) -> PathBuf {
    std::env::var_os(name)
        .map(PathBuf::from)
        .unwrap_or_else(|| panic!("{name} is not set (scripts/test.sh, stage win64, sets it)"))
}

/// The FMU under test, `$STICKSLIP_FMU`, imported for this platform.
pub fn import() -> Fmi2Import {
    let path = required_env("STICKSLIP_FMU");
    fmi::import::from_path(&path).unwrap_or_else(|e| panic!("the fmi crate cannot import {}: {e}", path.display()))
}

/// `$STICKSLIP_XPLAT_DIR/<name>`.
pub fn xplat_file(name: &str) -> PathBuf {
    let dir = required_env("STICKSLIP_XPLAT_DIR");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("create {}: {e}", dir.display()));
    dir.join(name)
}

/// Value references of the variables the master uses.
pub struct Layout {
    /// q*[1..4], q̇*[1..4], q̈*[1..4].
    pub inputs: Vec<u32>,
    /// The Real outputs except the stepper statistics, then the Boolean ones.
    pub names: Vec<String>,
    real: Vec<u32>,
    boolean: Vec<u32>,
}

impl Layout {
    pub fn of(import: &Fmi2Import) -> Layout {
        let md = import.model_description();
        let vr = |name: &str| {
            md.model_variable_by_name(name).unwrap_or_else(|_| panic!("no variable `{name}`")).value_reference
        };
        let inputs = ["q_star", "qd_star", "qdd_star"]
            .iter()
            .flat_map(|g| (1..=4).map(move |i| format!("{g}[{i}]")))
            .map(|n| vr(&n))
            .collect();
        let outputs = || md.get_model_variables().filter(|v| v.causality == Causality::Output);
        let mut names = Vec::new();
        let mut real = Vec::new();
        let mut boolean = Vec::new();
        for v in outputs().filter(|v| matches!(v.elem, ScalarVariableElement::Real(_))) {
            if !STATISTICS.contains(&v.name.as_str()) {
                names.push(v.name.clone());
                real.push(v.value_reference);
            }
        }
        for v in outputs().filter(|v| matches!(v.elem, ScalarVariableElement::Boolean(_))) {
            names.push(v.name.clone());
            boolean.push(v.value_reference);
        }
        assert!(real.len() > 50 && boolean.len() == 4, "{} Real and {} Boolean outputs", real.len(), boolean.len());
        Layout { inputs, names, real, boolean }
    }

    /// One row: the Real outputs, then the Boolean ones as 0/1.
    fn row(&self, inst: &mut InstanceCS) -> Vec<f64> {
        let mut values = vec![0.0; self.real.len()];
        inst.get_real(&self.real, &mut values).expect("fmi2GetReal");
        let mut flags = vec![0; self.boolean.len()];
        inst.get_boolean(&self.boolean, &mut flags).expect("fmi2GetBoolean");
        values.extend(flags.iter().map(|&b| f64::from(u8::from(b != 0))));
        values
    }
}

/// The inputs set before each step k (and at initialization, k = 0):
/// `reference_inputs(k·STEP)` of src/motion.rs, computed on this platform.
pub fn reference_inputs() -> Vec<[f64; 12]> {
    (0..STEPS)
        .map(|k| {
            let (q, qd, qdd) = motion::reference_inputs(k as f64 * STEP);
            let mut x = [0.0; 12];
            x[..4].copy_from_slice(&q);
            x[4..8].copy_from_slice(&qd);
            x[8..].copy_from_slice(&qdd);
            x
        })
        .collect()
}

/// A run of the reference motion through one platform's binary.
pub struct Record {
    pub names: Vec<String>,
    /// Inputs before each step.
    pub inputs: Vec<[f64; 12]>,
    /// Outputs after initialization (row 0) and after each step (row k + 1).
    pub rows: Vec<Vec<f64>>,
}

fn instantiate(import: &Fmi2Import, name: &str) -> InstanceCS {
    import.instantiate_cs(name, false, true).expect("fmi2Instantiate (resources from the resource URI)")
}

fn step(inst: &mut InstanceCS, layout: &Layout, inputs: &[f64; 12], k: usize) {
    inst.set_real(&layout.inputs, inputs).expect("fmi2SetReal of the inputs");
    inst.do_step(k as f64 * STEP, STEP, true).unwrap_or_else(|e| panic!("fmi2DoStep at step {k}: {e}"));
}

/// The whole motion with `inputs`; also the serialized FMU state after
/// `STATE_AT` steps.
pub fn run_reference(import: &Fmi2Import, inputs: &[[f64; 12]]) -> (Record, Vec<u8>) {
    let layout = Layout::of(import);
    let mut inst = instantiate(import, platform());
    inst.setup_experiment(None, 0.0, None).expect("fmi2SetupExperiment");
    inst.enter_initialization_mode().expect("fmi2EnterInitializationMode");
    inst.set_real(&layout.inputs, &inputs[0]).expect("fmi2SetReal of the inputs");
    inst.exit_initialization_mode().expect("fmi2ExitInitializationMode");
    let mut rows = vec![layout.row(&mut inst)];
    let mut state = Vec::new();
    for (k, x) in inputs.iter().enumerate() {
        if k == STATE_AT {
            let s = inst.get_fmu_state().expect("fmi2GetFMUstate");
            state = inst.serialize_fmu_state(&s).expect("fmi2SerializeFMUstate");
        }
        step(&mut inst, &layout, x, k);
        rows.push(layout.row(&mut inst));
    }
    inst.terminate().expect("fmi2Terminate");
    (Record { names: layout.names, inputs: inputs.to_vec(), rows }, state)
}

/// A fresh instance restored from serialized `state` (taken after `STATE_AT`
/// steps, possibly on the other platform) runs the next `AFTER_STATE` steps
/// with `inputs`; their output rows.
pub fn continue_from_state(import: &Fmi2Import, state: &[u8], inputs: &[[f64; 12]]) -> Vec<Vec<f64>> {
    let layout = Layout::of(import);
    let mut inst = instantiate(import, "restored");
    let restored = inst.deserialize_fmu_state(state).expect("fmi2DeSerializeFMUstate");
    inst.set_fmu_state(&restored).ok().expect("fmi2SetFMUstate");
    (STATE_AT..STATE_AT + AFTER_STATE)
        .map(|k| {
            step(&mut inst, &layout, &inputs[k], k);
            layout.row(&mut inst)
        })
        .collect()
}

/// Asserts that `actual` agrees with `expected` (rows of `names`): stick
/// flags and stiction counts equal at every row, every other output within
/// `REL_TOL` of its largest magnitude. Returns (bit-identical, worst relative
/// deviation, its output).
pub fn assert_agree(what: &str, names: &[String], actual: &[Vec<f64>], expected: &[Vec<f64>]) -> (bool, f64, String) {
    assert_eq!(actual.len(), expected.len(), "{what}: rows");
    let mut identical = true;
    let mut worst = (0.0_f64, String::new());
    for (j, name) in names.iter().enumerate() {
        let a: Vec<f64> = actual.iter().map(|r| r[j]).collect();
        let b: Vec<f64> = expected.iter().map(|r| r[j]).collect();
        identical &= a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits());
        if name.starts_with("stick[") || name.starts_with("n_stick[") {
            let first = a.iter().zip(&b).position(|(x, y)| x != y);
            assert!(first.is_none(), "{what}: {name} differs first at row {first:?}");
            continue;
        }
        let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let diff = a.iter().zip(&b).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(diff.is_finite(), "{what}: {name} not finite");
        let rel = if diff == 0.0 { 0.0 } else { diff / scale };
        assert!(rel <= REL_TOL, "{what}: {name} differs by {rel:.3e} of its largest magnitude {scale:.3e}");
        if name == "eps" {
            eprintln!("{what}: eps (end-point error ε) differs by {rel:.3e} of its largest magnitude {scale:.3e} m");
        }
        if rel > worst.0 {
            worst = (rel, name.clone());
        }
    }
    eprintln!("{what}: bit-identical = {identical}, worst relative deviation {:.3e} ({})", worst.0, worst.1);
    (identical, worst.0, worst.1)
}

/// Calls a master must not make are answered with fmi2Error, on every platform:
/// fmi2DoStep before initialization, a NaN input, an unknown value reference,
/// a truncated serialized state. The instance keeps working afterwards.
pub fn assert_bad_calls_are_errors(import: &Fmi2Import) {
    let layout = Layout::of(import);
    let mut inst = instantiate(import, "bad_calls");
    assert!(matches!(inst.do_step(0.0, STEP, true), Err(Fmi2Error::Error)), "fmi2DoStep before initialization");
    inst.setup_experiment(None, 0.0, None).expect("fmi2SetupExperiment");
    inst.enter_initialization_mode().expect("fmi2EnterInitializationMode");
    let inputs = reference_inputs();
    inst.set_real(&layout.inputs, &inputs[0]).expect("fmi2SetReal");
    inst.exit_initialization_mode().expect("fmi2ExitInitializationMode");
    assert!(matches!(inst.set_real(&layout.inputs[..1], &[f64::NAN]), Err(Fmi2Error::Error)), "NaN q_star[1]");
    let unknown = import.model_description().get_model_variables().map(|v| v.value_reference).max().unwrap() + 1000;
    let mut x = [0.0];
    assert!(matches!(inst.get_real(&[unknown], &mut x), Err(Fmi2Error::Error)), "fmi2GetReal of vr {unknown}");
    assert!(matches!(inst.set_real(&[unknown], &[1.0]), Err(Fmi2Error::Error)), "fmi2SetReal of vr {unknown}");
    let s = inst.get_fmu_state().expect("fmi2GetFMUstate");
    let bytes = inst.serialize_fmu_state(&s).expect("fmi2SerializeFMUstate");
    assert!(matches!(inst.deserialize_fmu_state(&bytes[..bytes.len() - 1]), Err(Fmi2Error::Error)), "truncated state");
    // still usable: the NaN was not taken
    step(&mut inst, &layout, &inputs[0], 0);
    assert!(layout.row(&mut inst).iter().all(|x| x.is_finite()));
    inst.terminate().expect("fmi2Terminate");
}

fn hex(values: &[f64]) -> String {
    values.iter().map(|x| format!("{:016x}", x.to_bits())).collect::<Vec<_>>().join(" ")
}

fn unhex(line: &str) -> Vec<f64> {
    line.split(' ')
        .map(|h| f64::from_bits(u64::from_str_radix(h, 16).unwrap_or_else(|_| panic!("bad hex `{h}`"))))
        .collect()
}

impl Record {
    /// `names` line, one `i` line per step (inputs), one `o` line per row.
    pub fn write(&self, name: &str) {
        let mut text = format!("names {}\n", self.names.join(" "));
        for x in &self.inputs {
            text += &format!("i {}\n", hex(x));
        }
        for r in &self.rows {
            text += &format!("o {}\n", hex(r));
        }
        let path = xplat_file(name);
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
    }

    pub fn read(name: &str) -> Record {
        let path = xplat_file(name);
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("read {}: {e} (written by the other platform's stage)", path.display()));
        let mut record = Record { names: Vec::new(), inputs: Vec::new(), rows: Vec::new() };
        for line in text.lines() {
            match line.split_once(' ') {
                Some(("names", rest)) => record.names = rest.split(' ').map(String::from).collect(),
                Some(("i", rest)) => record.inputs.push(unhex(rest).try_into().expect("12 inputs")),
                Some(("o", rest)) => record.rows.push(unhex(rest)),
                _ => panic!("{}: bad line `{line}`", path.display()),
            }
        }
        assert_eq!(record.inputs.len(), STEPS, "{}", path.display());
        assert_eq!(record.rows.len(), STEPS + 1, "{}", path.display());
        record
    }
}

pub fn write_bytes(name: &str, bytes: &[u8]) {
    let path = xplat_file(name);
    std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
}

pub fn read_bytes(name: &str) -> Vec<u8> {
    let path = xplat_file(name);
    std::fs::read(&path)
        .unwrap_or_else(|e| panic!("read {}: {e} (written by the other platform's stage)", path.display()))
}
