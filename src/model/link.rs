//! Links: rigid bodies with their inertial data.

use crate::math::{Mat3, Mat4, Vec3};

/// Inertial data of link i, expressed in its Denavit–Hartenberg frame i.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    /// Mass m_i > 0, kg.
    pub mass: f64,
    /// Centre of mass r_ci in frame i, m.
    pub com: Vec3,
    /// Inertia tensor about the centre of mass, axes of frame i, kg·m².
    pub inertia: Mat3,
}

impl Link {
    /// Pseudo-inertia matrix H_i of eq. (3.3): H = ∫ r rᵀ dm in homogeneous
    /// coordinates of frame i, so that T_i = ½ tr(Ḃ_i H_i Ḃ_iᵀ).
    pub fn pseudo_inertia(&self) -> Mat4 {
        let m = self.mass;
        let c = self.com;
        // Second moments about the centre of mass: Σ_c = ½ tr(I_c)·1 − I_c,
        // shifted to the frame origin by the parallel-axis term m·c·cᵀ.
        let sigma = Mat3::identity() * (0.5 * self.inertia.trace()) - self.inertia + c * c.transpose() * m;
        let mut h = Mat4::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
        h.fixed_view_mut::<3, 1>(0, 3).copy_from(&(c * m));
        h.fixed_view_mut::<1, 3>(3, 0).copy_from(&(c * m).transpose());
        h[(3, 3)] = m;
        h
    }
}
