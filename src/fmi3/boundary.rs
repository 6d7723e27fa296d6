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

use super::instance::{elements, no_variables_of, Held, Instance3, Modes};
use crate::fmi::description::{Causality, Quantity, Type3, Variable, Variable3};
use crate::fmi::logger::{Category, Logger};
use crate::fmi::status::{Fault, Outcome, Status};
use crate::stepper::State;
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

/// The values at a sub-step, for the calls from the intermediate-update
/// callback.
pub(crate) struct Frame {
    time: f64,
    vars: Arc<[Variable3]>,
    scalars: Arc<[Variable]>,
    /// By FMI 2.0 value reference: the outputs and the drive inputs at `time`.
    values: Vec<f64>,
    /// Which of `values` are there (outputs and inputs).
    available: Vec<bool>,
    /// Which inputs the master set in this callback.
    set: Vec<bool>,
    /// The instance's logger, as at the start of the step.
    logger: Logger,
}

/// The handle's frame and callback flag, as `fmi3DoStep` uses them.
pub(crate) struct Reentry<'a> {
    in_update: &'a Cell<bool>,
    frame: &'a RefCell<Frame>,
}

impl Reentry<'_> {
    /// Fills the frame with the outputs of `state` and the held inputs.
    pub(crate) fn fill(&self, time: f64, scalars: &[Variable], state: &State, held: &Held) {
        let mut f = self.frame.borrow_mut();
        f.time = time;
        let held_values = |q: Quantity| match q {
            Quantity::Input(field, j) => Some(held.drive[field.index()][j]),
            Quantity::MotorTorque(j) => Some(held.torques[0][j]),
            _ => None,
        };
        for (i, v) in scalars.iter().enumerate() {
            let value = match v.quantity {
                Quantity::Output(o) => Some(o.value(state)),
                q => held_values(q),
            };
            f.available[i] = value.is_some();
            f.values[i] = value.unwrap_or(f64::NAN);
            f.set[i] = false;
        }
    }

    pub(crate) fn enter(&self) {
        self.in_update.set(true);
    }

    pub(crate) fn leave(&self) {
        self.in_update.set(false);
    }

    /// Puts the inputs the master set in the last callback into `held`;
    /// true if there were any.
    pub(crate) fn take_inputs(&self, scalars: &[Variable], held: &mut Held) -> bool {
        let f = self.frame.borrow();
        let mut any = false;
        for (i, v) in scalars.iter().enumerate() {
            if f.set[i] {
                if let Some(x) = held.input(v.quantity) {
                    *x = f.values[i];
                    any = true;
                }
            }
        }
        any
    }
}

impl Frame {
    /// fmi3GetFloat64 / fmi3GetInt32 from the callback.
    pub(crate) fn get(&self, vrs: &[u32], ty: Type3, values: &mut [f64]) -> Outcome {
        let elements = elements(&self.vars, vrs, ty, values.len())?;
        for (e, out) in elements.iter().zip(values.iter_mut()) {
            *out = match e {
                None => self.time,
                Some(vr) if self.available[*vr as usize] => self.values[*vr as usize],
                Some(vr) => {
                    return Err(Fault::error(format!(
                        "FMI 2.0 element {vr} of the value references asked for is not available in Intermediate \
                         Update Mode: only the outputs, the drive inputs and `time` are"
                    )))
                }
            };
        }
        Ok(Status::Ok)
    }

    /// fmi3SetFloat64 from the callback: the drive inputs only (they are
    /// declared `intermediateUpdate`).
    pub(crate) fn set(&mut self, scalars: &[Variable], vrs: &[u32], values: &[f64]) -> Outcome {
        let elements = elements(&self.vars, vrs, Type3::Float64, values.len())?;
        for (e, x) in elements.iter().zip(values) {
            let Some(vr) = e else {
                return Err(Fault::error("`time` cannot be set"));
            };
            let v = &scalars[*vr as usize];
            if v.causality != Causality::Input {
                return Err(Fault::error(format!(
                    "`{}` cannot be set in Intermediate Update Mode: only the drive inputs can",
                    v.name
                )));
            }
            if !x.is_finite() {
                return Err(Fault::error(format!("`{}` = {x} is not finite", v.name)));
            }
        }
        for (e, x) in elements.iter().zip(values) {
            let vr = e.unwrap_or(0) as usize;
            self.values[vr] = *x;
            self.set[vr] = true;
        }
        Ok(Status::Ok)
    }

    /// The FMI 2.0 variables (for the setter).
    pub(crate) fn scalars(&self) -> Arc<[Variable]> {
        Arc::clone(&self.scalars)
    }

    /// A getter or setter of another type from the callback.
    pub(crate) fn no_variables_of(&self, kind: &str, vrs: &[u32]) -> Outcome {
        no_variables_of(&self.vars, kind, vrs)
    }
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

fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("panic")
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
