//! The stepping loop's instruction-set variants give bit-identical results.
//!
//! The loop is compiled for the baseline and for AVX2 and chosen at run time
//! (`stepper::InstructionSet`). Both must perform the same floating-point
//! operations in the same order; a fused multiply–add, a reassociated sum or
//! a vectorized reduction in one of them would show here as a difference in
//! the last bits, which the stiction dynamics then amplify.

use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::stepper::InstructionSet;
use stick_slip_manipulator::{DriveInputs, Model, Simulator, StepError};

/// The state after every interval of the reference run, printed with `{:?}`:
/// Rust prints each f64 as the shortest decimal that reads back to the same
/// bits (and −0.0 as such), so equal strings mean bit-identical states.
fn reference_run(set: InstructionSet, steps: (f64, f64), end: f64) -> (Vec<String>, String) {
    let mut model = Model::reference_rrpr();
    (model.integrator.h_min, model.integrator.h_max) = steps;
    let mut sim = Simulator::new(model).unwrap();
    sim.set_instruction_set(set).unwrap();
    assert_eq!(sim.instruction_set(), set);
    let (q, qd, qdd) = reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let interval = 1e-3;
    let mut states = Vec::new();
    for k in 0..(end / interval).round() as usize {
        let (q, qd, qdd) = reference_inputs(k as f64 * interval);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, interval).unwrap();
        states.push(format!("{:?}", sim.state()));
    }
    (states, format!("{:?}", sim.transitions()))
}

/// `steps`: (h_min, h_max), s.
fn assert_identical(steps: (f64, f64), end: f64) {
    let h_max = steps;
    let (baseline, baseline_transitions) = reference_run(InstructionSet::Baseline, steps, end);
    let (avx2, avx2_transitions) = reference_run(InstructionSet::Avx2, steps, end);
    if let Some(k) = baseline.iter().zip(&avx2).position(|(a, b)| a != b) {
        panic!(
            "sub-steps {h_max:?}: states differ after interval {k}:\nbaseline {}\nAVX2     {}",
            baseline[k], avx2[k]
        );
    }
    assert_eq!(baseline.len(), avx2.len());
    assert_eq!(baseline_transitions, avx2_transitions, "sub-steps {h_max:?}: transition logs differ");
    // The runs did stick and slip: the comparison covers the switching path.
    assert!(baseline_transitions.contains("Stuck"), "no transitions: {baseline_transitions}");
}

#[test]
fn baseline_and_avx2_give_bit_identical_reference_runs() {
    if !InstructionSet::Avx2.is_available() {
        // Asking for AVX2 must fail cleanly; but the two builds were not
        // compared, and a test that compared nothing must not pass unnoticed:
        // it fails unless the run says that this is expected.
        let mut sim = Simulator::new(Model::reference_rrpr()).unwrap();
        assert!(matches!(
            sim.set_instruction_set(InstructionSet::Avx2),
            Err(StepError::UnsupportedInstructionSet { name: "AVX2" })
        ));
        assert_eq!(sim.instruction_set(), InstructionSet::Baseline);
        assert!(
            std::env::var_os("STICKSLIP_NO_AVX2").is_some(),
            "this processor has no AVX2: the AVX2 and baseline stepping loops could not be compared; \
             run on a processor with AVX2, or set STICKSLIP_NO_AVX2=1 to accept that only the baseline loop runs"
        );
        eprintln!("NOT COMPARED: this processor has no AVX2 (STICKSLIP_NO_AVX2 set): only the baseline loop runs");
        return;
    }
    // The whole reference motion at the study's fixed sub-step, ten times
    // coarser, and error-controlled with the default settings.
    assert_identical((2e-6, 2e-6), REFERENCE_RUN_TIME);
    assert_identical((2e-5, 2e-5), REFERENCE_RUN_TIME);
    let default = Model::reference_rrpr().integrator;
    assert!(!default.fixed_step());
    assert_identical((default.h_min, default.h_max), REFERENCE_RUN_TIME);
}

#[test]
fn the_best_available_instruction_set_is_the_default() {
    let sim = Simulator::new(Model::reference_rrpr()).unwrap();
    assert_eq!(sim.instruction_set(), InstructionSet::best_available());
    assert!(sim.instruction_set().is_available());
}
