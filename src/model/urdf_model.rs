//! A URDF chain written as the engine's joints: placements with the joint
//! axis along z, links in the engine's link frames, drives and friction
//! from the model file's `[joints.<name>]` entries.
//!
//! URDF moves link i about or along an axis a given in its joint frame. The
//! engine turns every motion about or along z, so link i's engine frame is
//! the URDF child link frame C_i turned by the smallest rotation R_a that
//! takes z to a (the identity when a = +z): with Rot(a, q)·R_a = R_a·Rot_z(q),
//! C_i·R_a = J_i·R_a·Rot_z(q), and joint i's placement in the engine frame of
//! link i−1 is R_{a,i−1}ᵀ·(R_i, t_i)·R_{a,i}. Inertias, centres of mass, the
//! contact geometry and the end point are turned by R_aᵀ into the engine's
//! frames; the reactions are reported turned back by R_a
//! ([`Joint::reported_axes`]), in the URDF child link frame.

use std::collections::BTreeMap;

use super::urdf::UrdfChain;
use super::{ContactGeometry, Drive, IntegratorSettings, Joint, JointFriction, JointKind, Link, Model, Placement};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};

/// What a model file adds to a URDF joint (`[joints.<name>]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointExtras {
    /// The drive; rigid when not given.
    pub drive: Drive,
    /// Friction with its contact geometry, in the URDF joint frame (the
    /// bearing reference point on the axis) or child link frame (the slider
    /// centre).
    pub friction: Option<JointFriction>,
    /// True when the entry gives friction coefficients but no geometry (an
    /// error once the joint's kind is known).
    pub friction_without_geometry: bool,
}

/// Everything a URDF model is built from.
#[derive(Debug, Clone)]
pub struct UrdfModelSpec {
    /// The model's name.
    pub name: String,
    /// The chain as the URDF reader found it.
    pub chain: UrdfChain,
    /// Drives and friction by URDF joint name.
    pub extras: BTreeMap<String, JointExtras>,
    /// Gravity in the base frame, m/s².
    pub gravity: Vec3,
    /// End point in the `tip_link` frame, m.
    pub end_point: Vec3,
    /// Stepper settings.
    pub integrator: IntegratorSettings,
}

/// The rotation taking z to the unit vector `a`: the smallest one where a
/// leans towards +z (the identity for a = +z), else the smallest one taking
/// −z to a after a half turn about x (a half turn about x for a = −z), so
/// that the formula never divides by a small 1 + cos.
pub fn axis_alignment(a: &Vec3) -> Mat3 {
    // I + [k]× + [k]×²/(1 + c) with k = u × a, c = u·a takes u to a.
    let towards = |u: Vec3| {
        let kx = u.cross(a).cross_matrix();
        Mat3::identity() + kx + kx * kx / (1.0 + u.dot(a))
    };
    if a.z >= 0.0 {
        towards(Vec3::z())
    } else {
        towards(-Vec3::z()) * Mat3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)
    }
}

impl Model {
    /// Builds and validates the model of a URDF chain with the drives and
    /// friction of `spec.extras`.
    pub fn from_urdf_chain(spec: UrdfModelSpec) -> Result<Model, ModelError> {
        let UrdfModelSpec { name, chain, extras, gravity, end_point, integrator } = spec;
        for key in extras.keys() {
            if !chain.joints.iter().any(|j| &j.name == key) {
                let moving: Vec<&str> = chain.joints.iter().map(|j| j.name.as_str()).collect();
                return Err(ModelError::Invalid {
                    field: format!("joints.{key}"),
                    reason: format!(
                        "no moving joint of that name on the chain from `{}` to `{}` (its moving joints: {})",
                        chain.base_link,
                        chain.tip_link,
                        moving.join(", ")
                    ),
                });
            }
        }
        let mut joints = Vec::with_capacity(chain.joints.len());
        let mut links = Vec::with_capacity(chain.joints.len());
        let mut parent_alignment = Mat3::identity();
        for (uj, body) in chain.joints.iter().zip(&chain.bodies) {
            let ra = axis_alignment(&uj.axis);
            let extra = extras.get(&uj.name).copied().unwrap_or(JointExtras {
                drive: Drive::Rigid,
                friction: None,
                friction_without_geometry: false,
            });
            let field = format!("joints.{}", uj.name);
            if extra.friction_without_geometry {
                let (key, what) = uj.kind.friction_geometry();
                return Err(ModelError::Invalid {
                    field: format!("{field}.{key}"),
                    reason: format!("friction on this joint needs {what}"),
                });
            }
            let friction = match extra.friction {
                None => None,
                Some(f) => Some(JointFriction {
                    coefficients: f.coefficients,
                    geometry: engine_geometry(&field, uj.kind, &uj.axis, &ra, f.geometry)?,
                }),
            };
            joints.push(Joint {
                kind: uj.kind,
                placement: Placement {
                    rotation: parent_alignment.transpose() * uj.rotation * ra,
                    translation: parent_alignment.transpose() * uj.translation,
                },
                offset: 0.0,
                drive: extra.drive,
                friction,
                reported_axes: ra,
            });
            links.push(Link {
                mass: body.mass,
                com: ra.transpose() * body.com,
                inertia: ra.transpose() * body.inertia * ra,
            });
            parent_alignment = ra;
        }
        let tip = chain.tip_rotation * end_point + chain.tip_translation;
        let model = Model {
            name,
            joint_names: chain.joints.iter().map(|j| Some(j.name.clone())).collect(),
            joints,
            links,
            gravity,
            end_point: parent_alignment.transpose() * tip,
            integrator,
            warnings: chain.warnings,
        };
        model.validate()?;
        Ok(model)
    }
}

/// The contact geometry of a URDF joint in the engine's link frame, checked
/// against the joint's kind and axis.
fn engine_geometry(
    field: &str,
    kind: JointKind,
    axis: &Vec3,
    ra: &Mat3,
    g: ContactGeometry,
) -> Result<ContactGeometry, ModelError> {
    match (kind, g) {
        (JointKind::Revolute, ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c }) => {
            let off_axis = reaction_point - axis * axis.dot(&reaction_point);
            if off_axis.norm() > 1e-12 {
                return Err(ModelError::Invalid {
                    field: format!("{field}.bearings.reaction_point"),
                    reason: format!(
                        "must lie on the joint axis [{}, {}, {}] (in the joint frame), it is {:.3e} m off it",
                        axis.x,
                        axis.y,
                        axis.z,
                        off_axis.norm()
                    ),
                });
            }
            // On the axis: exactly on the engine's z.
            Ok(ContactGeometry::Bearings {
                reaction_point: Vec3::new(0.0, 0.0, axis.dot(&reaction_point)),
                l_a,
                l_b,
                d_a,
                d_b,
                d_c,
            })
        }
        (JointKind::Prismatic, ContactGeometry::Slider { centre, a, b, c }) => {
            Ok(ContactGeometry::Slider { centre: ra.transpose() * centre, a, b, c })
        }
        (JointKind::Revolute, ContactGeometry::Slider { .. }) => Err(ModelError::Invalid {
            field: format!("{field}.slider"),
            reason: "slider geometry belongs to prismatic joints; this URDF joint is revolute and takes `bearings`"
                .into(),
        }),
        (JointKind::Prismatic, ContactGeometry::Bearings { .. }) => Err(ModelError::Invalid {
            field: format!("{field}.bearings"),
            reason: "bearing geometry belongs to revolute joints; this URDF joint is prismatic and takes `slider`"
                .into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::axis_alignment;
    use crate::math::{Mat3, Vec3};

    #[test]
    fn axis_alignment_is_a_rotation_taking_z_to_the_axis() {
        for a in [
            Vec3::z(),
            -Vec3::z(),
            Vec3::x(),
            -Vec3::y(),
            Vec3::new(0.3, -0.4, 0.5).normalize(),
            Vec3::new(1e-9, 0.0, -1.0).normalize(),
        ] {
            let r = axis_alignment(&a);
            assert!((r * Vec3::z() - a).norm() < 1e-15, "{a:?}");
            assert!((r.transpose() * r - Mat3::identity()).amax() < 1e-15);
            assert!((r.determinant() - 1.0).abs() < 1e-15);
        }
    }
}
