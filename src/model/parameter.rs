//! Checked access to the tunable parameters of a model.

use super::range::{check_value, Range};
use super::{ContactGeometry, Drive, Joint, Link, Model};
use crate::error::ModelError;

/// A scalar parameter of one joint (or of the link it moves) that may be
/// changed between communication steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Parameter {
    /// Drive stiffness k, flexible drives only.
    Stiffness,
    /// Drive damping h, flexible drives only.
    Damping,
    /// Drive clearance Δ, flexible drives only.
    Clearance,
    /// Kinetic friction coefficient μ_k.
    MuKinetic,
    /// Static friction coefficient μ_s.
    MuStatic,
    /// Stribeck velocity v_s.
    StribeckVelocity,
    /// Viscous friction coefficient b of the joint.
    Viscous,
    /// Slider length a (prismatic joints).
    SliderA,
    /// Slider cross-section b (prismatic joints).
    SliderB,
    /// Slider cross-section c (prismatic joints).
    SliderC,
    /// Diameter of radial bearing A (revolute joints).
    DiameterA,
    /// Diameter of radial bearing B (revolute joints).
    DiameterB,
    /// Diameter of thrust bearing C (revolute joints).
    DiameterC,
    /// Distance l_A of bearing A from the reaction point (revolute joints).
    LengthA,
    /// Distance l_B of bearing B from the reaction point (revolute joints).
    LengthB,
    /// Mass of the link moved by the joint.
    Mass,
    /// Gear ratio N of a motor drive (fixed once a simulation runs).
    GearRatio,
    /// Rotor inertia J_m of a motor drive.
    RotorInertia,
    /// Viscous friction b_m of a motor drive.
    MotorViscous,
    /// Coulomb friction level τ_c of a motor drive.
    MotorCoulomb,
}

impl Parameter {
    /// Every parameter, in a fixed order.
    pub const ALL: [Parameter; 20] = [
        Parameter::Stiffness,
        Parameter::Damping,
        Parameter::Clearance,
        Parameter::MuKinetic,
        Parameter::MuStatic,
        Parameter::StribeckVelocity,
        Parameter::Viscous,
        Parameter::SliderA,
        Parameter::SliderB,
        Parameter::SliderC,
        Parameter::DiameterA,
        Parameter::DiameterB,
        Parameter::DiameterC,
        Parameter::LengthA,
        Parameter::LengthB,
        Parameter::Mass,
        Parameter::GearRatio,
        Parameter::RotorInertia,
        Parameter::MotorViscous,
        Parameter::MotorCoulomb,
    ];

    /// The short name used in model files and FMU variable names.
    pub fn name(self) -> &'static str {
        match self {
            Parameter::Stiffness => "k",
            Parameter::Damping => "h",
            Parameter::Clearance => "Delta",
            Parameter::MuKinetic => "mu_k",
            Parameter::MuStatic => "mu_s",
            Parameter::StribeckVelocity => "v_s",
            Parameter::Viscous => "b_v",
            Parameter::SliderA => "slider_a",
            Parameter::SliderB => "slider_b",
            Parameter::SliderC => "slider_c",
            Parameter::DiameterA => "d_A",
            Parameter::DiameterB => "d_B",
            Parameter::DiameterC => "d_C",
            Parameter::LengthA => "l_A",
            Parameter::LengthB => "l_B",
            Parameter::Mass => "m",
            Parameter::GearRatio => "gear_ratio",
            Parameter::RotorInertia => "J_m",
            Parameter::MotorViscous => "b_m",
            Parameter::MotorCoulomb => "tau_c",
        }
    }

    /// The physical range of the parameter: checked by
    /// [`Model::set_parameter`] and in model files, declared as `min`/`max`
    /// in the FMU's modelDescription.
    pub fn range(self) -> Range {
        match self {
            Parameter::Stiffness => Range::STIFFNESS,
            Parameter::Damping => Range::DAMPING,
            Parameter::Clearance => Range::CLEARANCE,
            Parameter::MuKinetic | Parameter::MuStatic => Range::FRICTION_COEFFICIENT,
            Parameter::StribeckVelocity => Range::STRIBECK_VELOCITY,
            Parameter::Viscous => Range::JOINT_VISCOUS,
            Parameter::SliderA => Range::SLIDER_LENGTH,
            Parameter::SliderB
            | Parameter::SliderC
            | Parameter::DiameterA
            | Parameter::DiameterB
            | Parameter::DiameterC
            | Parameter::LengthA
            | Parameter::LengthB => Range::CONTACT_SIZE,
            Parameter::Mass => Range::MASS,
            Parameter::GearRatio => Range::GEAR_RATIO,
            Parameter::RotorInertia => Range::ROTOR_INERTIA,
            Parameter::MotorViscous => Range::MOTOR_VISCOUS,
            Parameter::MotorCoulomb => Range::MOTOR_COULOMB,
        }
    }

    /// True for a parameter that may change between communication steps;
    /// false for one fixed once a simulation runs (the gear ratio: a new N
    /// would move the drive position q* = θ_m/N by a jump).
    pub fn is_tunable(self) -> bool {
        self != Parameter::GearRatio
    }
}

impl Model {
    /// Where parameter `p` of joint `joint` (0-based) is stored, or `None`
    /// if the joint does not have it (a rigid drive has no stiffness, a
    /// revolute joint no slider …).
    fn parameter_slot(&mut self, p: Parameter, joint: usize) -> Option<&mut f64> {
        slot(self.joints.get_mut(joint)?, self.links.get_mut(joint)?, p)
    }

    /// True if `other` is the same chain as this model up to the values of
    /// its tunable parameters and integrator settings: everything else (DH
    /// rows, drive and contact kinds, inertias, gravity, end point) equal.
    pub fn has_layout_of(&self, other: &Model) -> bool {
        if self.nq() != other.nq() {
            return false;
        }
        let mut probe = other.clone();
        for joint in 0..self.nq() {
            for p in Parameter::ALL {
                if let (Some(slot), Some(value)) = (probe.parameter_slot(p, joint), self.parameter(p, joint)) {
                    *slot = value;
                }
            }
        }
        probe.integrator = self.integrator;
        probe == *self
    }

    /// True if a flexible drive has a clearance Δ > 0 (so that δ of (2.1)
    /// can switch).
    #[inline]
    pub fn has_clearance(&self) -> bool {
        self.joints.iter().any(|j| j.drive.spring().is_some_and(|s| s.clearance > 0.0))
    }

    /// True if some flexible drive has both a clearance and damping, so that
    /// its flank can release (see [`crate::forces::drive`]).
    pub fn has_damped_clearance(&self) -> bool {
        self.joints.iter().any(|j| j.drive.spring().is_some_and(|s| s.clearance > 0.0 && s.damping != 0.0))
    }

    /// The joints (0-based) with a motor drive, in chain order: rotor r of
    /// the state's coordinates belongs to joint `motor_joints()[r]`.
    pub fn motor_joints(&self) -> Vec<usize> {
        (0..self.nq()).filter(|&i| self.joints[i].drive.is_motor()).collect()
    }

    /// Number of generalized coordinates: the n joint coordinates q, then
    /// the angle θ_m of each motor drive's rotor.
    pub fn n_coordinates(&self) -> usize {
        self.nq() + self.joints.iter().filter(|j| j.drive.is_motor()).count()
    }

    /// True if joint `joint` (0-based) has parameter `p`.
    pub fn has_parameter(&self, p: Parameter, joint: usize) -> bool {
        self.parameter(p, joint).is_some()
    }

    /// Value of parameter `p` of joint `joint` (0-based), if it has one.
    pub fn parameter(&self, p: Parameter, joint: usize) -> Option<f64> {
        // One lookup for reads and writes: joint and link are small copies.
        let (mut j, mut link) = (*self.joints.get(joint)?, *self.links.get(joint)?);
        slot(&mut j, &mut link, p).copied()
    }

    /// Sets parameter `p` of joint `joint` (0-based) after checking the value's
    /// own range. Relations between parameters (μ_s ≥ μ_k, …) are checked by
    /// [`Model::validate`], since a caller sets them one at a time.
    pub fn set_parameter(&mut self, p: Parameter, joint: usize, value: f64) -> Result<(), ModelError> {
        let field = format!("{}[{}]", p.name(), joint + 1);
        let n = self.nq();
        if joint >= n {
            return Err(ModelError::Invalid { field, reason: format!("the model has {n} joints") });
        }
        let Some(slot) = self.parameter_slot(p, joint) else {
            return Err(ModelError::Invalid { field, reason: "this joint has no such parameter".into() });
        };
        check_value(&field, value, p.range())?;
        *slot = value;
        Ok(())
    }

    /// Sets the parameter a `setting` `NAME[i]=VALUE` names by its FMU
    /// variable name (`m[3]=8.0`, `mu_k[1]=0.2`; i the joint number, 1…n),
    /// checked as [`Model::set_parameter`] checks it.
    pub fn apply_setting(&mut self, setting: &str) -> Result<(), ModelError> {
        let invalid = |reason: String| ModelError::Invalid { field: setting.to_string(), reason };
        let form = || invalid("expected NAME[i]=VALUE, a parameter by its FMU name (`m[3]=8.0`)".into());
        let (name, value) = setting.split_once('=').ok_or_else(form)?;
        let (stem, index) = name.trim().strip_suffix(']').and_then(|n| n.split_once('[')).ok_or_else(form)?;
        let parameter = Parameter::ALL.iter().copied().find(|p| p.name() == stem).ok_or_else(|| {
            let names: Vec<&str> = Parameter::ALL.iter().map(|p| p.name()).collect();
            invalid(format!("no parameter is named `{stem}` (the names: {})", names.join(", ")))
        })?;
        let joint = index.trim().parse::<usize>().ok().filter(|&i| i >= 1);
        let joint = joint.ok_or_else(|| invalid(format!("`{index}` is not a joint number (1…{})", self.nq())))?;
        let value = value.trim().parse::<f64>().map_err(|_| invalid(format!("`{}` is not a number", value.trim())))?;
        self.set_parameter(parameter, joint - 1, value)
    }
}

/// Where parameter `p` of joint `j` and the link it moves is stored.
fn slot<'a>(j: &'a mut Joint, link: &'a mut Link, p: Parameter) -> Option<&'a mut f64> {
    if p == Parameter::Mass {
        // A massless link (a URDF link without mass) has no tunable mass.
        return (link.mass > 0.0).then_some(&mut link.mass);
    }
    match (&mut j.drive, p) {
        (Drive::Flexible { stiffness, .. } | Drive::Motor { stiffness, .. }, Parameter::Stiffness) => {
            return Some(stiffness)
        }
        (Drive::Flexible { damping, .. } | Drive::Motor { damping, .. }, Parameter::Damping) => return Some(damping),
        (Drive::Flexible { clearance, .. } | Drive::Motor { clearance, .. }, Parameter::Clearance) => {
            return Some(clearance)
        }
        (Drive::Motor { rotor, .. }, Parameter::GearRatio) => return Some(&mut rotor.gear_ratio),
        (Drive::Motor { rotor, .. }, Parameter::RotorInertia) => return Some(&mut rotor.inertia),
        (Drive::Motor { rotor, .. }, Parameter::MotorViscous) => return Some(&mut rotor.viscous),
        (Drive::Motor { rotor, .. }, Parameter::MotorCoulomb) => return Some(&mut rotor.coulomb),
        _ => {}
    }
    let friction = j.friction.as_mut()?;
    let c = &mut friction.coefficients;
    match (p, &mut friction.geometry) {
        (Parameter::MuKinetic, _) => Some(&mut c.mu_kinetic),
        (Parameter::MuStatic, _) => Some(&mut c.mu_static),
        (Parameter::StribeckVelocity, _) => Some(&mut c.stribeck_velocity),
        (Parameter::Viscous, _) => Some(&mut c.viscous),
        (Parameter::SliderA, ContactGeometry::Slider { a, .. }) => Some(a),
        (Parameter::SliderB, ContactGeometry::Slider { b, .. }) => Some(b),
        (Parameter::SliderC, ContactGeometry::Slider { c, .. }) => Some(c),
        (Parameter::DiameterA, ContactGeometry::Bearings { d_a, .. }) => Some(d_a),
        (Parameter::DiameterB, ContactGeometry::Bearings { d_b, .. }) => Some(d_b),
        (Parameter::DiameterC, ContactGeometry::Bearings { d_c, .. }) => Some(d_c),
        (Parameter::LengthA, ContactGeometry::Bearings { l_a, .. }) => Some(l_a),
        (Parameter::LengthB, ContactGeometry::Bearings { l_b, .. }) => Some(l_b),
        _ => None,
    }
}
