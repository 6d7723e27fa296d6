//! FMI 3.0, stage 1 of 2 (Linux): the x86_64-linux binary of the packaged FMI
//! 3.0 FMU runs, through the `fmi` crate, the 2 s reference motion and the
//! first 0.2 s of it with early return; both are written to
//! `$STICKSLIP_XPLAT_DIR` as what the x86_64-windows binary is held to
//! (tests/win64_fmi3.rs). The reference motion must equal the FMI 2.0 FMU's
//! (`$STICKSLIP_FMU`, its linux64 binary) bit for bit.

use stickslip_win64_tests::fmi3::*;
use stickslip_win64_tests::*;

#[test]
fn linux64_fmi3_runs_the_reference_motion_and_writes_it_for_win64() {
    assert_eq!(platform(), "linux64");
    let inputs = reference_inputs();
    let record = run_reference3(&import3(), &inputs);
    // the motion is not trivial: joint 1 is stuck at the start and breaks away
    let stick1 = record.names.iter().position(|n| n == "stick[1]").expect("stick[1]");
    assert_eq!(record.rows[0][stick1], 1.0);
    assert!(record.rows.iter().any(|r| r[stick1] == 0.0));
    record.write("linux64-fmi3-motion.txt");

    // the same outputs as the FMI 2.0 FMU's linux64 binary, bit for bit
    let (fmi2, _) = run_reference(&import(), &inputs);
    assert_equals_fmi2("linux64", &record, &fmi2);
}

#[test]
fn linux64_fmi3_returns_early_at_the_events_and_writes_them_for_win64() {
    assert_eq!(platform(), "linux64");
    let inputs = reference_inputs();
    let stops = run_early_return(&import3(), &inputs[..EARLY_RETURN_STEPS]);
    let early = stops.early_returns();
    eprintln!("linux64: early returns over 0.2 s: {} at {:?}", early.len(), early);
    // the first stick→slip of the reference run: joint 1 at t = 0.0201 s
    let (t1, event) = early.first().copied().expect("an early return within 0.2 s");
    assert!(event, "the first early return asks for event handling");
    assert!((t1 - 0.0201).abs() < 5e-5, "first early return at t = {t1}, not at the first stick→slip (0.0201 s)");
    stops.write("linux64-fmi3-early.txt");
}
