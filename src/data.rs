//! The workspace of the algorithms: everything that is computed, sized once
//! from the model so that nothing allocates on the hot path.

use crate::math::{Mat3, Mat6, MatN, ThetaAnchor, Vec3};
use crate::model::Model;

/// Kinematic and dynamic workspace of one model (Pinocchio's `Data`).
///
/// Index conventions: frame arrays (`rotation`, `origin`, `omega`, …) have n+1
/// entries, index 0 being the base frame 0 and index i link i's frame; joint
/// arrays have n entries, index i−1 for joint i. The frame-0 kinematics
/// (`rotation` … `inertia`) come from
/// [`forward_kinematics`](crate::algorithms::kinematics::forward_kinematics);
/// the inverse dynamics works in the link frames from the joint transforms
/// alone (`link_rotation` … `link_offset_child`) and resolves every quantity
/// of link i in link i's frame.
#[derive(Debug, Clone)]
pub struct Data {
    /// Rotation of frame i in frame 0, i = 0…n.
    pub rotation: Vec<Mat3>,
    /// Origin of frame i in frame 0, m.
    pub origin: Vec<Vec3>,
    /// Centre of mass of link i in frame 0, m (joint array).
    pub com: Vec<Vec3>,
    /// Inertia tensor of link i about its centre of mass, frame 0 axes (joint array).
    pub inertia: Vec<Mat3>,
    /// Rotation R_i of link i's frame in link i−1's frame at the last joint
    /// coordinates: the placement's rotation times Rot_z(q_i + offset) for a
    /// revolute joint, the placement's alone for a prismatic one.
    pub link_rotation: Vec<Mat3>,
    /// The placement's origin resolved in the joint frame, Pᵀ·p (constant).
    pub origin_in_joint_frame: Vec<Vec3>,
    /// Coordinates and exact sines of the revolute joints' angles at which
    /// their rotations were last computed by the library (see
    /// [`joint_transforms_near_anchors`](crate::algorithms::kinematics::joint_transforms_near_anchors)).
    pub theta_anchor: Vec<ThetaAnchor>,
    /// Joint coordinates of the joint transforms (`link_rotation`,
    /// `link_offset`, `link_offset_child`).
    pub transforms_q: Vec<f64>,
    /// False when the joint transforms must be recomputed by the library's
    /// sines before they are used (see
    /// [`update_joint_transforms`](crate::algorithms::kinematics::update_joint_transforms)).
    pub transforms_current: bool,
    /// p_i = O_i − O_{i−1} resolved in link i−1's frame, m (for a prismatic
    /// joint the placement's origin moved by q_i + offset along the axis).
    pub link_offset: Vec<Vec3>,
    /// The same offset resolved in link i's frame, R_iᵀ·p_i, m.
    pub link_offset_child: Vec<Vec3>,
    /// Angular velocity of link i, frame i, rad/s.
    pub omega: Vec<Vec3>,
    /// Angular acceleration of link i, frame i, rad/s².
    pub omega_dot: Vec<Vec3>,
    /// Acceleration of the origin of frame i minus gravity, frame i, m/s².
    pub acceleration: Vec<Vec3>,
    /// Force f_i exerted by link i−1 on link i, frame i, N (joint array).
    pub force: Vec<Vec3>,
    /// Moment n_i exerted by link i−1 on link i about the origin of frame
    /// i (the joint's origin), frame i, N·m (joint array).
    pub moment: Vec<Vec3>,
    /// Generalized joint forces τ = M q̈ + bias of the last inverse dynamics.
    pub tau: Vec<f64>,
    /// Composite spatial inertia of links i…n about the origin of frame 0.
    pub composite: Vec<Mat6>,
    /// Joint-space mass matrix M(q) (study's D_si, eq. 3.9).
    pub mass_matrix: MatN,
    /// Joint-torque regressor Y(q, q̇, q̈), n × 10n: τ = Y·π with π the links'
    /// standard inertial parameters
    /// ([`joint_torque_regressor`](crate::algorithms::regressor::joint_torque_regressor)).
    pub regressor: MatN,
    /// Joint force at the reaction reference point, in the joint frame, N.
    pub reaction_force: Vec<Vec3>,
    /// Joint moment about the reaction reference point, in the joint frame, N·m.
    pub reaction_moment: Vec<Vec3>,
}

impl Data {
    /// A workspace sized for `model`.
    pub fn new(model: &Model) -> Data {
        let n = model.nq();
        Data {
            rotation: vec![Mat3::identity(); n + 1],
            origin: vec![Vec3::zeros(); n + 1],
            com: vec![Vec3::zeros(); n],
            inertia: vec![Mat3::zeros(); n],
            // A prismatic joint's rotation is its placement's, for good.
            link_rotation: model.joints.iter().map(|j| j.placement.rotation).collect(),
            origin_in_joint_frame: model
                .joints
                .iter()
                .map(|j| j.placement.rotation.tr_mul(&j.placement.translation))
                .collect(),
            theta_anchor: model
                .joints
                .iter()
                .map(|j| {
                    let (sin_theta, cos_theta) = j.offset.sin_cos();
                    ThetaAnchor { q: 0.0, sin_theta, cos_theta }
                })
                .collect(),
            transforms_q: vec![0.0; n],
            transforms_current: false,
            link_offset: vec![Vec3::zeros(); n],
            link_offset_child: vec![Vec3::zeros(); n],
            omega: vec![Vec3::zeros(); n + 1],
            omega_dot: vec![Vec3::zeros(); n + 1],
            acceleration: vec![Vec3::zeros(); n + 1],
            force: vec![Vec3::zeros(); n],
            moment: vec![Vec3::zeros(); n],
            tau: vec![0.0; n],
            composite: vec![Mat6::zeros(); n],
            mass_matrix: MatN::zeros(n, n),
            regressor: MatN::zeros(n, 10 * n),
            reaction_force: vec![Vec3::zeros(); n],
            reaction_moment: vec![Vec3::zeros(); n],
        }
    }
}
