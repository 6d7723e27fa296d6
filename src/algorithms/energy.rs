//! Kinetic and potential energy of the links.

use crate::data::Data;
use crate::math::Vec3;
use crate::model::{JointKind, Model};

/// Kinetic energy T = Σ ½·m_i·|v_ci|² + ½·ω_iᵀ·I_i·ω_i of the links at joint
/// velocities `qd` and the configuration of the last
/// [`joint_transforms`](super::kinematics::joint_transforms), J. Velocities
/// are carried outwards in the link frames as in the inverse dynamics.
pub fn kinetic_energy(model: &Model, data: &Data, qd: &[f64]) -> f64 {
    let (mut w, mut v) = (Vec3::zeros(), Vec3::zeros());
    let mut t = 0.0;
    for (i, (joint, link)) in model.joints.iter().zip(&model.links).enumerate() {
        let (r, p) = (&data.link_rotation[i], data.link_offset_child[i]);
        // Link i−1's motion in link i's frame, carried to the joint's origin.
        let w_prev = r.tr_mul(&w);
        v = r.tr_mul(&v) + w_prev.cross(&p);
        w = w_prev;
        match joint.kind {
            JointKind::Revolute => w.z += qd[i],
            JointKind::Prismatic => v.z += qd[i],
        }
        let v_c = v + w.cross(&link.com);
        t += 0.5 * link.mass * v_c.norm_squared() + 0.5 * w.dot(&(link.inertia * w));
    }
    t
}

/// Potential energy of gravity V = −Σ m_i·gᵀ·x_ci, zero at the origin of
/// frame 0, from the last forward kinematics, J.
pub fn potential_energy(model: &Model, data: &Data) -> f64 {
    model.links.iter().enumerate().map(|(i, link)| -link.mass * model.gravity.dot(&data.com[i])).sum()
}
