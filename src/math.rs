//! The one place for the math types: the nalgebra aliases, and the sines
//! of the joint angles that the workspace stores and the kinematics computes.
//!
//! Fixed-size types for per-link quantities; dynamic ones only where the size
//! is the number of joints n.

/// A 3-vector (position, force, moment, angular velocity, …).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3×3 matrix (rotation, inertia tensor).
pub type Mat3 = nalgebra::Matrix3<f64>;
/// A 4×4 homogeneous transformation or pseudo-inertia matrix (study eq. 3.1–3.3).
pub type Mat4 = nalgebra::Matrix4<f64>;
/// A 4-vector in homogeneous coordinates.
pub type Vec4 = nalgebra::Vector4<f64>;
/// A 6-vector of spatial algebra (angular part first).
pub type Vec6 = nalgebra::Vector6<f64>;
/// A 6×6 spatial inertia.
pub type Mat6 = nalgebra::Matrix6<f64>;
/// A 3×10 matrix: a link's force or moment as a map of its ten standard
/// inertial parameters (the joint-torque regressor's body regressor).
pub type Mat3x10 = nalgebra::SMatrix<f64, 3, 10>;
/// A joint-space vector of dimension n.
pub type VecN = nalgebra::DVector<f64>;
/// A joint-space matrix of dimension n×n.
pub type MatN = nalgebra::DMatrix<f64>;

/// A revolute joint's coordinate and the sine and cosine of its angle
/// θ = q + offset there, computed by the library.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThetaAnchor {
    /// Joint coordinate q, rad.
    pub q: f64,
    /// sin(offset + q).
    pub sin_theta: f64,
    /// cos(offset + q).
    pub cos_theta: f64,
}

/// How far from its anchor a joint's sine and cosine are expanded, rad.
pub const ANCHOR_REACH: f64 = 1e-2;

/// (sin(θ₀ + δ), cos(θ₀ + δ)) from s₀ = sin θ₀, c₀ = cos θ₀ for |δ| ≤
/// [`ANCHOR_REACH`]: sin δ and cos δ − 1 by their Taylor series to δ⁵ and
/// δ⁶ (the first omitted terms are below 2e-18), added to s₀, c₀ as small
/// corrections so that the result is within about one rounding of the exact
/// value.
#[inline(always)]
pub fn sin_cos_near(s0: f64, c0: f64, delta: f64) -> (f64, f64) {
    let d2 = delta * delta;
    let cos_m1 = d2 * (-0.5 + d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)));
    let sin_d = delta * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0)));
    (s0 + (s0 * cos_m1 + c0 * sin_d), c0 + (c0 * cos_m1 - s0 * sin_d))
}
