//! The C boundary of the FMI 3.0 layer: the handle behind an `fmi3Instance`
//! and the wrapper every exported function body runs in (a panic becomes
//! fmi3Error and the error state, as in [`crate::fmi`]'s boundary).
//!
//! The master's intermediate-update callback runs inside `fmi3DoStep`, which
//! holds the instance; the calls it makes back into the FMU (fmi3GetFloat64
//! of the outputs, fmi3SetFloat64 of the drive inputs) must not touch the
//! instance. They see only the handle's [`Frame`]: the outputs and held
//! inputs at that sub-step, and the inputs the master sets there. The frame
//! and the flag that says a callback runs live beside the instance, not in
//! it, so no reference to the instance is made while one is held.

use super::frame::{Frame, Reentry};
use super::instance::{Instance3, Modes};
use crate::fmi::boundary::panic_message;
use crate::fmi::logger::{Category, Logger};
use crate::fmi::status::{Fault, Outcome, Status};
use fmi_sys::fmi3::{fmi3Instance, fmi3Status};
use std::cell::{Cell, RefCell, UnsafeCell};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

const INSTANCE_MAGIC: u64 = u64::from_le_bytes(*b"SSMins3\0");

/// What an `fmi3Instance` points to.
#[repr(C)]
struct Handle {
    magic: u64,
    /// True while the master's intermediate-update callback runs.
    in_update: Cell<bool>,
    frame: RefCell<Frame>,
    instance: UnsafeCell<Instance3>,
}

/// Hands `instance` to C.
pub(crate) fn into_instance(instance: Instance3) -> fmi3Instance {
    let n = instance.scalars.len();
    let frame = Frame {
        time: 0.0,
        vars: Arc::clone(&instance.vars),
        scalars: Arc::clone(&instance.scalars),
        values: vec![f64::NAN; n],
        available: vec![false; n],
        set: vec![false; n],
        logger: instance.inner.logger.clone(),
    };
    let handle = Handle {
        magic: INSTANCE_MAGIC,
        in_update: Cell::new(false),
        frame: RefCell::new(frame),
        instance: UnsafeCell::new(instance),
    };
    Box::into_raw(Box::new(handle)).cast()
}

/// The handle behind `c`, if `c` is one.
///
/// # Safety
/// `c` is null or a pointer the master got from fmi3InstantiateCoSimulation
/// and has not freed.
unsafe fn handle<'a>(c: fmi3Instance) -> Option<&'a Handle> {
    let h = c.cast::<Handle>();
    if h.is_null() || !h.is_aligned() {
        return None;
    }
    // SAFETY: non-null, aligned and readable by contract; the magic number
    // says it is a live handle made by into_instance.
    (unsafe { std::ptr::addr_of!((*h).magic).read() } == INSTANCE_MAGIC).then(|| unsafe { &*h })
}

/// fmi3FreeInstance. Not from inside the callback.
///
/// # Safety
/// As for [`handle`]; `c` is not used again.
pub(crate) unsafe fn free_instance(c: fmi3Instance) {
    // SAFETY: see the function's contract.
    let Some(h) = (unsafe { handle(c) }) else { return };
    if h.in_update.get() {
        h.frame.borrow().logger.log(
            Status::Error,
            Category::StatusError,
            "fmi3FreeInstance: not allowed in Intermediate Update Mode (inside fmi3DoStep); the instance is kept",
        );
        return;
    }
    let h = c.cast::<Handle>();
    // SAFETY: `h` came from Box::into_raw in into_instance and is not in use.
    unsafe {
        std::ptr::addr_of_mut!((*h).magic).write(0);
        drop(Box::from_raw(h));
    }
}

fn to_fmi3(status: Status) -> fmi3Status {
    status.to_fmi() as fmi3Status
}

/// Logs a failed call as "`function`: message" and returns its status.
fn report(logger: &Logger, function: &str, fault: Fault) -> Status {
    logger.log(fault.status, Category::of_status(fault.status), &format!("{function}: {}", fault.message));
    fault.status
}

/// Runs `body` on the instance behind `c` if its mode is in `allowed`;
/// refuses the call from inside the intermediate-update callback.
///
/// # Safety
/// As for [`handle`].
pub(crate) unsafe fn with_instance(
    c: fmi3Instance,
    function: &'static str,
    allowed: Modes,
    body: impl FnOnce(&mut Instance3, &Reentry<'_>) -> Outcome,
) -> fmi3Status {
    // SAFETY: see the function's contract.
    unsafe { with_values(c, function, allowed, body, |_| Err(Fault::error(not_in_update()))) }
}

fn not_in_update() -> String {
    "illegal call sequence: not allowed in Intermediate Update Mode (inside the intermediateUpdate callback of \
     fmi3DoStep)"
        .into()
}

/// As [`with_instance`], but from inside the intermediate-update callback
/// `in_update` runs on the frame instead.
///
/// # Safety
/// As for [`handle`].
pub(crate) unsafe fn with_values(
    c: fmi3Instance,
    function: &'static str,
    allowed: Modes,
    body: impl FnOnce(&mut Instance3, &Reentry<'_>) -> Outcome,
    in_update: impl FnOnce(&mut Frame) -> Outcome,
) -> fmi3Status {
    // SAFETY: see the function's contract. Without an instance there is no
    // logger to tell.
    let Some(h) = (unsafe { handle(c) }) else { return to_fmi3(Status::Error) };
    if h.in_update.get() {
        let Ok(mut frame) = h.frame.try_borrow_mut() else { return to_fmi3(Status::Error) };
        let run = catch_unwind(AssertUnwindSafe(|| match in_update(&mut frame) {
            Ok(status) => status,
            Err(fault) => report(&frame.logger, function, fault),
        }));
        return to_fmi3(run.unwrap_or(Status::Error));
    }
    // SAFETY: no callback runs, so nothing else refers to the instance (the
    // master calls an instance from one thread at a time).
    let instance = unsafe { &mut *h.instance.get() };
    let reentry = Reentry { in_update: &h.in_update, frame: &h.frame };
    let run = catch_unwind(AssertUnwindSafe(|| {
        if let Ok(mut frame) = h.frame.try_borrow_mut() {
            frame.logger = instance.inner.logger.clone();
        }
        match instance.check_mode(allowed).and_then(|()| body(instance, &reentry)) {
            Ok(status) => status,
            Err(fault) => report(&instance.inner.logger, function, fault),
        }
    }));
    h.in_update.set(false);
    match run {
        Ok(status) => to_fmi3(status),
        Err(payload) => {
            let reason = panic_message(payload.as_ref());
            let _ = catch_unwind(AssertUnwindSafe(|| instance.inner.fail(function, reason)));
            to_fmi3(Status::Error)
        }
    }
}
