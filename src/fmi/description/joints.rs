//! How the variables name a joint and which units its quantities carry.

use crate::model::{Drive, JointKind, Model};

/// Units of the joint-space quantities of a joint kind.
pub(crate) struct JointUnits {
    pub(crate) coordinate: &'static str,
    pub(crate) rate: &'static str,
    pub(crate) acceleration: &'static str,
    pub(crate) force: &'static str,
    pub(crate) stiffness: &'static str,
    pub(crate) damping: &'static str,
}

pub(crate) fn joint_units(kind: JointKind) -> JointUnits {
    match kind {
        JointKind::Revolute => JointUnits {
            coordinate: "rad",
            rate: "rad/s",
            acceleration: "rad/s2",
            force: "N.m",
            stiffness: "N.m/rad",
            damping: "N.m.s/rad",
        },
        JointKind::Prismatic => JointUnits {
            coordinate: "m",
            rate: "m/s",
            acceleration: "m/s2",
            force: "N",
            stiffness: "N/m",
            damping: "N.s/m",
        },
    }
}

/// "joint 3 (prismatic, flexible drive)".
pub(super) fn joint_label(model: &Model, j: usize) -> String {
    let joint = &model.joints[j];
    let kind = match joint.kind {
        JointKind::Revolute => "revolute",
        JointKind::Prismatic => "prismatic",
    };
    let drive = match joint.drive {
        Drive::Rigid => "rigid",
        Drive::Flexible { .. } => "flexible",
        Drive::Motor { .. } => "motor",
    };
    match &model.joint_names[j] {
        Some(name) => format!("joint {} (`{name}`, {kind}, {drive} drive)", j + 1),
        None => format!("joint {} ({kind}, {drive} drive)", j + 1),
    }
}
