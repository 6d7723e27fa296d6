//! Composite rigid body algorithm: the joint-space mass matrix M(q), the
//! study's D_si of eq. (3.9), from spatial inertias about the origin of frame 0.

use crate::data::Data;
use crate::math::{Mat3, Mat6, Vec3, Vec6};
use crate::model::{JointKind, Model};

/// Motion subspace of joint `i` (0-based) as a spatial vector (ω, v_O) about
/// the origin O of frame 0, from the last forward kinematics.
#[inline]
pub fn motion_subspace(model: &Model, data: &Data, i: usize) -> Vec6 {
    let z: Vec3 = data.rotation[i + 1].column(2).into();
    match model.joints[i].kind {
        // Rotation about the axis through the joint's origin p: v_O = p × z.
        JointKind::Revolute => Vec6::new(z.x, z.y, z.z, 0.0, 0.0, 0.0) + lin(&data.origin[i + 1].cross(&z)),
        JointKind::Prismatic => lin(&z),
    }
}

#[inline]
fn lin(v: &Vec3) -> Vec6 {
    Vec6::new(0.0, 0.0, 0.0, v.x, v.y, v.z)
}

/// Spatial inertia about the origin of frame 0 of a body of mass `m`, centre
/// of mass `c` and inertia `inertia` about the centre of mass (frame 0 axes):
/// [[I_c + m·[c]×[c]×ᵀ, m·[c]×], [m·[c]×ᵀ, m·1]].
pub fn spatial_inertia(m: f64, c: &Vec3, inertia: &Mat3) -> Mat6 {
    let cx = c.cross_matrix();
    let mut s = Mat6::zeros();
    s.fixed_view_mut::<3, 3>(0, 0).copy_from(&(inertia + cx * cx.transpose() * m));
    s.fixed_view_mut::<3, 3>(0, 3).copy_from(&(cx * m));
    s.fixed_view_mut::<3, 3>(3, 0).copy_from(&(cx.transpose() * m));
    s.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Mat3::identity() * m));
    s
}

/// Fills `data.mass_matrix` with M(q) at the configuration of the last
/// forward kinematics: M_ij = S_iᵀ · I^c_max(i,j) · S_j, where I^c_k is the
/// composite inertia of links k…n. Symmetric by construction.
pub fn crba(model: &Model, data: &mut Data) {
    let n = model.nq();
    let mut acc = Mat6::zeros();
    for i in (0..n).rev() {
        acc += spatial_inertia(model.links[i].mass, &data.com[i], &data.inertia[i]);
        data.composite[i] = acc;
    }
    for j in 0..n {
        let s_j = motion_subspace(model, data, j);
        // Column j below the diagonal uses the composite inertia of the deeper joint i ≥ j.
        for i in j..n {
            let force = data.composite[i] * s_j;
            let m_ij = motion_subspace(model, data, i).dot(&force);
            data.mass_matrix[(i, j)] = m_ij;
            data.mass_matrix[(j, i)] = m_ij;
        }
    }
}
