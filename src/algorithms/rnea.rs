//! Recursive Newton–Euler inverse dynamics with joint reactions (Luh, Walker
//! and Paul 1980, as cited by the study in section 3).

use super::kinematics::reaction_point;
use crate::data::Data;
use crate::math::Vec3;
use crate::model::{JointKind, Model};

/// Inverse dynamics at the configuration of the last
/// [`forward_kinematics`](super::kinematics::forward_kinematics) call.
///
/// `qd`, `qdd`: joint velocities and accelerations (length n). Gravity is the
/// model's. Results: `data.tau` (τ = M q̈ + bias, length n), the joint forces
/// `data.force[i]` and moments `data.moment[i]` (about the origin of frame
/// i−1) exerted by link i−1 on link i, and the link velocities.
///
/// The forward loop carries velocities and accelerations from link 1 to n,
/// the backward loop the joint forces from joint n to 1.
pub fn rnea(model: &Model, data: &mut Data, qd: &[f64], qdd: &[f64]) {
    let n = model.nq();
    // One check up front lets the compiler drop the per-index bounds checks.
    assert!(
        qd.len() == n
            && qdd.len() == n
            && model.links.len() == n
            && data.rotation.len() == n + 1
            && data.origin.len() == n + 1
            && data.omega.len() == n + 1
            && data.omega_dot.len() == n + 1
            && data.velocity.len() == n + 1
            && data.acceleration.len() == n + 1
            && data.com.len() == n
            && data.inertia.len() == n
            && data.com_velocity.len() == n
            && data.force.len() == n
            && data.moment.len() == n
            && data.tau.len() == n,
        "rnea: data, q̇ and q̈ must be sized for the model"
    );
    data.omega[0] = Vec3::zeros();
    data.omega_dot[0] = Vec3::zeros();
    data.velocity[0] = Vec3::zeros();
    // Gravity enters as an upward acceleration of the base.
    data.acceleration[0] = -model.gravity;
    for i in 0..n {
        let z: Vec3 = data.rotation[i].column(2).into();
        let r = data.origin[i + 1] - data.origin[i];
        let (w_prev, wd_prev) = (data.omega[i], data.omega_dot[i]);
        let (w, wd, v, a) = match model.joints[i].kind {
            JointKind::Revolute => {
                let w = w_prev + z * qd[i];
                let wd = wd_prev + z * qdd[i] + w_prev.cross(&z) * qd[i];
                (w, wd, data.velocity[i] + w.cross(&r), data.acceleration[i] + wd.cross(&r) + w.cross(&w.cross(&r)))
            }
            JointKind::Prismatic => {
                // r = p_i − p_{i−1} turns with link i−1 and grows along z.
                let v = data.velocity[i] + w_prev.cross(&r) + z * qd[i];
                let a = data.acceleration[i]
                    + wd_prev.cross(&r)
                    + w_prev.cross(&w_prev.cross(&r))
                    + w_prev.cross(&z) * (2.0 * qd[i])
                    + z * qdd[i];
                (w_prev, wd_prev, v, a)
            }
        };
        data.omega[i + 1] = w;
        data.omega_dot[i + 1] = wd;
        data.velocity[i + 1] = v;
        data.acceleration[i + 1] = a;
    }
    let mut f_next = Vec3::zeros();
    let mut n_next = Vec3::zeros();
    for i in (0..n).rev() {
        let link = &model.links[i];
        let (w, wd) = (data.omega[i + 1], data.omega_dot[i + 1]);
        let c = data.com[i] - data.origin[i + 1];
        data.com_velocity[i] = data.velocity[i + 1] + w.cross(&c);
        let a_c = data.acceleration[i + 1] + wd.cross(&c) + w.cross(&w.cross(&c));
        let inertia = &data.inertia[i];
        let f_inertial = a_c * link.mass;
        let n_inertial = inertia * wd + w.cross(&(inertia * w));
        let r_joint = data.origin[i + 1] - data.origin[i];
        let f = f_inertial + f_next;
        let m = n_inertial + (r_joint + c).cross(&f_inertial) + n_next + r_joint.cross(&f_next);
        let z: Vec3 = data.rotation[i].column(2).into();
        data.tau[i] = match model.joints[i].kind {
            JointKind::Revolute => z.dot(&m),
            JointKind::Prismatic => z.dot(&f),
        };
        data.force[i] = f;
        data.moment[i] = m;
        f_next = f;
        n_next = m;
    }
}

/// Joint reactions of every joint at its reaction reference point, resolved
/// in the joint frame (z along the joint axis), from the last [`rnea`] call:
/// `data.reaction_force[i]` (f_s, or f'_s for a slider) and
/// `data.reaction_moment[i]` (n_s, or n'_s).
pub fn joint_reactions(model: &Model, data: &mut Data) {
    for i in 0..model.nq() {
        joint_reaction(model, data, i);
    }
}

/// The reaction of joint `i` (0-based) only, as in [`joint_reactions`].
#[inline]
pub fn joint_reaction(model: &Model, data: &mut Data, i: usize) {
    let p = reaction_point(model, data, i);
    let f = data.force[i];
    // Moment about the reaction point from the moment about the frame i−1 origin.
    let m = data.moment[i] + (data.origin[i] - p).cross(&f);
    let rt = data.joint_rotation[i].transpose();
    data.reaction_force[i] = rt * f;
    data.reaction_moment[i] = rt * m;
}
