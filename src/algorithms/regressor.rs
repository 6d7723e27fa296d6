//! The joint-torque regressor: the rigid-body inverse dynamics
//! τ = M(q)·q̈ + C(q, q̇)·q̇ + g(q) of the study's (3.9) written as Y(q, q̇, q̈)·π,
//! linear in the links' standard inertial parameters π (Atkeson, An and
//! Hollerbach 1986; Pinocchio's `computeJointTorqueRegressor`).
//!
//! Per link i, ten parameters in Pinocchio's order
//! `[m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]` ([`PARAMETER_NAMES`]):
//! the mass, its first moment about the origin of link i's frame and the
//! inertia tensor about that origin, I = I_c + m·(cᵀc·1 − c·cᵀ), everything
//! resolved in link i's frame, the engine's link frame (see
//! [`Joint`](crate::model::Joint)), in which [`Link`] holds its data:
//!
//! * a Denavit–Hartenberg model: the frame just after joint i's motion,
//!   A_1·…·A_{i−1}·P_i·M_i(q_i), which is the study's frame i (eq. 3.1)
//!   turned back by its trailing T_i = Trans_x(a_i)·Rot_x(α_i): the origin on
//!   the axis z_{i−1} at height d_i, z along that axis, x along the common
//!   normal towards joint i+1. The model file's `link` data (in the study's
//!   frame i) reach it through T_i ([`trailing_placement`](crate::model::trailing_placement));
//! * a URDF model: the URDF child link frame of joint i (the frame of the
//!   moving body, with the bodies on fixed joints after it merged in), turned
//!   by R_a, the smallest rotation taking z to the joint's axis a (the
//!   identity for `axis xyz="0 0 1"`, see
//!   [`axis_alignment`](crate::model::axis_alignment)); for an axis +z it is
//!   Pinocchio's joint frame of a model built from the same URDF, otherwise π
//!   of Pinocchio is (m, R_a·h, R_a·I·R_aᵀ) of the engine's (m, h, I).
//!
//! The algorithm: the link velocities and accelerations of the recursive
//! Newton–Euler forward pass ([`rnea`]), then per link j its body regressor,
//! the force and the moment about its frame's origin that link j's own
//! inertia needs, linear in its ten parameters, carried inwards through the
//! joint transforms to every joint i ≤ j, whose axis component is Y_i,j.

use super::inverse_dynamics::{state_row, state_rows};
use super::kinematics::joint_transforms;
use super::rnea::rnea;
use crate::data::Data;
use crate::error::ModelError;
use crate::math::{Mat3, Mat3x10, Vec3};
use crate::model::{JointKind, Link, Model};

/// The number of standard inertial parameters of a link.
pub const LINK_PARAMETERS: usize = 10;

/// The names of a link's standard inertial parameters, in Pinocchio's order
/// (h = m·c the first moment, I the inertia about the frame's origin).
pub const PARAMETER_NAMES: [&str; LINK_PARAMETERS] =
    ["m", "mc_x", "mc_y", "mc_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz"];

/// The ten standard parameters of `link` (its data in its link frame, inertia
/// about the centre of mass): [m, h, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] with
/// h = m·c and I = I_c + m·(cᵀc·1 − c·cᵀ), the parallel-axis theorem.
pub fn link_parameters(link: &Link) -> [f64; LINK_PARAMETERS] {
    let (m, c) = (link.mass, link.com);
    let h = c * m;
    let i = link.inertia + (Mat3::identity() * c.norm_squared() - c * c.transpose()) * m;
    [m, h.x, h.y, h.z, i[(0, 0)], i[(0, 1)], i[(1, 1)], i[(0, 2)], i[(1, 2)], i[(2, 2)]]
}

/// The model's standard parameters π into `pi` (length 10n): link 1's ten
/// ([`link_parameters`]), then link 2's, and so on, each in its link frame.
pub fn standard_parameters(model: &Model, pi: &mut [f64]) {
    assert_eq!(pi.len(), LINK_PARAMETERS * model.nq(), "standard_parameters: π must have 10n values");
    for (block, link) in pi.chunks_exact_mut(LINK_PARAMETERS).zip(&model.links) {
        block.copy_from_slice(&link_parameters(link));
    }
}

/// `model` with its links' masses, centres of mass and inertias (about the
/// centre of mass) from the standard parameters `pi` (length 10n, in the
/// order and frames of [`standard_parameters`]), then validated as a model
/// file's are: what writes an identified model.
///
/// Each link must be physically consistent: its parameters finite, its mass
/// m > 0 (or the link all zero, a massless link as a URDF link without
/// `<inertial>`), and the inertia about its centre of mass,
/// I_c = I − (hᵀh·1 − h·hᵀ)/m, positive semidefinite with principal moments
/// that satisfy the triangle inequality I1 + I2 ≥ I3 (each to 1e-12 of the
/// link's inertia scale, for rounding); the model's own checks then also
/// want I_c positive definite. An error names the link (`joint[i].link.…`,
/// with the URDF joint's name where there is one).
pub fn with_standard_parameters(mut model: Model, pi: &[f64]) -> Result<Model, ModelError> {
    let n = model.nq();
    if pi.len() != LINK_PARAMETERS * n {
        return Err(ModelError::Invalid {
            field: "link".into(),
            reason: format!("{} standard parameters for {n} links; each link has {LINK_PARAMETERS}", pi.len()),
        });
    }
    for (i, block) in pi.chunks_exact(LINK_PARAMETERS).enumerate() {
        let field = |what: &str| {
            let name = model.joint_names[i].as_ref().map_or(String::new(), |s| format!(" (`{s}`)"));
            format!("joint[{}]{name}.link.{what}", i + 1)
        };
        model.links[i] = link_from_parameters(block.try_into().expect("ten values"), &field)?;
    }
    model.validate()?;
    Ok(model)
}

/// The link of ten standard parameters, checked for physical consistency
/// (see [`with_standard_parameters`]); `field` names a part of it.
fn link_from_parameters(p: &[f64; LINK_PARAMETERS], field: &dyn Fn(&str) -> String) -> Result<Link, ModelError> {
    if let Some(k) = p.iter().position(|x| !x.is_finite()) {
        return Err(ModelError::InvalidParameter {
            field: field(PARAMETER_NAMES[k]),
            value: p[k],
            reason: "is not finite".into(),
        });
    }
    let (m, h) = (p[0], Vec3::new(p[1], p[2], p[3]));
    let origin_inertia = Mat3::new(p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9]);
    if p.iter().all(|&x| x == 0.0) {
        return Ok(Link { mass: 0.0, com: Vec3::zeros(), inertia: Mat3::zeros() });
    }
    if m <= 0.0 {
        return Err(ModelError::InvalidParameter {
            field: field("mass"),
            value: m,
            reason: "a link with a first moment or inertia needs a positive mass".into(),
        });
    }
    let c = h / m;
    // The parallel-axis theorem backwards, in h: no division before the subtraction.
    let inertia = origin_inertia - (Mat3::identity() * h.norm_squared() - h * h.transpose()) / m;
    let scale = origin_inertia.amax().max(h.norm_squared() / m);
    let moments = Mat3::symmetric_eigenvalues(&inertia);
    let (smallest, largest) = (moments.min(), moments.max());
    let tolerance = 1e-12 * scale;
    let reason = if smallest < -tolerance {
        "is not positive semidefinite"
    } else if moments.sum() - 2.0 * largest < -tolerance {
        "violates the triangle inequality I1 + I2 >= I3"
    } else {
        return Ok(Link { mass: m, com: c, inertia });
    };
    Err(ModelError::Invalid {
        field: field("inertia"),
        reason: format!(
            "the inertia about the centre of mass (principal moments {:.6e}, {:.6e}, {:.6e} kg·m²) {reason}",
            moments[0], moments[1], moments[2]
        ),
    })
}

/// The joint-torque regressor Y(q, q̇, q̈) (n × 10n) into `data.regressor`:
/// τ = Y·π with π the model's [`standard_parameters`] and τ its inverse
/// dynamics with gravity, M(q)·q̈ + bias(q, q̇) of (3.9) (N·m or N). `q`, `qd`,
/// `qdd` each of length n (rad or m, per s, per s²).
///
/// Row i is joint i, columns 10j…10j+9 link j's parameters; Y_i,j = 0 for a
/// link j before joint i. On the way it computes the joint transforms of `q`
/// and runs [`rnea`], whose forward pass gives the link motions: `data.tau`
/// then holds the same τ by the recursion on the model's own inertias.
pub fn joint_torque_regressor(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], qdd: &[f64]) {
    let n = model.nq();
    assert!(
        data.regressor.nrows() == n && data.regressor.ncols() == LINK_PARAMETERS * n,
        "joint_torque_regressor: data must be sized for the model"
    );
    joint_transforms(model, data, q);
    rnea(model, data, q, qd, qdd);
    data.regressor.fill(0.0);
    for j in 0..n {
        let (mut force, mut moment) =
            body_regressor(&data.omega[j + 1], &data.omega_dot[j + 1], &data.acceleration[j + 1]);
        for i in (0..=j).rev() {
            let row = match model.joints[i].kind {
                JointKind::Revolute => moment.row(2),
                JointKind::Prismatic => force.row(2),
            };
            data.regressor.view_mut((i, LINK_PARAMETERS * j), (1, LINK_PARAMETERS)).copy_from(&row);
            if i > 0 {
                // Into link i−1's frame, the moment about its joint's origin
                // O_{i−1}: n' = R·n + p × (R·f), as the recursion carries a
                // child's force.
                let (r, p) = (&data.link_rotation[i], data.link_offset[i]);
                force = r * force;
                moment = r * moment + p.cross_matrix() * force;
            }
        }
    }
}

/// The force f and the moment n about the origin O of a link's frame that
/// its own inertia needs, as maps of its ten standard parameters
/// [m, h, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], from its angular velocity ω,
/// angular acceleration ω̇ and the acceleration a of O minus gravity, all in
/// its frame (Newton–Euler about O):
///
/// f = m·a + ω̇ × h + ω × (ω × h),   n = I·ω̇ + ω × (I·ω) + h × a.
fn body_regressor(w: &Vec3, wd: &Vec3, a: &Vec3) -> (Mat3x10, Mat3x10) {
    let (wx, wdx, ax) = (w.cross_matrix(), wd.cross_matrix(), a.cross_matrix());
    let mut force = Mat3x10::zeros();
    force.fixed_view_mut::<3, 1>(0, 0).copy_from(a);
    force.fixed_view_mut::<3, 3>(0, 1).copy_from(&(wdx + wx * wx));
    let mut moment = Mat3x10::zeros();
    // h × a = −[a]×·h.
    moment.fixed_view_mut::<3, 3>(0, 1).copy_from(&(-ax));
    let inertia_map = |v: &Vec3| {
        // I·v as a map of (I_xx, I_xy, I_yy, I_xz, I_yz, I_zz).
        nalgebra::SMatrix::<f64, 3, 6>::from_row_slice(&[
            v.x, v.y, 0.0, v.z, 0.0, 0.0, //
            0.0, v.x, v.y, 0.0, v.z, 0.0, //
            0.0, 0.0, 0.0, v.x, v.y, v.z,
        ])
    };
    moment.fixed_view_mut::<3, 6>(0, 4).copy_from(&(inertia_map(wd) + wx * inertia_map(w)));
    (force, moment)
}

/// Row by row over `states`, row-major rows × [q(n), q̇(n), q̈(n)] (n =
/// `model.nq()`, SI units): Y of each row into `regressor`, row-major
/// rows × n × 10n. `data` must have been built for `model`.
///
/// An error names the first row (1-based) and state that is not finite, or
/// the lengths that do not fit; the output is then partly written.
pub fn joint_torque_regressor_rows(
    model: &Model,
    data: &mut Data,
    states: &[f64],
    regressor: &mut [f64],
) -> Result<(), String> {
    let n = model.nq();
    let rows = state_rows(n, states)?;
    let size = n * LINK_PARAMETERS * n;
    if regressor.len() != rows * size {
        return Err(format!(
            "`regressor` has {} values, {rows} rows of {n} x {} need {}",
            regressor.len(),
            LINK_PARAMETERS * n,
            rows * size
        ));
    }
    for (r, (state, out)) in states.chunks_exact(3 * n).zip(regressor.chunks_exact_mut(size)).enumerate() {
        let (q, qd, qdd) = state_row(n, r, state)?;
        joint_torque_regressor(model, data, q, qd, qdd);
        // DMatrix is column-major; the output row-major.
        for (i, row) in out.chunks_exact_mut(LINK_PARAMETERS * n).enumerate() {
            for (k, y) in row.iter_mut().enumerate() {
                *y = data.regressor[(i, k)];
            }
        }
    }
    Ok(())
}
