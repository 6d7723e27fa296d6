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
        let (p, r) = (data.link_offset[i], data.dh_rotation[i]);
        match joint.kind {
            JointKind::Revolute => {
                w = r.to_child(&(w + Vec3::z() * qd[i]));
                v = r.to_child(&v) + w.cross(&p);
            }
            JointKind::Prismatic => {
                w = r.to_child(&w);
                v = r.to_child(&v) + w.cross(&p) + r.axis_in_child() * qd[i];
            }
        }
        let v_c = v + w.cross(&link.com);
        t += 0.5 * link.mass * v_c.norm_squared() + 0.5 * w.dot(&(link.inertia * w));
    }
    t
}

/// Potential energy of gravity V = −Σ m_i·gᵀ·x_ci, zero at the origin of
/// frame 0, from the last forward kinematics, J.
pub fn potential_energy(model: &Model, data: &Data) -> f64 {
    model
        .links
        .iter()
        .enumerate()
        .map(|(i, link)| -link.mass * model.gravity.dot(&data.com[i]))
        .sum()
}
