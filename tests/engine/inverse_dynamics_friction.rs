//! The equation of motion read backwards: the inverse dynamics of a state
//! the engine simulated gives that state's friction loads.
//!
//! `inverse_dynamics` reports, besides τ = M(q)·q̈ + bias(q, q̇), the loads the
//! friction law of each joint with friction reads: the lever load L
//! (`load[i]`, the dry friction is μ·L, (3.11)–(3.15)) and the axial reaction
//! F* (`axial[i]`, (3.17)). The reference arm, with viscous friction on both
//! friction joints (b_v[1] = 4 N·m·s/rad, b_v[3] = 150 N·s/m, so that every
//! term of the law counts), follows the reference motion at fixed 2e-6 s
//! sub-steps with the iteration converged to 1e-12; every 10 ms its q, q̇, q̈
//! go through the binary. For a slipping joint the equation of motion
//! (3.9), (3.10) must hold with the binary's numbers:
//! τ = F^d − μ(q̇)·L·sgn q̇ − b·q̇ with F^d the engine's drive force, to 1e-9
//! of the joint's force scale |F^d| + |F^f| + |τ|, and L must be the
//! engine's lever load to 1e-9; for a stuck joint the friction holding it is
//! F^d − F* (3.16) with the binary's F* (same tolerance). Measured over 118
//! and 114 slipping and 2 and 6 stuck samples of joints 1 and 3: equation of
//! motion 2.9e-12 (the iteration's tolerance), lever load 7.2e-16. F* equals
//! τ, bit for bit: the reaction's component along the axis is the
//! generalized force the joint transmits.
//!
//! The FMU library's `stickslip_inverse_dynamics` (what the fit's
//! equation-error stage calls with ctypes) gives the binary's τ and L bit for
//! bit at the same states and settings, NaN for a joint without friction; a
//! block on a tilted slideway gives the closed form τ = m(q̈ + g sin α),
//! L = m g cos α to 1e-12; bad input is status 1 with a message that names
//! it, never a panic.

use std::collections::HashMap;
use std::ffi::{c_char, CString};
use std::path::PathBuf;

use stick_slip_manipulator::algorithms::kinematics::forward_kinematics;
use stick_slip_manipulator::algorithms::rnea::rnea;
use stick_slip_manipulator::fmi::stickslip_inverse_dynamics;
use stick_slip_manipulator::model::{IntegratorSettings, Parameter, REFERENCE_RRPR_TOML};
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{Data, DriveInputs, Model, Phase, Simulator, State};

/// The reference model file with viscous friction on joints 1 and 3.
fn model_text() -> String {
    let joint_1 = "v_s = 0.0, viscous = 0.0 }   # viscous b";
    let joint_3 = "v_s = 0.0, viscous = 0.0 }   # N·s/m";
    assert!(REFERENCE_RRPR_TOML.contains(joint_1) && REFERENCE_RRPR_TOML.contains(joint_3));
    REFERENCE_RRPR_TOML
        .replace(joint_1, "v_s = 0.0, viscous = 4.0 }   # viscous b")
        .replace(joint_3, "v_s = 0.0, viscous = 150.0 }   # N·s/m")
}

/// Every 10 ms of the first 1.2 s of the reference motion: the state.
fn simulated_states(model: &Model) -> Vec<State> {
    let mut model = model.clone();
    let default = model.integrator;
    model.integrator = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, tolerance: 1e-12, ..default };
    let mut sim = Simulator::new(model).unwrap();
    let inputs = |t: f64| reference_inputs(t);
    let (a, b, c) = inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, None).unwrap();
    let mut states = Vec::new();
    for k in 0..1200 {
        let (a, b, c) = inputs(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, 1e-3).unwrap();
        if k % 10 == 9 {
            states.push(sim.state().clone());
        }
    }
    states
}

/// A fresh directory for one run's files (the tests run in parallel).
fn scratch() -> PathBuf {
    static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("inverse_dynamics_friction_{}_{k}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `inverse_dynamics` on the states; its output, column by name.
fn inverse_dynamics(model_text: &str, states: &[State], n: usize) -> HashMap<String, Vec<f64>> {
    inverse_dynamics_with(model_text, states, n, &[]).expect("inverse_dynamics failed")
}

/// The same with extra arguments (`--set ...`); Err(stderr) where it exits non-zero.
fn inverse_dynamics_with(
    model_text: &str,
    states: &[State],
    n: usize,
    extra: &[&str],
) -> Result<HashMap<String, Vec<f64>>, String> {
    let dir = scratch();
    let (model, input, output) = (dir.join("model.toml"), dir.join("states.csv"), dir.join("out.csv"));
    std::fs::write(&model, model_text).unwrap();
    let mut csv = ["q", "qd", "qdd"].iter().flat_map(|b| (1..=n).map(move |i| format!("{b}[{i}]"))).collect::<Vec<_>>();
    let mut lines = vec![csv.join(",")];
    for s in states {
        // `{:e}` writes the shortest digits that read back to the same double.
        csv = [&s.q, &s.qd, &s.qdd].iter().flat_map(|v| v[..n].iter().map(|x| format!("{x:e}"))).collect();
        lines.push(csv.join(","));
    }
    std::fs::write(&input, lines.join("\n") + "\n").unwrap();
    let done = std::process::Command::new(env!("CARGO_BIN_EXE_inverse_dynamics"))
        .args(["--model", model.to_str().unwrap(), "--states", input.to_str().unwrap()])
        .args(["--out", output.to_str().unwrap()])
        .args(extra)
        .output()
        .unwrap();
    if !done.status.success() {
        std::fs::remove_dir_all(&dir).unwrap();
        return Err(String::from_utf8_lossy(&done.stderr).into_owned());
    }
    let text = std::fs::read_to_string(&output).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let mut rows = text.lines();
    // Quoted names (they hold commas): split at `","`.
    let header = rows.next().unwrap();
    let names: Vec<String> = header.trim_matches('"').split("\",\"").map(str::to_string).collect();
    let mut columns: HashMap<String, Vec<f64>> = names.iter().map(|n| (n.clone(), Vec::new())).collect();
    for row in rows {
        let cells: Vec<f64> = row.split(',').map(|c| c.parse().unwrap()).collect();
        assert_eq!(cells.len(), names.len());
        for (name, x) in names.iter().zip(cells) {
            columns.get_mut(name).unwrap().push(x);
        }
    }
    Ok(columns)
}

/// `--set NAME[i]=VALUE` (the fit's equation-error stage passes an experiment's known
/// masses and contact geometry so): the same columns as a model file with that value,
/// bit for bit; a name the model does not have, a value out of range or a relation the
/// model refuses (μ_s < μ_k) is one line on stderr and a non-zero exit.
#[test]
fn set_changes_a_parameter_as_the_model_file_would() {
    let text = model_text();
    let model = Model::from_toml_str(&text).unwrap();
    let states = simulated_states(&model);
    let n = model.nq();
    let mut heavier = model.clone();
    heavier.set_parameter(Parameter::Mass, 2, 12.0).unwrap();
    let set = inverse_dynamics_with(&text, &states, n, &["--set", "m[3]=12"]).unwrap();
    let plain = inverse_dynamics(&text, &states, n);
    assert_ne!(set["tau[1]"], plain["tau[1]"], "m[3] changes the column's load");
    // The same numbers as the engine's RNEA with the heavier link.
    let mut data = Data::new(&heavier);
    for (k, s) in states.iter().enumerate() {
        forward_kinematics(&heavier, &mut data, &s.q);
        rnea(&heavier, &mut data, &s.q, &s.qd, &s.qdd);
        for i in 0..n {
            assert_eq!(set[&format!("tau[{}]", i + 1)][k], data.tau[i], "tau[{}] at state {k}", i + 1);
        }
    }
    for bad in ["m[9]=1", "m[3]=-1", "nonsense=1", "mu_k[1]=0.9", "m[0]=1", "m[3]"] {
        let err = inverse_dynamics_with(&text, &states, n, &["--set", bad]).unwrap_err();
        assert_eq!(err.trim().lines().count(), 1, "{bad}: {err}");
    }
}

#[test]
fn inverse_dynamics_of_a_simulated_state_gives_its_friction_loads() {
    let text = model_text();
    let model = Model::from_toml_str(&text).unwrap();
    let n = model.nq();
    let states = simulated_states(&model);
    let columns = inverse_dynamics(&text, &states, n);
    // Only the joints with friction have load and axial columns.
    for i in [2, 4] {
        assert!(!columns.contains_key(&format!("load[{i}]")) && !columns.contains_key(&format!("axial[{i}]")));
    }
    let (mut slipping, mut stuck) = ([0usize; 2], [0usize; 2]);
    let (mut worst_equation, mut worst_load): (f64, f64) = (0.0, 0.0);
    for (k, s) in states.iter().enumerate() {
        for (slot, i) in [0usize, 2].into_iter().enumerate() {
            let tau = columns[&format!("tau[{}]", i + 1)][k];
            let load = columns[&format!("load[{}]", i + 1)][k];
            let axial = columns[&format!("axial[{}]", i + 1)][k];
            assert_eq!(axial.to_bits(), tau.to_bits(), "F* (3.17) is τ");
            let friction = model.joints[i].friction.unwrap().coefficients;
            let drive = s.drive_force[i];
            let at = format!("joint {} at t = {:.3} s ({:?})", i + 1, s.time, s.phase[i]);
            let scale = drive.abs() + s.friction_force[i].abs() + tau.abs();
            match s.phase[i] {
                Phase::Slipping(_) if s.qd[i].abs() > 1e-6 => {
                    slipping[slot] += 1;
                    let qd = s.qd[i];
                    // (3.9), (3.10) backwards, the friction from the binary's L.
                    let f_friction = friction.kinetic(qd) * load * qd.signum() + friction.viscous * qd;
                    let equation = (drive - f_friction - tau).abs() / scale;
                    worst_equation = worst_equation.max(equation);
                    assert!(equation < 1e-9, "{at}: τ = {tau}, F^d − F^f = {}", drive - f_friction);
                    let lever = (load - s.lever_load[i]).abs() / s.lever_load[i];
                    worst_load = worst_load.max(lever);
                    assert!(lever < 1e-9, "{at}: L = {load} vs the engine's {}", s.lever_load[i]);
                }
                Phase::Stuck => {
                    stuck[slot] += 1;
                    // (3.16): the friction holding it is F^d − F*.
                    let held = (s.friction_force[i] - (drive - axial)).abs() / scale;
                    worst_equation = worst_equation.max(held);
                    assert!(held < 1e-9, "{at}: F^f = {} vs F^d − F* = {}", s.friction_force[i], drive - axial);
                }
                _ => {}
            }
        }
    }
    eprintln!(
        "slipping samples {slipping:?}, stuck {stuck:?} (joints 1, 3); equation of motion {worst_equation:.1e}, \
         lever load {worst_load:.1e} relative"
    );
    assert!(slipping.iter().all(|&c| c >= 10), "too few slipping samples: {slipping:?}");
    assert!(stuck[1] >= 1, "joint 3 is never stuck at a sample: {stuck:?}");
}

/// The export's answer: status, message, τ and L (rows × n each).
struct Export {
    status: i32,
    message: String,
    tau: Vec<f64>,
    lever_load: Vec<f64>,
}

/// `stickslip_inverse_dynamics` on `states` (rows of `columns` values) of the
/// model `text` with `settings`, outputs sized for `n` joints.
fn export(text: &str, urdf: Option<&str>, settings: &[&str], states: &[f64], columns: usize, n: usize) -> Export {
    let (text, urdf) = (CString::new(text).unwrap(), urdf.map(|u| CString::new(u).unwrap()));
    let settings: Vec<CString> = settings.iter().map(|s| CString::new(*s).unwrap()).collect();
    let pointers: Vec<*const c_char> = settings.iter().map(|s| s.as_ptr()).collect();
    let rows = states.len() / columns;
    let (mut tau, mut lever_load) = (vec![f64::NAN; rows * n], vec![f64::NAN; rows * n]);
    let mut message = vec![0u8; 512];
    let status = unsafe {
        stickslip_inverse_dynamics(
            text.as_ptr(),
            urdf.as_ref().map_or(std::ptr::null(), |u| u.as_ptr()),
            pointers.as_ptr(),
            pointers.len(),
            states.as_ptr(),
            rows,
            columns,
            tau.as_mut_ptr(),
            lever_load.as_mut_ptr(),
            rows * n,
            message.as_mut_ptr().cast(),
            message.len(),
        )
    };
    let end = message.iter().position(|&b| b == 0).expect("the message is NUL-terminated");
    Export { status, message: String::from_utf8(message[..end].to_vec()).unwrap(), tau, lever_load }
}

/// Rows × [q(n), q̇(n), q̈(n)] of the states.
fn state_rows(states: &[State], n: usize) -> Vec<f64> {
    states.iter().flat_map(|s| s.q[..n].iter().chain(&s.qd[..n]).chain(&s.qdd[..n]).copied()).collect()
}

#[test]
fn the_fmu_library_export_gives_the_binarys_numbers_bit_for_bit() {
    let text = model_text();
    let model = Model::from_toml_str(&text).unwrap();
    let n = model.nq();
    let states = simulated_states(&model);
    let binary = inverse_dynamics_with(&text, &states, n, &["--set", "m[3]=12", "--set", "d_A[1]=0.12"]).unwrap();
    let out = export(&text, None, &["m[3]=12", "d_A[1]=0.12"], &state_rows(&states, n), 3 * n, n);
    assert_eq!((out.status, out.message.as_str()), (0, ""));
    for (k, _) in states.iter().enumerate() {
        for i in 0..n {
            let tau = binary[&format!("tau[{}]", i + 1)][k];
            assert_eq!(out.tau[k * n + i].to_bits(), tau.to_bits(), "tau[{}] at state {k}", i + 1);
            let load = out.lever_load[k * n + i];
            match binary.get(&format!("load[{}]", i + 1)) {
                Some(column) => assert_eq!(load.to_bits(), column[k].to_bits(), "load[{}] at state {k}", i + 1),
                None => assert!(load.is_nan(), "joint {} has no friction: NaN, not {load}", i + 1),
            }
        }
    }
}

#[test]
fn the_export_gives_a_block_on_a_tilted_slideway_in_closed_form() {
    // One prismatic joint along z0, the block's centre of mass at the slider's
    // centre: gravity's component g sin α along the axis is carried by τ, its
    // component g cos α across it by the slider, N_s = m g cos α (3.11).
    let (m, g, tilt) = (2.5, 9.81, 0.4_f64);
    let text = format!(
        "name = \"block\"\ngravity = [0.0, {}, {}]\nend_point = [0.0, 0.0, 0.0]\n[[joint]]\ntype = \"prismatic\"\n\
         theta = 0.0\nd = 0.0\na = 0.0\nalpha = 0.0\ndrive = {{ type = \"flexible\", k = 1.0e4, h = 0.0, clearance = 0.0 }}\n\
         friction = {{ mu_k = 0.2, mu_s = 0.3, v_s = 0.0, viscous = 0.0 }}\n\
         slider = {{ centre = [0.0, 0.0, 0.0], a = 0.2, b = 0.07, c = 0.07 }}\n\
         link = {{ mass = 1.0, com = [0.0, 0.0, 0.0], inertia = {{ xx = 0.01, yy = 0.01, zz = 0.01 }} }}\n",
        -g * tilt.cos(),
        -g * tilt.sin()
    );
    let states = [0.0, 0.0, 0.0, 0.3, -1.5, 4.0, -0.2, 2.0, -7.5];
    let out = export(&text, None, &[&format!("m[1]={m}")], &states, 3, 1);
    assert_eq!((out.status, out.message.as_str()), (0, ""));
    for (r, row) in states.chunks(3).enumerate() {
        let (tau, load) = (m * (row[2] + g * tilt.sin()), m * g * tilt.cos());
        assert!((out.tau[r] - tau).abs() <= 1e-12 * tau.abs().max(m * g), "row {r}: τ = {} vs {tau}", out.tau[r]);
        assert!((out.lever_load[r] - load).abs() <= 1e-12 * load, "row {r}: L = {} vs {load}", out.lever_load[r]);
    }
}

#[test]
fn the_export_refuses_bad_input_with_a_message() {
    let text = model_text();
    let n = 4;
    let mut states: Vec<f64> = (0..2 * 3 * n).map(|k| 0.01 * k as f64).collect();
    let refused = |out: Export, says: &str| {
        assert_eq!(out.status, 1, "{says}: {}", out.message);
        assert!(out.message.contains(says), "expected `{says}` in: {}", out.message);
    };
    refused(export(&text, None, &["nonsense[1]=2"], &states, 3 * n, n), "no parameter is named `nonsense`");
    refused(export(&text, None, &["m[3]=-1"], &states, 3 * n, n), "m[3]");
    refused(export(&text, None, &["mu_k[1]=0.9"], &states, 3 * n, n), "static coefficient below the kinetic one");
    refused(export("name = [", None, &[], &states, 3 * n, n), "the model: model file is malformed");
    refused(export("urdf = \"arm.urdf\"\n", None, &[], &states, 3 * n, n), "none was supplied");
    refused(export(&text, None, &[], &states[..2 * 3 * (n - 1)], 3 * (n - 1), n - 1), "3n = 12");
    refused(export(&text, None, &[], &states, 3 * n, n - 1), "2 rows of 4 joints need 8");
    states[3 * n + n + 1] = f64::NAN;
    refused(export(&text, None, &[], &states, 3 * n, n), "row 2: qd[2] = NaN is not finite");
    // NULL where values are due, overlapping outputs and a short message buffer.
    let model = CString::new(text).unwrap();
    let mut out = vec![0.0; 2 * n];
    let mut message = [0x55u8; 8];
    let call = |states: *const f64, tau: *mut f64, lever_load: *mut f64, message: &mut [u8]| unsafe {
        let (p, size) = (message.as_mut_ptr().cast(), message.len());
        stickslip_inverse_dynamics(
            model.as_ptr(),
            std::ptr::null(),
            std::ptr::null(),
            0,
            states,
            2,
            3 * n,
            tau,
            lever_load,
            2 * n,
            p,
            size,
        )
    };
    assert_eq!(call(std::ptr::null(), out.as_mut_ptr(), out.as_mut_ptr().wrapping_add(n), &mut message), 1);
    assert_eq!(&message, b"`tau` a\0", "cut to the buffer, NUL-terminated");
    let mut long = [0u8; 200];
    let (tau, lever_load) = (out.as_mut_ptr(), out.as_mut_ptr().wrapping_add(n));
    assert_eq!(call(std::ptr::null(), tau, lever_load, &mut long), 1);
    assert!(long.starts_with(b"`tau` and `lever_load` overlap\0"));
    let mut separate = vec![0.0; 2 * n];
    assert_eq!(call(std::ptr::null(), out.as_mut_ptr(), separate.as_mut_ptr(), &mut long), 1);
    assert!(long.starts_with(b"`states[]` is NULL but has 24 elements\0"));
    let no_model = unsafe {
        stickslip_inverse_dynamics(
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            0,
            std::ptr::null(),
            0,
            0,
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            0,
            long.as_mut_ptr().cast(),
            long.len(),
        )
    };
    assert_eq!(no_model, 1);
    assert!(long.starts_with(b"`model` is NULL\0"));
}
