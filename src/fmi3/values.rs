//! The FMI 3.0 arrays' elements: value references of the arrays expanded to
//! the FMI 2.0 scalars they hold, with their types and counts checked; and
//! the drive inputs held at a sub-step.

use crate::fmi::description::{InputField, Quantity, Type3, Variable3};
use crate::fmi::status::{Fault, Outcome, Status};
use crate::stepper::{DriveInputs, MotorTorques, SubStep};

/// An element of an array getter or setter: the time, or an FMI 2.0 scalar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Slot {
    Time,
    Scalar(u32),
}

/// The drive inputs and motor torques at a sub-step, per joint.
pub(crate) struct Held {
    pub(crate) drive: [Vec<f64>; 3],
    pub(crate) torques: [Vec<f64>; 3],
}

impl Held {
    pub(crate) fn new(n: usize) -> Held {
        Held { drive: std::array::from_fn(|_| vec![0.0; n]), torques: std::array::from_fn(|_| vec![0.0; n]) }
    }

    pub(crate) fn take(&mut self, step: &SubStep<'_>) {
        let [x, xd, xdd] = &mut self.drive;
        step.held_drive_inputs([x, xd, xdd]);
        let [u, ud, udd] = &mut self.torques;
        step.held_motor_torques([u, ud, udd]);
    }

    pub(crate) fn drive(&self) -> DriveInputs<'_> {
        DriveInputs { q_star: &self.drive[0], qd_star: &self.drive[1], qdd_star: &self.drive[2] }
    }

    pub(crate) fn torques(&self) -> MotorTorques<'_> {
        MotorTorques { tau_m: &self.torques[0], tau_m_rate: &self.torques[1], tau_m_accel: &self.torques[2] }
    }

    /// The held value of an input quantity, or None for other quantities.
    pub(crate) fn input(&mut self, q: Quantity) -> Option<&mut f64> {
        match q {
            Quantity::Input(field, j) => Some(&mut self.drive[field_index(field)][j]),
            Quantity::MotorTorque(j) => Some(&mut self.torques[0][j]),
            _ => None,
        }
    }
}

fn field_index(field: InputField) -> usize {
    field.index()
}

/// The FMI 3.0 variable `vr` of `vars`.
pub(crate) fn variable(vars: &[Variable3], vr: u32) -> Result<&Variable3, Fault> {
    vars.get(vr as usize).ok_or_else(|| {
        Fault::error(format!("unknown value reference {vr} (this FMU has 0 to {})", vars.len().saturating_sub(1)))
    })
}

/// The elements of `vrs` in `vars`, of type `ty` each, `n_values` in all.
pub(crate) fn slots(vars: &[Variable3], vrs: &[u32], ty: Type3, n_values: usize) -> Result<Vec<Slot>, Fault> {
    let mut out = Vec::with_capacity(n_values);
    for vr in vrs {
        let v = variable(vars, *vr)?;
        if v.ty != ty {
            return Err(Fault::error(format!(
                "`{}` (value reference {vr}) is a {:?} variable, not {ty:?}",
                v.name, v.ty
            )));
        }
        if v.elements.is_empty() {
            out.push(Slot::Time);
        } else {
            out.extend(v.elements.iter().map(|e| Slot::Scalar(*e)));
        }
    }
    if out.len() != n_values {
        return Err(Fault::error(format!(
            "nValues = {n_values}, but the {} value references have {} elements",
            vrs.len(),
            out.len()
        )));
    }
    Ok(out)
}

/// The elements of `vrs` in `vars` with their FMI 3.0 type checked, as
/// FMI 2.0 value references (`time` as `None`); for the frame's getters.
pub(crate) fn elements(vars: &[Variable3], vrs: &[u32], ty: Type3, n_values: usize) -> Result<Vec<Option<u32>>, Fault> {
    Ok(slots(vars, vrs, ty, n_values)?
        .into_iter()
        .map(|s| match s {
            Slot::Time => None,
            Slot::Scalar(vr) => Some(vr),
        })
        .collect())
}

pub(crate) fn scalar_slots(slots: Vec<Slot>) -> Vec<u32> {
    slots.into_iter().filter_map(|s| if let Slot::Scalar(vr) = s { Some(vr) } else { None }).collect()
}

/// A getter or setter of a type the FMU has no variable of.
pub(crate) fn no_variables_of(vars: &[Variable3], kind: &str, vrs: &[u32]) -> Outcome {
    match vrs.first() {
        None => Ok(Status::Ok),
        Some(vr) => {
            let what = variable(vars, *vr)
                .map(|v| format!("`{}` (value reference {vr}) is a {:?} variable", v.name, v.ty))
                .unwrap_or_else(|f| f.message);
            Err(Fault::error(format!("the FMU has no {kind} variables ({what})")))
        }
    }
}
