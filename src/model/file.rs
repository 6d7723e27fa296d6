//! The model file: a human-readable TOML description of a chain.
//!
//! See `models/reference_rrpr.toml` for a complete, commented example. Unknown
//! keys are rejected so that a misspelt parameter never silently falls back to
//! a default.

use super::{
    ContactGeometry, DhRow, Drive, FrictionCoefficients, IntegratorSettings, Joint, JointFriction, JointKind, Link,
    Model,
};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    name: Option<String>,
    gravity: [f64; 3],
    end_point: [f64; 3],
    integrator: Option<IntegratorFile>,
    #[serde(default)]
    joint: Vec<JointFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IntegratorFile {
    h_min: Option<f64>,
    h_max: Option<f64>,
    error_tolerance: Option<f64>,
    beta: Option<f64>,
    gamma: Option<f64>,
    tolerance: Option<f64>,
    max_iterations: Option<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    #[serde(rename = "type")]
    kind: KindFile,
    theta: f64,
    d: f64,
    a: f64,
    alpha: f64,
    drive: DriveFile,
    friction: Option<FrictionFile>,
    bearings: Option<BearingsFile>,
    slider: Option<SliderFile>,
    link: LinkFile,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum KindFile {
    Revolute,
    Prismatic,
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum DriveFile {
    Rigid,
    Flexible {
        k: f64,
        #[serde(default)]
        h: f64,
        #[serde(default)]
        clearance: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FrictionFile {
    mu_k: f64,
    mu_s: f64,
    #[serde(default)]
    v_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BearingsFile {
    reaction_point: [f64; 3],
    l_a: f64,
    l_b: f64,
    d_a: f64,
    d_b: f64,
    d_c: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SliderFile {
    centre: [f64; 3],
    a: f64,
    b: f64,
    c: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkFile {
    mass: f64,
    com: [f64; 3],
    inertia: InertiaFile,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InertiaFile {
    xx: f64,
    yy: f64,
    zz: f64,
    #[serde(default)]
    xy: f64,
    #[serde(default)]
    xz: f64,
    #[serde(default)]
    yz: f64,
}

/// The reference manipulator's model file, compiled into the library.
pub const REFERENCE_RRPR_TOML: &str = include_str!("../../models/reference_rrpr.toml");

impl Model {
    /// Parses and validates a model from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Model, ModelError> {
        let file: ModelFile = toml::from_str(text).map_err(|e| ModelError::Syntax { reason: e.to_string() })?;
        let joints = file
            .joint
            .iter()
            .enumerate()
            .map(|(i, j)| joint_from_file(i + 1, j))
            .collect::<Result<Vec<_>, _>>()?;
        let links = file.joint.iter().map(|j| link_from_file(&j.link)).collect();
        let defaults = IntegratorSettings::default();
        let integrator = match file.integrator {
            None => defaults,
            Some(s) => IntegratorSettings {
                h_min: s.h_min.unwrap_or(defaults.h_min),
                h_max: s.h_max.unwrap_or(defaults.h_max),
                error_tolerance: s.error_tolerance.unwrap_or(defaults.error_tolerance),
                beta: s.beta.unwrap_or(defaults.beta),
                gamma: s.gamma.unwrap_or(defaults.gamma),
                tolerance: s.tolerance.unwrap_or(defaults.tolerance),
                max_iterations: s.max_iterations.unwrap_or(defaults.max_iterations),
            },
        };
        let model = Model {
            name: file.name.unwrap_or_else(|| "manipulator".into()),
            joints,
            links,
            gravity: Vec3::from(file.gravity),
            end_point: Vec3::from(file.end_point),
            integrator,
        };
        model.validate()?;
        Ok(model)
    }

    /// Reads, parses and validates a model file.
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Model, ModelError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| ModelError::Io { path: path.display().to_string(), reason: e.to_string() })?;
        Model::from_toml_str(&text)
    }

    /// The reference RRPR manipulator of `shared/reference-manipulator.md`,
    /// from `models/reference_rrpr.toml`.
    pub fn reference_rrpr() -> Model {
        Model::from_toml_str(REFERENCE_RRPR_TOML).expect("the shipped reference model is valid")
    }
}

fn joint_from_file(number: usize, j: &JointFile) -> Result<Joint, ModelError> {
    let kind = match j.kind {
        KindFile::Revolute => JointKind::Revolute,
        KindFile::Prismatic => JointKind::Prismatic,
    };
    let drive = match j.drive {
        DriveFile::Rigid => Drive::Rigid,
        DriveFile::Flexible { k, h, clearance } => Drive::Flexible { stiffness: k, damping: h, clearance },
    };
    let geometry = match (kind, &j.bearings, &j.slider) {
        (_, Some(_), Some(_)) => {
            return Err(ModelError::Invalid {
                field: format!("joint[{number}]"),
                reason: "has both `bearings` and `slider`; a joint has one contact geometry".into(),
            })
        }
        (JointKind::Prismatic, Some(_), None) => {
            return Err(ModelError::Invalid {
                field: format!("joint[{number}].bearings"),
                reason: "bearing geometry belongs to revolute joints; a prismatic joint takes `slider`".into(),
            })
        }
        (JointKind::Revolute, None, Some(_)) => {
            return Err(ModelError::Invalid {
                field: format!("joint[{number}].slider"),
                reason: "slider geometry belongs to prismatic joints; a revolute joint takes `bearings`".into(),
            })
        }
        (_, Some(b), None) => Some(ContactGeometry::Bearings {
            reaction_point: Vec3::from(b.reaction_point),
            l_a: b.l_a,
            l_b: b.l_b,
            d_a: b.d_a,
            d_b: b.d_b,
            d_c: b.d_c,
        }),
        (_, None, Some(s)) => Some(ContactGeometry::Slider { centre: Vec3::from(s.centre), a: s.a, b: s.b, c: s.c }),
        (_, None, None) => None,
    };
    let friction = match (&j.friction, geometry) {
        (Some(f), Some(geometry)) => Some(JointFriction {
            coefficients: FrictionCoefficients { mu_kinetic: f.mu_k, mu_static: f.mu_s, stribeck_velocity: f.v_s },
            geometry,
        }),
        // Geometry without coefficients: frictionless for now, tunable later.
        (None, Some(geometry)) => Some(JointFriction {
            coefficients: FrictionCoefficients { mu_kinetic: 0.0, mu_static: 0.0, stribeck_velocity: 0.0 },
            geometry,
        }),
        (Some(_), None) => {
            let (field, what) = match kind {
                JointKind::Revolute => ("bearings", "its bearing geometry (reaction_point, l_a, l_b, d_a, d_b, d_c)"),
                JointKind::Prismatic => ("slider", "its slider geometry (centre, a, b, c)"),
            };
            return Err(ModelError::Invalid {
                field: format!("joint[{number}].{field}"),
                reason: format!("friction on this joint needs {what}"),
            });
        }
        (None, None) => None,
    };
    Ok(Joint { kind, dh: DhRow { theta: j.theta, d: j.d, a: j.a, alpha: j.alpha }, drive, friction })
}

fn link_from_file(l: &LinkFile) -> Link {
    let i = &l.inertia;
    Link {
        mass: l.mass,
        com: Vec3::from(l.com),
        inertia: Mat3::new(i.xx, i.xy, i.xz, i.xy, i.yy, i.yz, i.xz, i.yz, i.zz),
    }
}
