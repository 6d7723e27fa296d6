//! What the calls from inside the master's intermediate-update callback see
//! (they run while `fmi3DoStep` holds the instance): the [`Frame`] of the
//! outputs and held drive inputs at that sub-step, and the inputs the master
//! sets there; [`Reentry`] is how `fmi3DoStep` fills and reads it.

use super::values::{elements, no_variables_of, Held};
use crate::fmi::description::{Causality, Quantity, Type3, Variable, Variable3};
use crate::fmi::logger::Logger;
use crate::fmi::status::{Fault, Outcome, Status};
use crate::stepper::State;
use std::cell::{Cell, RefCell};
use std::sync::Arc;

/// The values at a sub-step, for the calls from the intermediate-update
/// callback.
pub(crate) struct Frame {
    pub(crate) time: f64,
    pub(crate) vars: Arc<[Variable3]>,
    pub(crate) scalars: Arc<[Variable]>,
    /// By FMI 2.0 value reference: the outputs and the drive inputs at `time`.
    pub(crate) values: Vec<f64>,
    /// Which of `values` are there (outputs and inputs).
    pub(crate) available: Vec<bool>,
    /// Which inputs the master set in this callback.
    pub(crate) set: Vec<bool>,
    /// The instance's logger, as at the start of the step.
    pub(crate) logger: Logger,
}

/// The handle's frame and callback flag, as `fmi3DoStep` uses them.
pub(crate) struct Reentry<'a> {
    pub(crate) in_update: &'a Cell<bool>,
    pub(crate) frame: &'a RefCell<Frame>,
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
