//! The packaged FMU through an independent FMI 2.0 importer written in Rust: the
//! `fmi` crate (rust-fmi 0.8, feature `fmi2`). It unzips the `.fmu`, parses the
//! modelDescription with its own strict schema, loads
//! `binaries/linux64/StickSlipManipulator.so` with libloading and calls the C
//! functions. 100 communication steps of 1 ms of the reference motion must equal a
//! direct `Simulator` run of the engine to 1e-12 of each output's largest magnitude
//! (the FMU adds no arithmetic of its own: they are in fact bit for bit).
//!
//! Which FMU: `$STICKSLIP_FMU` if set; otherwise one packed by this test (into
//! `target/<profile>/fmi-crate-test/`) from the artifacts of this very build: the
//! `package_fmu` binary and the cdylib `libstick_slip_manipulator.so` that cargo
//! compiles with the rlib the test links, so that the FMU and the direct run come
//! from the same source (scripts/test.sh runs cargo test before
//! scripts/build_fmu.sh); failing that,
//! `target/fmu/StickSlipManipulator.fmu` (built by `bash scripts/build_fmu.sh`).
//! If none exists the tests print why and return (skip).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::traits::{FmiImport, FmiStatus};
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{DriveInputs, Model, Simulator, State};

const STEP: f64 = 1e-3;
const STEPS: usize = 100;

/// The FMU under test, packed once per test process. A test without an FMU
/// fails (it must not pass without checking anything).
fn fmu_file() -> PathBuf {
    static FMU: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    FMU.get_or_init(find_or_pack_fmu).clone().unwrap_or_else(|reason| panic!("{reason}"))
}

fn find_or_pack_fmu() -> Result<PathBuf, String> {
    if let Ok(p) = std::env::var("STICKSLIP_FMU") {
        return Ok(PathBuf::from(p));
    }
    // The cdylib of this build: rustc writes it to deps/ together with the rlib the
    // test links (cdylib names carry no hash; `cargo build` also copies it one level up).
    let packager = PathBuf::from(env!("CARGO_BIN_EXE_package_fmu"));
    let dir = packager.parent().expect("target/<profile>");
    let candidates = [dir.join("deps/libstick_slip_manipulator.so"), dir.join("libstick_slip_manipulator.so")];
    if let Some(lib) = candidates.iter().find(|p| p.is_file()) {
        let tmp = dir.join("fmi-crate-test");
        std::fs::create_dir_all(&tmp).expect("directory for the test FMU");
        let out = tmp.join("StickSlipManipulator.fmu");
        let status = std::process::Command::new(&packager)
            .arg("--lib")
            .arg(lib)
            .arg("--out")
            .arg(&out)
            .status()
            .expect("run package_fmu");
        assert!(status.success(), "package_fmu --lib {} --out {} failed", lib.display(), out.display());
        eprintln!("fmi_crate: packed {} from {}", out.display(), lib.display());
        return Ok(out);
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fmu/StickSlipManipulator.fmu");
    if built.is_file() {
        return Ok(built);
    }
    Err(format!(
        "no FMU to test: no libstick_slip_manipulator.so in {} and no {}; build it with `bash scripts/build_fmu.sh`",
        dir.display(),
        built.display()
    ))
}

/// The reference motion's inputs at t: q*, q̇*, q̈* of the 4 joints.
fn inputs_at(t: f64) -> ([f64; 4], [f64; 4], [f64; 4]) {
    reference_inputs(t)
}

/// The outputs of the FMU interface computed from an engine state, by variable name.
fn outputs_of(s: &State) -> Vec<(String, f64)> {
    let n = s.nq();
    let mut v = Vec::new();
    let mut per_joint = |name: &str, f: &dyn Fn(usize) -> f64| {
        for i in 0..n {
            v.push((format!("{name}[{}]", i + 1), f(i)));
        }
    };
    per_joint("q", &|i| s.q[i]);
    per_joint("qd", &|i| s.qd[i]);
    per_joint("qdd", &|i| s.qdd[i]);
    per_joint("F_drive", &|i| s.drive_force[i]);
    per_joint("F_friction", &|i| s.friction_force[i]);
    per_joint("N_normal", &|i| s.normal_load[i]);
    per_joint("eps_joint", &|i| s.joint_error(i));
    per_joint("n_stick", &|i| s.stick_count[i] as f64);
    per_joint("t_stick", &|i| s.stuck_time[i]);
    for i in 0..n {
        for k in 0..3 {
            v.push((format!("f[{},{}]", i + 1, k + 1), s.reaction_force[i][k]));
            v.push((format!("n[{},{}]", i + 1, k + 1), s.reaction_moment[i][k]));
        }
    }
    v.push(("eps".into(), s.end_point_error()));
    for k in 0..3 {
        v.push((format!("x_E[{}]", k + 1), s.end_point[k]));
    }
    let e = &s.energy;
    for (name, x) in [
        ("E_kin", e.kinetic),
        ("E_pot", e.potential),
        ("E_spring", e.spring),
        ("W_drive", e.drive_work),
        ("Q_friction", e.friction_heat),
        ("Q_damping", e.damping_heat),
    ] {
        v.push((name.into(), x));
    }
    v
}

fn vr(import: &Fmi2Import, name: &str) -> u32 {
    import
        .model_description()
        .model_variable_by_name(name)
        .unwrap_or_else(|_| panic!("no variable `{name}` in the modelDescription"))
        .value_reference
}

struct Vrs {
    inputs: Vec<u32>,
    stick: Vec<u32>,
}

fn vrs(import: &Fmi2Import) -> Vrs {
    let mut inputs = Vec::new();
    for group in ["q_star", "qd_star", "qdd_star"] {
        for i in 1..=4 {
            inputs.push(vr(import, &format!("{group}[{i}]")));
        }
    }
    Vrs { inputs, stick: (1..=4).map(|i| vr(import, &format!("stick[{i}]"))).collect() }
}

fn set_inputs(inst: &mut InstanceCS, v: &Vrs, t: f64) {
    let (q, qd, qdd) = inputs_at(t);
    let values: Vec<f64> = q.iter().chain(&qd).chain(&qdd).copied().collect();
    inst.set_real(&v.inputs, &values).expect("fmi2SetReal of the inputs");
}

fn initialized(import: &Fmi2Import, name: &str, v: &Vrs) -> InstanceCS {
    let mut inst = import.instantiate_cs(name, false, false).expect("fmi2Instantiate");
    inst.setup_experiment(None, 0.0, None).expect("fmi2SetupExperiment");
    inst.enter_initialization_mode().expect("fmi2EnterInitializationMode");
    set_inputs(&mut inst, v, 0.0);
    inst.exit_initialization_mode().expect("fmi2ExitInitializationMode");
    inst
}

/// Largest |a − b| / max|b| over the steps, for one signal (0 if equal).
fn deviation(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let diff = a.iter().zip(b).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
    if diff == 0.0 {
        0.0
    } else if scale > 0.0 {
        diff / scale
    } else {
        f64::INFINITY
    }
}

/// 100 steps of the reference motion through the `fmi` crate equal a direct
/// `Simulator` run to 1e-12 of each output's largest magnitude: every Real output
/// (q, qd, qdd, F_drive, F_friction, N_normal, eps_joint, n_stick, t_stick, f, n, eps,
/// x_E, energies)
/// and the Boolean stick[i], after initialization and after each step.
#[test]
fn fmi_crate_runs_the_fmu_like_the_engine() {
    let path = fmu_file();
    let import: Fmi2Import = fmi::import::from_path(&path).expect("the fmi crate imports the FMU");
    let md = import.model_description();
    assert_eq!(md.fmi_version, "2.0");
    assert_eq!(md.co_simulation.as_ref().expect("CoSimulation").model_identifier, "StickSlipManipulator");
    let v = vrs(&import);
    let mut inst = initialized(&import, "fmi_crate", &v);
    assert_eq!(inst.get_version(), "2.0");
    assert_eq!(inst.get_types_platform(), "default");

    let mut sim = Simulator::new(Model::reference_rrpr()).expect("reference model");
    let (q, qd, qdd) = inputs_at(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).expect("initialize");

    let names: Vec<String> = outputs_of(sim.state()).into_iter().map(|(n, _)| n).collect();
    let out_vrs: Vec<u32> = names.iter().map(|n| vr(&import, n)).collect();
    let mut fmu_rows: Vec<Vec<f64>> = Vec::new();
    let mut direct_rows: Vec<Vec<f64>> = Vec::new();
    let mut record = |inst: &mut InstanceCS, sim: &Simulator| {
        let mut values = vec![0.0; out_vrs.len()];
        inst.get_real(&out_vrs, &mut values).expect("fmi2GetReal");
        let mut stick = vec![0; v.stick.len()];
        inst.get_boolean(&v.stick, &mut stick).expect("fmi2GetBoolean");
        values.extend(stick.iter().map(|&b| f64::from(u8::from(b != 0))));
        fmu_rows.push(values);
        let s = sim.state();
        let mut direct: Vec<f64> = outputs_of(s).into_iter().map(|(_, x)| x).collect();
        direct.extend((0..s.nq()).map(|i| f64::from(u8::from(s.is_stuck(i)))));
        direct_rows.push(direct);
    };
    record(&mut inst, &sim);
    for k in 0..STEPS {
        let t = k as f64 * STEP;
        set_inputs(&mut inst, &v, t);
        inst.do_step(t, STEP, true).expect("fmi2DoStep");
        let (q, qd, qdd) = inputs_at(t);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, STEP).expect("advance");
        record(&mut inst, &sim);
    }
    inst.terminate().expect("fmi2Terminate");

    let mut all_names = names.clone();
    all_names.extend((1..=4).map(|i| format!("stick[{i}]")));
    let mut worst = (0.0_f64, String::new());
    let mut identical = true;
    for (j, name) in all_names.iter().enumerate() {
        let a: Vec<f64> = fmu_rows.iter().map(|r| r[j]).collect();
        let b: Vec<f64> = direct_rows.iter().map(|r| r[j]).collect();
        identical &= a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits());
        let d = deviation(&a, &b);
        if d > worst.0 {
            worst = (d, name.clone());
        }
        assert!(d <= 1e-12, "{name}: FMU and engine differ by {d:.3e} of the signal's range");
    }
    eprintln!("fmi crate vs engine, {STEPS} steps: bit for bit = {identical}, worst relative deviation {worst:?}");
    // the run is not trivial: joint 1 breaks away within the 100 ms
    let stick1 = all_names.iter().position(|n| n == "stick[1]").unwrap();
    assert_eq!(fmu_rows[0][stick1], 1.0);
    assert_eq!(fmu_rows[STEPS][stick1], 0.0);
}

/// Through the `fmi` crate, an FMU state got after 50 steps, serialized, and
/// deserialized into a second instance gives the same next 20 steps, bit for bit.
#[test]
fn fmi_crate_state_round_trip() {
    let path = fmu_file();
    let import: Fmi2Import = fmi::import::from_path(&path).expect("the fmi crate imports the FMU");
    let v = vrs(&import);
    let q3 = vr(&import, "q[3]");
    let qd1 = vr(&import, "qd[1]");
    let run = |inst: &mut InstanceCS, from: usize, steps: usize| -> Vec<[f64; 2]> {
        (from..from + steps)
            .map(|k| {
                let t = k as f64 * STEP;
                set_inputs(inst, &v, t);
                inst.do_step(t, STEP, true).expect("fmi2DoStep");
                let mut x = [0.0; 2];
                inst.get_real(&[q3, qd1], &mut x).expect("fmi2GetReal");
                x
            })
            .collect()
    };
    let mut a = initialized(&import, "a", &v);
    run(&mut a, 0, 50);
    let state = a.get_fmu_state().expect("fmi2GetFMUstate");
    let bytes = a.serialize_fmu_state(&state).expect("fmi2SerializeFMUstate");
    let expected = run(&mut a, 50, 20);

    let mut b = import.instantiate_cs("b", false, false).expect("fmi2Instantiate");
    let restored = b.deserialize_fmu_state(&bytes).expect("fmi2DeSerializeFMUstate");
    b.set_fmu_state(&restored).ok().expect("fmi2SetFMUstate");
    let actual = run(&mut b, 50, 20);
    for (x, y) in actual.iter().zip(&expected) {
        assert_eq!(x.map(f64::to_bits), y.map(f64::to_bits));
    }
    // a truncated buffer is refused with fmi2Error
    assert!(matches!(b.deserialize_fmu_state(&bytes[..bytes.len() / 2]), Err(fmi::fmi2::Fmi2Error::Error)));
}
