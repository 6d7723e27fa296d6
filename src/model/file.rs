//! The model file: a human-readable TOML description of a chain, by
//! Denavit–Hartenberg rows (`[[joint]]`) or by a URDF file it names (`urdf`,
//! with `[joints.<URDF joint name>]` for what URDF does not carry).
//!
//! See `models/reference_rrpr.toml` and `models/urdf/*/*.toml` for complete,
//! commented examples. Unknown keys are rejected so that a misspelt
//! parameter never silently falls back to a default.

use std::collections::BTreeMap;

use super::urdf::read_urdf;
use super::urdf_model::{JointExtras, UrdfModelSpec};
use super::{
    ContactGeometry, DhJoint, DhRow, Drive, FrictionCoefficients, IntegratorSettings, JointFriction, JointKind, Link,
    Model, Rotor,
};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    name: Option<String>,
    gravity: Option<[f64; 3]>,
    end_point: Option<[f64; 3]>,
    integrator: Option<IntegratorFile>,
    #[serde(default)]
    joint: Vec<JointFile>,
    /// A URDF file, relative to the model file.
    urdf: Option<String>,
    base_link: Option<String>,
    tip_link: Option<String>,
    /// Drives and friction of URDF joints, by joint name.
    joints: Option<BTreeMap<String, UrdfJointFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UrdfJointFile {
    drive: Option<DriveFile>,
    friction: Option<FrictionFile>,
    bearings: Option<BearingsFile>,
    slider: Option<SliderFile>,
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
    /// A flexible gear driven by a motor rotor (torque input).
    Motor {
        k: f64,
        #[serde(default)]
        h: f64,
        #[serde(default)]
        clearance: f64,
        gear_ratio: f64,
        rotor_inertia: f64,
        #[serde(default)]
        motor_viscous: f64,
        #[serde(default)]
        motor_coulomb: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FrictionFile {
    mu_k: f64,
    mu_s: f64,
    #[serde(default)]
    v_s: f64,
    /// b of the viscous part b·q̇, N·s/m or N·m·s/rad.
    #[serde(default)]
    viscous: f64,
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

/// The reference manipulator with motor drives on joints 1 and 3
/// (`models/reference_rrpr_motor.toml`), compiled into the library.
pub const REFERENCE_RRPR_MOTOR_TOML: &str = include_str!("../../models/reference_rrpr_motor.toml");

/// A model file's text with the text of the URDF it names, if any: what an
/// FMU carries in `resources/` and what its GUID fingerprints.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelSource {
    /// The model file (TOML).
    pub toml: String,
    /// The URDF it names (`urdf`), as text.
    pub urdf: Option<String>,
}

impl ModelSource {
    /// A model file without a URDF.
    pub fn toml(text: impl Into<String>) -> ModelSource {
        ModelSource { toml: text.into(), urdf: None }
    }

    /// The text a fingerprint of the model is taken over: the model file,
    /// followed by the URDF where there is one (so that a changed URDF is a
    /// different model).
    pub fn fingerprint_text(&self) -> std::borrow::Cow<'_, str> {
        match &self.urdf {
            None => std::borrow::Cow::Borrowed(&self.toml),
            Some(urdf) => std::borrow::Cow::Owned(format!("{}\n# --- URDF ---\n{urdf}", self.toml)),
        }
    }

    /// Parses and validates the model; the URDF is taken from `self.urdf`
    /// whatever name the model file gives it.
    pub fn model(&self) -> Result<Model, ModelError> {
        Model::from_toml_with(&self.toml, &|name| {
            self.urdf.clone().ok_or_else(|| ModelError::Io {
                path: name.into(),
                reason: "the model names a URDF, but none was supplied with it".into(),
            })
        })
    }
}

/// The model text with its `urdf = "…"` line naming `file_name` instead:
/// how the packaging writes `resources/model.toml` beside the URDF it copies
/// into `resources/`. `None` when the text has no such line of its own (the
/// caller then keeps the text and reports).
pub fn with_urdf_file_name(text: &str, file_name: &str) -> Option<String> {
    let mut found = false;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            let t = line.trim_start();
            let is_key = t.strip_prefix("urdf").is_some_and(|rest| rest.trim_start().starts_with('='));
            if is_key && !found {
                found = true;
                format!(
                    "urdf = {:?}   # packaged into resources/ beside this file (the model file said: {})",
                    file_name, t
                )
            } else {
                line.to_string()
            }
        })
        .collect();
    let rewritten = lines.join("\n") + "\n";
    (found && Model::urdf_reference(&rewritten).as_deref() == Some(file_name)).then_some(rewritten)
}

/// The gravity of a URDF model without `gravity`: 9.81 m/s² along −z of the
/// base frame.
const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

impl Model {
    /// Parses and validates a model from TOML text; a URDF it names is read
    /// relative to the current directory.
    pub fn from_toml_str(text: &str) -> Result<Model, ModelError> {
        Model::from_toml_with(text, &|path| {
            std::fs::read_to_string(path).map_err(|e| ModelError::Io { path: path.into(), reason: e.to_string() })
        })
    }

    /// Parses and validates a model from TOML text; `read_file` returns the
    /// text of a file the model names (its `urdf`), given the name as written.
    pub fn from_toml_with(
        text: &str,
        read_file: &dyn Fn(&str) -> Result<String, ModelError>,
    ) -> Result<Model, ModelError> {
        let file: ModelFile = toml::from_str(text).map_err(|e| ModelError::Syntax { reason: e.to_string() })?;
        let defaults = IntegratorSettings::default();
        let integrator = match &file.integrator {
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
        match &file.urdf {
            Some(path) => urdf_model(&file, path, read_file, integrator),
            None => dh_model(&file, integrator),
        }
    }

    /// Reads, parses and validates a model file; a URDF it names is read
    /// relative to the model file's directory.
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Model, ModelError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| ModelError::Io { path: path.display().to_string(), reason: e.to_string() })?;
        let dir = path.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
        Model::from_toml_with(&text, &|name| {
            let file = dir.join(name);
            std::fs::read_to_string(&file)
                .map_err(|e| ModelError::Io { path: file.display().to_string(), reason: e.to_string() })
        })
    }

    /// The URDF file a model text names (its `urdf` key), if any; `None`
    /// also for text that is not a model file (its parse reports that).
    pub fn urdf_reference(text: &str) -> Option<String> {
        toml::from_str::<toml::Table>(text).ok()?.get("urdf")?.as_str().map(str::to_string)
    }

    /// The reference RRPR manipulator of `shared/reference-manipulator.md`,
    /// from `models/reference_rrpr.toml`.
    pub fn reference_rrpr() -> Model {
        Model::from_toml_str(REFERENCE_RRPR_TOML).expect("the shipped reference model is valid")
    }

    /// The reference manipulator with motor drives on joints 1 and 3, from
    /// `models/reference_rrpr_motor.toml`.
    pub fn reference_rrpr_motor() -> Model {
        Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).expect("the shipped motor reference model is valid")
    }
}

fn missing(field: &str, what: &str) -> ModelError {
    ModelError::Syntax { reason: format!("missing field `{field}`: {what}") }
}

fn dh_model(file: &ModelFile, integrator: IntegratorSettings) -> Result<Model, ModelError> {
    for (key, present) in [
        ("base_link", file.base_link.is_some()),
        ("tip_link", file.tip_link.is_some()),
        ("joints", file.joints.is_some()),
    ] {
        if present {
            return Err(ModelError::Invalid {
                field: key.into(),
                reason: "belongs to a URDF model; this file has no `urdf` (a Denavit-Hartenberg file gives `[[joint]]` rows)".into(),
            });
        }
    }
    let gravity = file.gravity.ok_or_else(|| missing("gravity", "the gravity vector in frame 0, m/s²"))?;
    let end_point =
        file.end_point.ok_or_else(|| missing("end_point", "the end point in the frame of the last link, m"))?;
    let joints =
        file.joint.iter().enumerate().map(|(i, j)| joint_from_file(i + 1, j)).collect::<Result<Vec<_>, _>>()?;
    let links: Vec<Link> = file.joint.iter().map(|j| link_from_file(&j.link)).collect();
    Model::from_dh(
        file.name.clone().unwrap_or_else(|| "manipulator".into()),
        &joints,
        &links,
        Vec3::from(gravity),
        Vec3::from(end_point),
        integrator,
    )
}

fn urdf_model(
    file: &ModelFile,
    path: &str,
    read_file: &dyn Fn(&str) -> Result<String, ModelError>,
    integrator: IntegratorSettings,
) -> Result<Model, ModelError> {
    if !file.joint.is_empty() {
        return Err(ModelError::Invalid {
            field: "joint".into(),
            reason: "a model file gives either a `urdf` or Denavit-Hartenberg `[[joint]]` rows, not both".into(),
        });
    }
    let xml = read_file(path)?;
    let chain = read_urdf(&xml, file.base_link.as_deref(), file.tip_link.as_deref()).map_err(|e| match e {
        ModelError::Urdf { element, reason } => ModelError::Urdf { element: format!("{path}: {element}"), reason },
        other => other,
    })?;
    let mut extras = BTreeMap::new();
    for (name, entry) in file.joints.iter().flatten() {
        extras.insert(name.clone(), JointExtras::from_file(name, entry)?);
    }
    let stem = std::path::Path::new(path).file_stem().and_then(|s| s.to_str()).unwrap_or("manipulator");
    Model::from_urdf_chain(UrdfModelSpec {
        name: file.name.clone().unwrap_or_else(|| stem.to_string()),
        chain,
        extras,
        gravity: Vec3::from(file.gravity.unwrap_or(DEFAULT_GRAVITY)),
        end_point: Vec3::from(file.end_point.unwrap_or([0.0; 3])),
        integrator,
    })
}

impl JointExtras {
    /// The entry `[joints.<name>]` of a URDF model file; the joint's kind is
    /// checked against the geometry when the chain is known.
    fn from_file(name: &str, entry: &UrdfJointFile) -> Result<JointExtras, ModelError> {
        let field = format!("joints.{name}");
        if entry.bearings.is_some() && entry.slider.is_some() {
            return Err(ModelError::Invalid {
                field,
                reason: "has both `bearings` and `slider`; a joint has one contact geometry".into(),
            });
        }
        let geometry = geometry_from_file(entry.bearings.as_ref(), entry.slider.as_ref());
        Ok(JointExtras {
            drive: entry.drive.as_ref().map_or(Drive::Rigid, drive_from_file),
            friction: friction_from_file(entry.friction.as_ref(), geometry),
            friction_without_geometry: entry.friction.is_some() && geometry.is_none(),
        })
    }
}

fn drive_from_file(d: &DriveFile) -> Drive {
    match *d {
        DriveFile::Rigid => Drive::Rigid,
        DriveFile::Flexible { k, h, clearance } => Drive::Flexible { stiffness: k, damping: h, clearance },
        DriveFile::Motor { k, h, clearance, gear_ratio, rotor_inertia, motor_viscous, motor_coulomb } => Drive::Motor {
            stiffness: k,
            damping: h,
            clearance,
            rotor: Rotor { gear_ratio, inertia: rotor_inertia, viscous: motor_viscous, coulomb: motor_coulomb },
        },
    }
}

fn geometry_from_file(bearings: Option<&BearingsFile>, slider: Option<&SliderFile>) -> Option<ContactGeometry> {
    match (bearings, slider) {
        (Some(b), _) => Some(ContactGeometry::Bearings {
            reaction_point: Vec3::from(b.reaction_point),
            l_a: b.l_a,
            l_b: b.l_b,
            d_a: b.d_a,
            d_b: b.d_b,
            d_c: b.d_c,
        }),
        (None, Some(s)) => Some(ContactGeometry::Slider { centre: Vec3::from(s.centre), a: s.a, b: s.b, c: s.c }),
        (None, None) => None,
    }
}

/// Coefficients with geometry; geometry alone is a frictionless joint whose
/// coefficients can be tuned later; coefficients alone are the caller's
/// error to report.
fn friction_from_file(f: Option<&FrictionFile>, geometry: Option<ContactGeometry>) -> Option<JointFriction> {
    let geometry = geometry?;
    let coefficients = match f {
        Some(f) => {
            FrictionCoefficients { mu_kinetic: f.mu_k, mu_static: f.mu_s, stribeck_velocity: f.v_s, viscous: f.viscous }
        }
        None => FrictionCoefficients { mu_kinetic: 0.0, mu_static: 0.0, stribeck_velocity: 0.0, viscous: 0.0 },
    };
    Some(JointFriction { coefficients, geometry })
}

fn joint_from_file(number: usize, j: &JointFile) -> Result<DhJoint, ModelError> {
    let kind = match j.kind {
        KindFile::Revolute => JointKind::Revolute,
        KindFile::Prismatic => JointKind::Prismatic,
    };
    match (kind, &j.bearings, &j.slider) {
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
        _ => {}
    }
    let geometry = geometry_from_file(j.bearings.as_ref(), j.slider.as_ref());
    if j.friction.is_some() && geometry.is_none() {
        let (field, what) = kind.friction_geometry();
        return Err(ModelError::Invalid {
            field: format!("joint[{number}].{field}"),
            reason: format!("friction on this joint needs {what}"),
        });
    }
    Ok(DhJoint {
        kind,
        dh: DhRow { theta: j.theta, d: j.d, a: j.a, alpha: j.alpha },
        drive: drive_from_file(&j.drive),
        friction: friction_from_file(j.friction.as_ref(), geometry),
    })
}

fn link_from_file(l: &LinkFile) -> Link {
    let i = &l.inertia;
    Link {
        mass: l.mass,
        com: Vec3::from(l.com),
        inertia: Mat3::new(i.xx, i.xy, i.xz, i.xy, i.yy, i.yz, i.xz, i.yz, i.zz),
    }
}
