//! FMI 3.0, stage 2 of 2 (x86_64-pc-windows-gnu, run under wine by cargo's
//! target runner): the x86_64-windows DLL of the same packaged FMI 3.0 FMU,
//! loaded by the `fmi` crate the way a Windows master loads it, runs what the
//! x86_64-linux binary ran in tests/linux64_fmi3.rs with its very inputs:
//!
//! * the 2 s reference motion: the same stick flags and stiction counts at
//!   every step, every other output within `REL_TOL` of its largest
//!   magnitude (as FMI 2.0, tests/win64.rs; bit-identity is reported), and
//!   equal to the FMI 2.0 FMU's win64 DLL (`$STICKSLIP_FMU`) bit for bit;
//! * the first 0.2 s with early return: the same returns of fmi3DoStep in the
//!   same order (grid points, early returns with eventHandlingNeeded), each at
//!   the same lastSuccessfulTime bit for bit, and the outputs there agreeing
//!   as above.

use stickslip_win64_tests::fmi3::*;
use stickslip_win64_tests::*;

#[test]
fn win64_fmi3_runs_the_reference_motion_like_linux64() {
    assert_eq!(platform(), "win64");
    let linux = Record::read("linux64-fmi3-motion.txt");
    let record = run_reference3(&import3(), &linux.inputs);
    assert_eq!(record.names, linux.names);
    assert_agree("FMI 3.0 win64 vs linux64, 2 s reference motion", &record.names, &record.rows, &linux.rows);
    // the same outputs as the FMI 2.0 FMU's win64 binary, bit for bit
    let (fmi2, _) = run_reference(&import(), &linux.inputs);
    assert_equals_fmi2("win64", &record, &fmi2);
}

#[test]
fn win64_fmi3_returns_early_at_the_same_instants_as_linux64() {
    assert_eq!(platform(), "win64");
    let linux = Stops::read("linux64-fmi3-early.txt");
    let stops = run_early_return(&import3(), &linux.inputs);
    let what = "FMI 3.0 win64 vs linux64, early return over 0.2 s";
    let early = assert_same_returns(what, &stops, &linux);
    assert!(early > 0);
    let rows = |s: &Stops| s.stops.iter().map(|x| x.2.clone()).collect::<Vec<_>>();
    assert_agree(what, &stops.names, &rows(&stops), &rows(&linux));
}
