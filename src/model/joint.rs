//! Joints: placement and motion, drive, friction; the Denavit–Hartenberg row
//! as one way of writing a placement.

use crate::math::{Mat3, Vec3};

/// Kind of a joint (study section 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the z axis of the joint frame by q_i + offset.
    Revolute,
    /// Translation along the z axis of the joint frame by q_i + offset.
    Prismatic,
}

impl JointKind {
    /// The model-file key and the description of the contact geometry
    /// friction on a joint of this kind needs.
    pub(crate) fn friction_geometry(self) -> (&'static str, &'static str) {
        match self {
            JointKind::Revolute => ("bearings", "its bearing geometry (reaction_point, l_a, l_b, d_a, d_b, d_c)"),
            JointKind::Prismatic => ("slider", "its slider geometry (centre, a, b, c)"),
        }
    }
}

/// A constant rigid placement of a frame in its parent frame:
/// x_parent = rotation · x_child + translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Axes of the child frame resolved in the parent frame (orthonormal,
    /// right-handed).
    pub rotation: Mat3,
    /// Origin of the child frame in the parent frame, m.
    pub translation: Vec3,
}

impl Placement {
    /// The identity placement.
    pub fn identity() -> Placement {
        Placement { rotation: Mat3::identity(), translation: Vec3::zeros() }
    }

    /// `self · other`: `other` given in the child frame of `self`.
    pub fn then(&self, other: &Placement) -> Placement {
        Placement {
            rotation: self.rotation * other.rotation,
            translation: self.translation + self.rotation * other.translation,
        }
    }

    /// A point of the child frame resolved in the parent frame.
    pub fn apply(&self, x: &Vec3) -> Vec3 {
        self.rotation * x + self.translation
    }
}

/// One row of standard (distal) Denavit–Hartenberg parameters:
/// A_i = Rot_z(θ_i) · Trans_z(d_i) · Trans_x(a_i) · Rot_x(α_i), the transform
/// from frame i to frame i−1 (study eq. 3.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// θ for a prismatic joint, the offset θ0 for a revolute one, rad.
    pub theta: f64,
    /// d for a revolute joint, the offset d0 for a prismatic one, m.
    pub d: f64,
    /// Link length a_i, m.
    pub a: f64,
    /// Link twist α_i, rad.
    pub alpha: f64,
}

/// The drive of a joint (study Figs. 4, 5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Drive {
    /// q_i is a kinematic input; the drive supplies whatever force it takes.
    Rigid,
    /// A massless spring with damping and clearance between the drive end q*_i
    /// and the link (eq. 2.1); q*_i is a kinematic input.
    Flexible {
        /// Stiffness k_i > 0, N/m or N·m/rad.
        stiffness: f64,
        /// Damping h_i ≥ 0, N·s/m or N·m·s/rad.
        damping: f64,
        /// Clearance (backlash) Δ_i ≥ 0, m or rad.
        clearance: f64,
    },
    /// The spring of a flexible drive, driven by a motor rotor instead of a
    /// prescribed q*: q* = θ_m/N, the gear force F of (2.1) acts on the link
    /// and F/N back on the rotor, which obeys
    /// J_m·θ̈_m = τ_m − F/N − b_m·θ̇_m − τ_f with the motor torque τ_m an
    /// input (see [`Rotor`]).
    Motor {
        /// Stiffness k_i > 0 of the gear, link side, N/m or N·m/rad.
        stiffness: f64,
        /// Damping h_i ≥ 0 of the gear, link side, N·s/m or N·m·s/rad.
        damping: f64,
        /// Clearance (backlash) Δ_i ≥ 0 of the gear, link side, m or rad.
        clearance: f64,
        /// The motor's rotor and its friction.
        rotor: Rotor,
    },
}

/// The rotor of a motor drive: its inertia, its friction and the gear ratio
/// that turns its angle θ_m into the drive position q* = θ_m/N of (2.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotor {
    /// Gear ratio N > 0: rad of the motor per rad of a revolute joint, per m
    /// of a prismatic one (a ball screw of lead p: 2π/p).
    pub gear_ratio: f64,
    /// Rotor inertia J_m > 0 on the motor side (rotor and gear input), kg·m².
    pub inertia: f64,
    /// Viscous friction b_m ≥ 0 of motor and gear on the motor side, N·m·s/rad.
    pub viscous: f64,
    /// Coulomb friction level τ_c ≥ 0 of motor and gear on the motor side,
    /// N·m, with true stiction: the rotor stays stuck while the net torque
    /// on it is within ±τ_c.
    pub coulomb: f64,
}

/// The spring of a flexible or motor drive: the three coefficients of (2.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSpring {
    /// Stiffness k > 0, N/m or N·m/rad.
    pub stiffness: f64,
    /// Damping h ≥ 0, N·s/m or N·m·s/rad.
    pub damping: f64,
    /// Clearance Δ ≥ 0, m or rad.
    pub clearance: f64,
}

impl Drive {
    /// True for a drive with a spring (flexible or motor): the link's q is
    /// a coordinate with an equation of motion (3.9), not an input.
    pub fn is_flexible(&self) -> bool {
        !matches!(self, Drive::Rigid)
    }

    /// True for a motor drive.
    pub fn is_motor(&self) -> bool {
        matches!(self, Drive::Motor { .. })
    }

    /// The spring of (2.1) of a flexible or motor drive.
    #[inline(always)]
    pub fn spring(&self) -> Option<DriveSpring> {
        match *self {
            Drive::Rigid => None,
            Drive::Flexible { stiffness, damping, clearance } | Drive::Motor { stiffness, damping, clearance, .. } => {
                Some(DriveSpring { stiffness, damping, clearance })
            }
        }
    }

    /// The rotor of a motor drive.
    #[inline(always)]
    pub fn rotor(&self) -> Option<Rotor> {
        match *self {
            Drive::Motor { rotor, .. } => Some(rotor),
            _ => None,
        }
    }

    /// The damping h of a flexible or motor drive, 0 for a rigid one.
    pub fn damping(&self) -> f64 {
        self.spring().map_or(0.0, |s| s.damping)
    }
}

/// Friction coefficients of a joint; their characteristic μ(v) is in
/// [`crate::forces::friction`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionCoefficients {
    /// Kinetic coefficient μ_k (at high sliding velocity), ≥ 0.
    pub mu_kinetic: f64,
    /// Static coefficient μ_s ≥ μ_k, used for the stiction limit (3.16).
    pub mu_static: f64,
    /// Stribeck velocity v_s ≥ 0, m/s or rad/s; 0 means a constant kinetic
    /// coefficient μ_k.
    pub stribeck_velocity: f64,
    /// Viscous coefficient b ≥ 0, N·s/m or N·m·s/rad: a moving joint feels
    /// b·q̇ on top of its dry friction μ(q̇)·L·sgn q̇, independent of the
    /// normal load; 0 (the default) is the study's dry friction alone.
    pub viscous: f64,
}

/// Where the normal loads of a joint come from (study sections 3.1, 3.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactGeometry {
    /// Revolute joint: pin of link i in a sleeve of link i−1 with radial
    /// bearings A, B and thrust bearing C (Fig. 7, eqs. 3.13–3.15).
    Bearings {
        /// Reaction reference point, on the joint axis, in the joint frame
        /// ([`DhJoint`]: in frame i−1), m.
        reaction_point: Vec3,
        /// Distance l_A of bearing A below the reference point, m.
        l_a: f64,
        /// Distance l_B of bearing B above the reference point, m.
        l_b: f64,
        /// Diameter d_A of bearing A, m.
        d_a: f64,
        /// Diameter d_B of bearing B, m.
        d_b: f64,
        /// Diameter d_C of thrust bearing C, m.
        d_c: f64,
    },
    /// Prismatic joint: slider of link i in a slideway of link i−1, contact
    /// at the eight corner points (Fig. 6, eq. 3.11).
    Slider {
        /// Slider centre, a point of link i in its frame, m.
        centre: Vec3,
        /// Slider length a along the axis, m.
        a: f64,
        /// Cross-section b along x of link i's frame, m.
        b: f64,
        /// Cross-section c along y of link i's frame, m.
        c: f64,
    },
}

/// Dry friction in a joint: coefficients and contact geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointFriction {
    /// Coefficients and characteristic.
    pub coefficients: FrictionCoefficients,
    /// Contact geometry that turns reactions into normal loads.
    pub geometry: ContactGeometry,
}

/// A joint of the chain: joint i connects link i−1 to link i.
///
/// Its joint frame sits at a constant [`Placement`] in the frame of link
/// i−1 (frame 0 for joint 1); link i's frame is the joint frame turned by
/// q_i + `offset` about its z axis (revolute) or moved by q_i + `offset`
/// along it (prismatic). Every model source (Denavit–Hartenberg rows, URDF)
/// is written in this form when the model is built, so that every algorithm
/// has one code path. Link i's frame is also the frame in which its inertia
/// is given and its joint reactions are resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Placement of the joint frame in the frame of link i−1.
    pub placement: Placement,
    /// Constant part of the motion: θ0 of a Denavit–Hartenberg revolute
    /// joint, d0 of a prismatic one, 0 for URDF joints; rad or m.
    pub offset: f64,
    /// Rigid or flexible drive.
    pub drive: Drive,
    /// Dry friction, if modelled. The bearing reference point lies on the
    /// joint axis (x = y = 0 of the joint frame); the slider centre is a
    /// point of link i, in its frame.
    pub friction: Option<JointFriction>,
    /// Axes of link i's frame resolved in the frame the user described link
    /// i in: identity for Denavit–Hartenberg joints and for URDF joints whose
    /// axis is +z; for another URDF axis, the rotation that took z to it.
    /// Reported reactions are turned by it into the user's frame.
    pub reported_axes: Mat3,
}

/// A joint as a Denavit–Hartenberg model file writes it: its row, its drive
/// and its friction with the contact geometry in the study's frames (the
/// bearing reference point in frame i−1, the slider centre in frame i).
/// [`Model::from_dh`](crate::model::Model::from_dh) converts a chain of them
/// into [`Joint`]s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhJoint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Denavit–Hartenberg row with the constant offsets.
    pub dh: DhRow,
    /// Rigid or flexible drive.
    pub drive: Drive,
    /// Dry friction, if modelled.
    pub friction: Option<JointFriction>,
}
