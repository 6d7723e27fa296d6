//! The one place for the math types: the nalgebra aliases, and the
//! rotations and sines of the Denavit–Hartenberg transforms that the
//! workspace stores and the kinematics computes.
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
/// A joint-space vector of dimension n.
pub type VecN = nalgebra::DVector<f64>;
/// A joint-space matrix of dimension n×n.
pub type MatN = nalgebra::DMatrix<f64>;

/// The rotation of a DH transform A_i (eq. 3.1), R_i = Rot_z(θ_i)·Rot_x(α_i),
/// by the sines and cosines of its two angles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRotation {
    /// sin θ_i.
    pub sin_theta: f64,
    /// cos θ_i.
    pub cos_theta: f64,
    /// sin α_i.
    pub sin_alpha: f64,
    /// cos α_i.
    pub cos_alpha: f64,
}

// `to_*` read as "into frame …": the receiver is small and taken by reference
// like the vector.
#[allow(clippy::wrong_self_convention)]
impl DhRotation {
    /// R_i for the angles θ, α.
    pub fn new(theta: f64, alpha: f64) -> DhRotation {
        let ((sin_theta, cos_theta), (sin_alpha, cos_alpha)) = (theta.sin_cos(), alpha.sin_cos());
        DhRotation { sin_theta, cos_theta, sin_alpha, cos_alpha }
    }

    /// R_iᵀ·v: a vector resolved in frame i−1 resolved in frame i.
    #[inline]
    pub fn to_child(&self, v: &Vec3) -> Vec3 {
        let (st, ct, sa, ca) = (self.sin_theta, self.cos_theta, self.sin_alpha, self.cos_alpha);
        let (x, y) = (ct * v.x + st * v.y, ct * v.y - st * v.x);
        Vec3::new(x, ca * y + sa * v.z, ca * v.z - sa * y)
    }

    /// R_i·v: a vector resolved in frame i resolved in frame i−1.
    #[inline]
    pub fn to_parent(&self, v: &Vec3) -> Vec3 {
        let (st, ct) = (self.sin_theta, self.cos_theta);
        let u = self.to_joint_frame(v);
        Vec3::new(ct * u.x - st * u.y, st * u.x + ct * u.y, u.z)
    }

    /// Rot_x(α_i)·v: a vector resolved in frame i resolved in the joint frame
    /// of joint i (frame i−1 turned by θ_i; z the joint axis).
    #[inline]
    pub fn to_joint_frame(&self, v: &Vec3) -> Vec3 {
        let (sa, ca) = (self.sin_alpha, self.cos_alpha);
        Vec3::new(v.x, ca * v.y - sa * v.z, sa * v.y + ca * v.z)
    }

    /// Rot_z(θ_i)ᵀ·v: a vector resolved in frame i−1 resolved in the joint frame.
    #[inline]
    pub fn parent_to_joint_frame(&self, v: &Vec3) -> Vec3 {
        let (st, ct) = (self.sin_theta, self.cos_theta);
        Vec3::new(ct * v.x + st * v.y, ct * v.y - st * v.x, v.z)
    }

    /// The joint axis z_{i−1} resolved in frame i: R_iᵀ·e_z = (0, sin α_i, cos α_i).
    #[inline]
    pub fn axis_in_child(&self) -> Vec3 {
        Vec3::new(0.0, self.sin_alpha, self.cos_alpha)
    }
}

/// A revolute joint's coordinate and the sine and cosine of its θ there,
/// computed by the library.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThetaAnchor {
    /// Joint coordinate q, rad.
    pub q: f64,
    /// sin(θ_DH + q).
    pub sin_theta: f64,
    /// cos(θ_DH + q).
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

