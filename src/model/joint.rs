//! Joints: Denavit–Hartenberg row, drive, friction.

use crate::math::Vec3;

/// Kind of a joint (study section 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about z_{i−1}; the joint variable enters θ_i = q_i + θ0_i.
    Revolute,
    /// Translation along z_{i−1}; the joint variable enters d_i = q_i + d0_i.
    Prismatic,
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
    /// and the link (eq. 2.1).
    Flexible {
        /// Stiffness k_i > 0, N/m or N·m/rad.
        stiffness: f64,
        /// Damping h_i ≥ 0, N·s/m or N·m·s/rad.
        damping: f64,
        /// Clearance (backlash) Δ_i ≥ 0, m or rad.
        clearance: f64,
    },
}

impl Drive {
    /// True for a flexible drive.
    pub fn is_flexible(&self) -> bool {
        matches!(self, Drive::Flexible { .. })
    }

    /// The damping h of a flexible drive, 0 for a rigid one.
    pub fn damping(&self) -> f64 {
        match self {
            Drive::Flexible { damping, .. } => *damping,
            Drive::Rigid => 0.0,
        }
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
}

/// Where the normal loads of a joint come from (study sections 3.1, 3.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactGeometry {
    /// Revolute joint: pin of link i in a sleeve of link i−1 with radial
    /// bearings A, B and thrust bearing C (Fig. 7, eqs. 3.13–3.15).
    Bearings {
        /// Reaction reference point, on the joint axis, in frame i−1, m.
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
        /// Slider centre, in frame i, m.
        centre: Vec3,
        /// Slider length a along the axis, m.
        a: f64,
        /// Cross-section b along x of the joint frame, m.
        b: f64,
        /// Cross-section c along y of the joint frame, m.
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

/// A joint of the chain: joint i connects link i−1 to link i and moves about
/// or along z_{i−1}.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Denavit–Hartenberg row with the constant offsets.
    pub dh: DhRow,
    /// Rigid or flexible drive.
    pub drive: Drive,
    /// Dry friction, if modelled.
    pub friction: Option<JointFriction>,
}
