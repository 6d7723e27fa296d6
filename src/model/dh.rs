//! Standard Denavit–Hartenberg rows written as joint placements.
//!
//! The study's transform A_i = Rot_z(θ_i)·Trans_z(d_i)·Trans_x(a_i)·Rot_x(α_i)
//! (eq. 3.1) splits into a motion and two constant parts. Rot_z and Trans_z
//! commute, so the joint variable's factor (Rot_z(θ0 + q) of a revolute
//! joint, Trans_z(d0 + q) of a prismatic one) can be taken rightmost of the
//! leading pair, and the trailing Trans_x(a_i)·Rot_x(α_i) is constant:
//!
//! ```text
//! A_i = P_i · M_i(q_i) · T_i,   P_i = Trans_z(d_i) (revolute) or Rot_z(θ_i) (prismatic),
//!                               T_i = Trans_x(a_i)·Rot_x(α_i).
//! ```
//!
//! The engine's link frame i is the frame after the motion, P_1·M_1…P_i·M_i
//! with T_{i−1} moved into the next placement: joint i's placement is
//! T_{i−1}·P_i. The study's frame i is the engine's link frame i turned by
//! T_i, so link data, the slider centre and the end point given in frame i
//! are carried through T_i, and a bearing reference point given on z_{i−1}
//! in frame i−1 lands on the joint axis at height z − d_i.

use super::manipulator::validate_link;
use super::range::{check_value, check_vec, Range};
use super::{
    ContactGeometry, DhJoint, DhRow, IntegratorSettings, Joint, JointFriction, JointKind, Link, Model, Placement,
};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};

/// T_i = Trans_x(a_i)·Rot_x(α_i): the study's frame i in the engine's link frame i.
pub fn trailing_placement(row: &DhRow) -> Placement {
    let (sa, ca) = row.alpha.sin_cos();
    Placement { rotation: Mat3::new(1.0, 0.0, 0.0, 0.0, ca, -sa, 0.0, sa, ca), translation: Vec3::new(row.a, 0.0, 0.0) }
}

/// P_i: Trans_z(d_i) for a revolute joint, Rot_z(θ_i) for a prismatic one.
fn leading_placement(kind: JointKind, row: &DhRow) -> Placement {
    match kind {
        JointKind::Revolute => Placement { rotation: Mat3::identity(), translation: Vec3::new(0.0, 0.0, row.d) },
        JointKind::Prismatic => {
            let (st, ct) = row.theta.sin_cos();
            Placement { rotation: Mat3::new(ct, -st, 0.0, st, ct, 0.0, 0.0, 0.0, 1.0), translation: Vec3::zeros() }
        }
    }
}

/// The DH quantities checked before the conversion, with the field names of
/// the DH model file.
fn check_dh_joint(number: usize, joint: &DhJoint) -> Result<(), ModelError> {
    let f = |name: &str| format!("joint[{number}].{name}");
    check_value(&f("theta"), joint.dh.theta, Range::GEOMETRY)?;
    check_value(&f("d"), joint.dh.d, Range::GEOMETRY)?;
    check_value(&f("a"), joint.dh.a, Range::GEOMETRY)?;
    check_value(&f("alpha"), joint.dh.alpha, Range::GEOMETRY)?;
    if let Some(JointFriction { geometry: ContactGeometry::Bearings { reaction_point, .. }, .. }) = joint.friction {
        for (k, x) in reaction_point.iter().enumerate() {
            check_value(&f(&format!("bearings.reaction_point[{}]", k + 1)), *x, Range::GEOMETRY)?;
        }
        if reaction_point.x.abs() > 1e-12 || reaction_point.y.abs() > 1e-12 {
            return Err(ModelError::Invalid {
                field: f("bearings.reaction_point"),
                reason: "must lie on the joint axis z (x = y = 0 in frame i-1)".into(),
            });
        }
    }
    Ok(())
}

/// A link whose data are given in the study's frame i, in the engine's link
/// frame: through T_i.
fn link_in_link_frame(link: &Link, trailing: &Placement) -> Link {
    let r = trailing.rotation;
    Link { mass: link.mass, com: trailing.apply(&link.com), inertia: r * link.inertia * r.transpose() }
}

impl Model {
    /// Builds and validates a model from Denavit–Hartenberg joints, their
    /// links (inertial data in the study's frames i) and the end point E in
    /// frame n, as the DH model file describes them.
    pub fn from_dh(
        name: impl Into<String>,
        dh_joints: &[DhJoint],
        links: &[Link],
        gravity: Vec3,
        end_point: Vec3,
        integrator: IntegratorSettings,
    ) -> Result<Model, ModelError> {
        for (i, joint) in dh_joints.iter().enumerate() {
            check_dh_joint(i + 1, joint)?;
        }
        if links.len() != dh_joints.len() {
            return Err(ModelError::Invalid {
                field: "link".into(),
                reason: format!("{} links for {} joints", links.len(), dh_joints.len()),
            });
        }
        // Links and the end point with the values and frames of the file.
        for (i, link) in links.iter().enumerate() {
            validate_link(i + 1, link, true)?;
        }
        check_vec("end_point", &end_point, Range::GEOMETRY)?;
        let mut joints = Vec::with_capacity(dh_joints.len());
        let mut previous_trailing = Placement::identity();
        for j in dh_joints {
            let leading = leading_placement(j.kind, &j.dh);
            let offset = match j.kind {
                JointKind::Revolute => j.dh.theta,
                JointKind::Prismatic => j.dh.d,
            };
            let trailing = trailing_placement(&j.dh);
            let friction = j.friction.map(|f| JointFriction {
                coefficients: f.coefficients,
                geometry: match f.geometry {
                    // On z_{i−1}: the joint frame is frame i−1 shifted by d_i along it.
                    ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c } => {
                        ContactGeometry::Bearings {
                            reaction_point: Vec3::new(0.0, 0.0, reaction_point.z - leading.translation.z),
                            l_a,
                            l_b,
                            d_a,
                            d_b,
                            d_c,
                        }
                    }
                    ContactGeometry::Slider { centre, a, b, c } => {
                        ContactGeometry::Slider { centre: trailing.apply(&centre), a, b, c }
                    }
                },
            });
            joints.push(Joint {
                kind: j.kind,
                placement: previous_trailing.then(&leading),
                offset,
                drive: j.drive,
                friction,
                reported_axes: Mat3::identity(),
            });
            previous_trailing = trailing;
        }
        let links: Vec<Link> =
            links.iter().zip(dh_joints).map(|(l, j)| link_in_link_frame(l, &trailing_placement(&j.dh))).collect();
        let model = Model {
            name: name.into(),
            joint_names: vec![None; joints.len()],
            joints,
            links,
            gravity,
            end_point: previous_trailing.apply(&end_point),
            integrator,
            warnings: Vec::new(),
        };
        model.validate()?;
        Ok(model)
    }
}
