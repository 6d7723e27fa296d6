//! Stepping does not touch the heap, and a simulator is small.
//!
//! A counting global allocator records every allocation of this test
//! process. Once a simulator is initialized, advancing it over intervals
//! that include stick–slip transitions, phase decisions and event location
//! allocates nothing; restoring a state allocates nothing. A simulator of
//! the reference manipulator owns less than 64 KiB of heap. The
//! joint-torque regressor, in a `Data` built beforehand, allocates nothing.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use stick_slip_manipulator::algorithms::regressor::joint_torque_regressor;
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{Data, DriveInputs, Model, Simulator};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
static LIVE_BYTES: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        LIVE_BYTES.fetch_add(layout.size(), Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE_BYTES.fetch_sub(layout.size(), Ordering::SeqCst);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

// One test function: the counters are process-wide and tests run in threads.
#[test]
fn stepping_allocates_nothing_and_a_simulator_is_small() {
    let model = Model::reference_rrpr();
    let before = LIVE_BYTES.load(Ordering::SeqCst);
    let mut sim = Simulator::new(model).unwrap();
    let heap = LIVE_BYTES.load(Ordering::SeqCst) - before;
    eprintln!("heap of a reference simulator: {heap} bytes");
    assert!(heap < 64 * 1024, "simulator owns {heap} bytes");

    let at = reference_inputs;
    let (a, b, c) = at(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, None).unwrap();
    let saved = sim.state().clone();
    for k in 0..1400 {
        let (a, b, c) = at(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, 1e-3).unwrap();
    }
    sim.clear_transitions();
    let start = ALLOCATIONS.load(Ordering::SeqCst);
    // 1.40–1.50 s: the end of the motion, where joints stick and slip again.
    for k in 1400..1500 {
        let (a, b, c) = at(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, 1e-3).unwrap();
    }
    sim.set_state(&saved).unwrap();
    let (a, b, c) = at(0.0);
    sim.advance(&DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, 1e-3).unwrap();
    let allocations = ALLOCATIONS.load(Ordering::SeqCst) - start;
    assert!(sim.transitions().0.len() >= 2, "the window includes transitions: {:?}", sim.transitions());
    assert_eq!(allocations, 0, "stepping allocated {allocations} times");

    let model = Model::reference_rrpr();
    let mut data = Data::new(&model);
    let start = ALLOCATIONS.load(Ordering::SeqCst);
    joint_torque_regressor(&model, &mut data, &[0.1, -0.2, 0.3, 0.4], &[1.0, -0.5, 0.2, 2.0], &[5.0, 3.0, -1.0, 8.0]);
    let allocations = ALLOCATIONS.load(Ordering::SeqCst) - start;
    assert_eq!(allocations, 0, "the regressor allocated {allocations} times");
}
