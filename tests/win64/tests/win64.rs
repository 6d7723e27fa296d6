//! Stage 2 of 3 (x86_64-pc-windows-gnu, run under wine by cargo's target
//! runner): the win64 DLL of the same packaged FMU, loaded by the `fmi` crate
//! the way a Windows master loads it (resources from a `file:///C:/…` URI),
//! runs the 2 s reference motion with the very inputs the linux64 run used
//! (tests/linux64.rs) and must reproduce it: the same stick flags and stiction
//! counts at every step, every other output within 1e-8 of its largest
//! magnitude. A state serialized by linux64 is restored here; the win64 run
//! and its state go to `$STICKSLIP_XPLAT_DIR` for tests/linux64_after_win64.rs.

use stickslip_win64_tests::*;

#[test]
fn win64_runs_the_reference_motion_like_linux64() {
    assert_eq!(platform(), "win64");
    let linux = Record::read("linux64-motion.txt");
    let import = import();
    // Linux's inputs, so that the two FMU binaries alone are compared.
    let (record, state) = run_reference(&import, &linux.inputs);
    record.write("win64-motion.txt");
    write_bytes("win64-state.bin", &state);
    assert_eq!(record.names, linux.names);
    assert_agree("win64 vs linux64, 2 s reference motion", &record.names, &record.rows, &linux.rows);
    let n_stick: Vec<String> = (1..=4)
        .map(|i| {
            let j = record.names.iter().position(|n| *n == format!("n_stick[{i}]")).expect("n_stick");
            format!("{}", record.rows[STEPS][j])
        })
        .collect();
    eprintln!("n_stick per joint after 2 s on win64: [{}]", n_stick.join(", "));
    // Whether this platform's math library computes the inputs (sin, cos of
    // src/motion.rs) to the same bits as glibc's: reported, not required.
    let own = reference_inputs();
    let differing = own.iter().flatten().zip(linux.inputs.iter().flatten()).filter(|(a, b)| a.to_bits() != b.to_bits());
    eprintln!(
        "reference inputs computed on win64 that differ in bits from linux64's: {} of {}",
        differing.count(),
        12 * STEPS
    );
}

#[test]
fn win64_restores_a_linux64_state() {
    let linux = Record::read("linux64-motion.txt");
    let state = read_bytes("linux64-state.bin");
    let after = continue_from_state(&import(), &state, &linux.inputs);
    assert_agree(
        "linux64 state restored on win64",
        &linux.names,
        &after,
        &linux.rows[STATE_AT + 1..=STATE_AT + AFTER_STATE],
    );
}

#[test]
fn win64_answers_bad_calls_with_errors() {
    assert_bad_calls_are_errors(&import());
}
