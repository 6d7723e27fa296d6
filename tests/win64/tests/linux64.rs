//! Stage 1 of 3 (Linux): the linux64 binary of the packaged FMU runs the 2 s
//! reference motion through the `fmi` crate; its outputs, inputs and the FMU
//! state serialized at t = 1 s are written to `$STICKSLIP_XPLAT_DIR` as what
//! the win64 binary is held to (tests/win64.rs). Restoring that state on Linux
//! must give the run's own continuation bit for bit, and bad calls are errors.

use stickslip_win64_tests::*;

#[test]
fn linux64_runs_the_reference_motion_and_writes_it_for_win64() {
    assert_eq!(platform(), "linux64");
    let import = import();
    let inputs = reference_inputs();
    let (record, state) = run_reference(&import, &inputs);
    // the motion is not trivial: joint 1 is stuck at the start and breaks away
    let stick1 = record.names.iter().position(|n| n == "stick[1]").expect("stick[1]");
    assert_eq!(record.rows[0][stick1], 1.0);
    assert!(record.rows.iter().any(|r| r[stick1] == 0.0));
    let after = continue_from_state(&import, &state, &inputs);
    let (identical, _, _) = assert_agree(
        "linux64 state restored on linux64",
        &record.names,
        &after,
        &record.rows[STATE_AT + 1..=STATE_AT + AFTER_STATE],
    );
    assert!(identical, "a restored state continues bit for bit on the same binary");
    record.write("linux64-motion.txt");
    write_bytes("linux64-state.bin", &state);
}

#[test]
fn linux64_answers_bad_calls_with_errors() {
    assert_bad_calls_are_errors(&import());
}
