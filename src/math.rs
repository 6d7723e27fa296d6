//! The one place for the math type aliases.
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
