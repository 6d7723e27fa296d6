//! Newmark iterations (inverse-dynamics evaluations) per sub-step over the
//! reference motion: `cargo run --release --example iteration_count`.
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

fn main() {
    let model = Model::reference_rrpr();
    let substeps = (REFERENCE_RUN_TIME / model.integrator.h_max).round();
    let mut sim = Simulator::new(model).unwrap();
    let at = reference_inputs;
    let (q, qd, qdd) = at(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let mut total = 0;
    for k in 0..2000 {
        let (q, qd, qdd) = at(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, 1e-3).unwrap();
        total += sim.iterations();
    }
    println!("{total} evaluations for {substeps} sub-steps: {:.3} per sub-step", total as f64 / substeps);
}
