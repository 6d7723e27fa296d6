//! The reference arm written as a URDF by hand
//! (`models/urdf/reference_rrpr/`: rpy offsets, joint axes along y, a fixed
//! joint between two moving ones that splits link 2 in two, a tool frame)
//! moves exactly as its Denavit–Hartenberg file: the two model sources give
//! one chain.
//!
//! Over the 2 s reference motion at fixed sub-steps of 2e-6 s, with the Newmark
//! iteration converged to rounding (tolerance 1e-14, so that both runs stop
//! on the same iterate), every output agrees to 1e-9 of its largest
//! magnitude (7.0e-10 measured, in F_friction[1]): coordinates, rates,
//! accelerations, drive and friction forces,
//! normal loads, reactions (the URDF's reported in its child link frames,
//! turned back into the DH joint frames), end point and energies. At the
//! default iteration tolerance (1e-10) the runs stop on iterates that differ
//! at that level, and a drive spring of k = 1e6 N/m turns it into 1e-8 of
//! the accelerations; that is the solver's resolution, not a difference of
//! the models.

use stick_slip_manipulator::math::Vec3;
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

const URDF_MODEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/urdf/reference_rrpr/reference_rrpr.toml");

fn prepared(mut model: Model, h: f64) -> Model {
    (model.integrator.h_min, model.integrator.h_max) = (h, h);
    model.integrator.tolerance = 1e-14;
    model
}

/// Samples of every compared output every millisecond: one row of named
/// values per sample.
fn run(model: Model) -> Vec<Vec<(String, f64)>> {
    let axes: Vec<_> = model.joints.iter().map(|j| j.reported_axes).collect();
    let mut sim = Simulator::new(model).unwrap();
    let (q, qd, qdd) = reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let interval = 1e-3;
    let mut rows = Vec::new();
    for k in 0..(REFERENCE_RUN_TIME / interval).round() as usize {
        let (q, qd, qdd) = reference_inputs(k as f64 * interval);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, interval).unwrap();
        let s = sim.state();
        let mut row = Vec::new();
        for (i, turn) in axes.iter().enumerate() {
            let push = |row: &mut Vec<(String, f64)>, name: &str, v: f64| row.push((format!("{name}[{}]", i + 1), v));
            push(&mut row, "q", s.q[i]);
            push(&mut row, "qd", s.qd[i]);
            push(&mut row, "qdd", s.qdd[i]);
            push(&mut row, "F_drive", s.drive_force[i]);
            push(&mut row, "F_friction", s.friction_force[i]);
            push(&mut row, "N_normal", s.normal_load[i]);
            push(&mut row, "stick", f64::from(u8::from(s.is_stuck(i))));
            // Back into the engine's link frame (the DH joint frame).
            let (f, n): (Vec3, Vec3) =
                (turn.transpose() * s.reaction_force[i], turn.transpose() * s.reaction_moment[i]);
            for k in 0..3 {
                row.push((format!("f[{},{}]", i + 1, k + 1), f[k]));
                row.push((format!("n[{},{}]", i + 1, k + 1), n[k]));
            }
        }
        for k in 0..3 {
            row.push((format!("x_E[{}]", k + 1), s.end_point[k]));
        }
        row.push(("eps".into(), s.end_point_error()));
        row.push(("E_kin".into(), s.energy.kinetic));
        row.push(("E_pot".into(), s.energy.potential));
        row.push(("Q_friction".into(), s.energy.friction_heat));
        rows.push(row);
    }
    rows
}

#[test]
fn reference_arm_as_urdf_moves_as_its_dh_file_to_1e_9() {
    let dh = prepared(Model::reference_rrpr(), 2e-6);
    let urdf = prepared(Model::from_file(URDF_MODEL).unwrap(), 2e-6);
    assert_eq!(urdf.nq(), 4);
    let names: Vec<_> = urdf.joint_names.iter().map(|n| n.clone().unwrap()).collect();
    assert_eq!(names, ["j1", "j2", "j3", "j4"]);
    // The fixed joint merged link 2's two parts into the DH file's link 2.
    assert!((urdf.links[1].mass - 15.0).abs() < 1e-12);
    assert!(urdf.warnings.is_empty(), "{:?}", urdf.warnings);
    let (a, b) = (run(dh), run(urdf));
    let columns = a[0].len();
    let mut worst = (0.0f64, String::new());
    let mut stick_changes = 0;
    for c in 0..columns {
        let name = &a[0][c].0;
        assert_eq!(name, &b[0][c].0);
        let scale = a.iter().fold(0.0f64, |m, r| m.max(r[c].1.abs())).max(1e-300);
        let deviation = a.iter().zip(&b).fold(0.0f64, |m, (ra, rb)| m.max((ra[c].1 - rb[c].1).abs())) / scale;
        if name.starts_with("stick") {
            stick_changes += a.windows(2).filter(|w| w[0][c].1 != w[1][c].1).count();
        }
        if deviation > worst.0 {
            worst = (deviation, name.clone());
        }
        assert!(
            deviation <= 1e-9,
            "{name}: the URDF model deviates by {deviation:.2e} of the largest magnitude {scale:.3e}"
        );
    }
    eprintln!("largest deviation {:.2e} ({}); {stick_changes} stick/slip changes in the samples", worst.0, worst.1);
    assert!(stick_changes >= 4, "the compared motion has stick-slip");
}
