//! The study's Lagrange formulation with the B matrices (eqs. 3.3–3.9),
//! kept as the reference against which the recursive algorithms are tested.
//!
//! Straightforward and O(n⁴): every derivative of B_i is built as the product
//! of eq. (3.6), with the constant matrices D_j inserted before A_j.

use super::kinematics::joint_transform;
use crate::math::{Mat4, MatN, Vec4, VecN};
use crate::model::{Joint, JointKind, Model};

/// The constant matrix D_j with ∂A_j/∂q_j = D_j·A_j (eq. 3.6). With A_j =
/// P_j·M_j(q) (a placement, then the motion) and ∂M_j/∂q = D·M_j for the
/// motion's generator D, D_j = P_j·D·P_j⁻¹.
pub fn derivative_operator(joint: &Joint) -> Mat4 {
    let mut d = Mat4::zeros();
    match joint.kind {
        // ∂/∂θ Rot_z = [ẑ]× Rot_z.
        JointKind::Revolute => {
            d[(0, 1)] = -1.0;
            d[(1, 0)] = 1.0;
        }
        JointKind::Prismatic => d[(2, 3)] = 1.0,
    }
    let (r, t) = (joint.placement.rotation, joint.placement.translation);
    let mut p = Mat4::identity();
    p.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    p.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    let mut p_inv = Mat4::identity();
    p_inv.fixed_view_mut::<3, 3>(0, 0).copy_from(&r.transpose());
    p_inv.fixed_view_mut::<3, 1>(0, 3).copy_from(&(-(r.transpose() * t)));
    p * d * p_inv
}

/// B_i^{j…} of eq. (3.6): A_1…A_i with D_k inserted before A_k once for
/// every k in `derivatives` (1-based joint numbers, repeats allowed). With no
/// derivatives this is B_i of eq. (3.2); a derivative by a joint k > i gives 0.
pub fn b_derivative(model: &Model, q: &[f64], i: usize, derivatives: &[usize]) -> Mat4 {
    if derivatives.iter().any(|&k| k > i) {
        return Mat4::zeros();
    }
    let mut b = Mat4::identity();
    for k in 1..=i {
        let joint = &model.joints[k - 1];
        for _ in derivatives.iter().filter(|&&d| d == k) {
            b *= derivative_operator(joint);
        }
        b *= joint_transform(joint, q[k - 1]);
    }
    b
}

/// The joint-space equations of motion in the study's form (3.9).
#[derive(Debug, Clone)]
pub struct LagrangeTerms {
    /// D_si: mass matrix.
    pub mass: MatN,
    /// Σ_j Σ_{i≥j} D_sji q̇_j q̇_i: Coriolis and centrifugal terms.
    pub velocity_terms: VecN,
    /// D_s = −Σ_{i≥s} m_i gᵀ(B_i^s r_ci): gravity terms.
    pub gravity: VecN,
}

fn homogeneous(v: &crate::math::Vec3) -> Vec4 {
    Vec4::new(v.x, v.y, v.z, 1.0)
}

/// Evaluates D_si, D_sji q̇_j q̇_i and D_s of eq. (3.9) at (q, q̇).
pub fn lagrange_terms(model: &Model, q: &[f64], qd: &[f64]) -> LagrangeTerms {
    let n = model.nq();
    let h: Vec<Mat4> = model.links.iter().map(|l| l.pseudo_inertia()).collect();
    // bs[l][j] = B_l^j (1-based l, j).
    let bs: Vec<Vec<Mat4>> = (0..=n)
        .map(|l| (0..=n).map(|j| if j == 0 { Mat4::zeros() } else { b_derivative(model, q, l, &[j]) }).collect())
        .collect();
    let mut mass = MatN::zeros(n, n);
    for s in 1..=n {
        for i in 1..=n {
            mass[(s - 1, i - 1)] = (s.max(i)..=n).map(|l| (bs[l][i] * h[l - 1] * bs[l][s].transpose()).trace()).sum();
        }
    }
    let mut velocity_terms = VecN::zeros(n);
    for s in 1..=n {
        let mut sum = 0.0;
        for j in 1..=n {
            for i in j..=n {
                let delta = if i == j { 1.0 } else { 2.0 };
                let d_sji: f64 = (i.max(j).max(s)..=n)
                    .map(|l| (b_derivative(model, q, l, &[j, i]) * h[l - 1] * bs[l][s].transpose()).trace())
                    .sum();
                sum += delta * d_sji * qd[j - 1] * qd[i - 1];
            }
        }
        velocity_terms[s - 1] = sum;
    }
    // (3.4) with the gravity vector of the model instead of g·a: V = −Σ m_i gᵀ(B_i r_ci).
    let g = Vec4::new(model.gravity.x, model.gravity.y, model.gravity.z, 0.0);
    let mut gravity = VecN::zeros(n);
    for s in 1..=n {
        let b_star: Vec4 =
            (s..=n).map(|i| bs[i][s] * homogeneous(&model.links[i - 1].com) * model.links[i - 1].mass).sum();
        gravity[s - 1] = -g.dot(&b_star);
    }
    LagrangeTerms { mass, velocity_terms, gravity }
}

/// Kinetic energy by eq. (3.3), T = ½ Σ tr(Ḃ_i H_i Ḃ_iᵀ) with Ḃ_i = Σ_j B_i^j q̇_j (3.7).
pub fn kinetic_energy(model: &Model, q: &[f64], qd: &[f64]) -> f64 {
    let n = model.nq();
    (1..=n)
        .map(|i| {
            let bdot: Mat4 = (1..=i).map(|j| b_derivative(model, q, i, &[j]) * qd[j - 1]).sum();
            0.5 * (bdot * model.links[i - 1].pseudo_inertia() * bdot.transpose()).trace()
        })
        .sum()
}

/// Potential energy of gravity by eq. (3.4), V = −gᵀ Σ m_i B_i r_ci.
pub fn potential_energy(model: &Model, q: &[f64]) -> f64 {
    let g = Vec4::new(model.gravity.x, model.gravity.y, model.gravity.z, 0.0);
    (1..=model.nq())
        .map(|i| {
            -g.dot(&(b_derivative(model, q, i, &[]) * homogeneous(&model.links[i - 1].com))) * model.links[i - 1].mass
        })
        .sum()
}
