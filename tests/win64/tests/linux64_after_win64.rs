//! Stage 3 of 3 (Linux, after tests/win64.rs ran under wine): the FMU state the
//! win64 binary serialized at t = 1 s is restored by the linux64 binary, whose
//! next 200 steps must agree with the win64 run's (as in tests/win64.rs).

use stickslip_win64_tests::*;

#[test]
fn linux64_restores_a_win64_state() {
    assert_eq!(platform(), "linux64");
    let win = Record::read("win64-motion.txt");
    let state = read_bytes("win64-state.bin");
    let after = continue_from_state(&import(), &state, &win.inputs);
    assert_agree(
        "win64 state restored on linux64",
        &win.names,
        &after,
        &win.rows[STATE_AT + 1..=STATE_AT + AFTER_STATE],
    );
}
