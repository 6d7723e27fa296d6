//! The URDF reader: the serial chain between two links of a URDF robot, with
//! the fixed joints on it merged and whatever hangs off it lumped in.
//!
//! [`read_urdf`] reads the elements a chain's dynamics needs — `<robot>`,
//! `<link>` with its `<inertial>` (`<origin xyz rpy>`, `<mass value>`,
//! `<inertia ixx … izz>`) and `<joint>` (`type`, `<origin>`, `<axis>`,
//! `<limit>`, `<parent>`, `<child>`) — and skips everything else (`visual`,
//! `collision`, `material`, `transmission`, `gazebo`, `dynamics`,
//! `calibration`, `safety_controller`, unknown elements). It then builds the
//! chain from `base_link` to `tip_link`:
//!
//! * each moving joint (revolute, continuous, prismatic) starts a body, its
//!   child link; the fixed joints on the chain are merged, the inertial of a
//!   rigidly attached link combined exactly into the body (masses summed,
//!   combined centre of mass, inertia about it by the parallel-axis theorem),
//!   the placement of the next joint composed through them;
//! * links hanging off the chain (a subtree attached to a chain link through
//!   joints of any type) are lumped into the body they hang on, at their
//!   joints' zero position, with a warning naming them; subtrees of massless
//!   links attached only through fixed joints (tool frames and the like) are
//!   lumped silently, as that changes nothing;
//! * the links before the first moving joint belong to the fixed base: their
//!   mass is ignored, and the first joint is placed in the `base_link` frame;
//! * the fixed joints after the last moving joint give the placement of
//!   `tip_link` in the last body.
//!
//! Conventions of the URDF specification: `rpy` is R = Rz(yaw)·Ry(pitch)·Rx(roll);
//! the joint frame is the child link frame at q = 0; the inertia is given about
//! the centre of mass in the frame of `<inertial><origin>`.
//!
//! Judgments where the specification leaves room, all documented in the
//! messages:
//! * a link with mass 0 and a nonzero (positive semi-definite) inertia is
//!   accepted (pybullet's files use mass 0 for static bases); when it is part
//!   of a body its inertia is kept as given and a warning says so;
//! * `<mimic>` is refused on the joints of the chain only: a mimicking joint
//!   off the chain is lumped at its zero position like any other off-chain
//!   joint (a gripper's second finger);
//! * `floating`, `planar` and unknown joint types are refused wherever they
//!   are in the file; a zero `<axis>` is refused on moving joints, ignored on
//!   fixed ones (exporters write `0 0 0` there);
//! * an element of which the reader uses one (`<inertial>`, `<origin>`,
//!   `<mass>`, `<inertia>`, `<axis>`, `<limit>`, `<parent>`, `<child>`) given
//!   twice in the same parent is refused as contradicting;
//! * `<limit>` values are returned as given (each optional), only checked to
//!   be numbers.

use std::collections::HashMap;
use std::fmt::Write as _;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

use crate::error::ModelError;
use crate::math::{Mat3, Vec3};
use crate::model::JointKind;

/// Relative margin below which a violation of the triangle inequality of the
/// principal moments is taken as rounding.
const TRIANGLE_TOLERANCE: f64 = 1e-12;

/// Mass properties of a body, in the frame of its link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UrdfInertial {
    /// Mass, kg (≥ 0).
    pub mass: f64,
    /// Centre of mass in the link frame, m (zero when the mass is 0).
    pub com: Vec3,
    /// Inertia tensor about the centre of mass, resolved in the link frame, kg·m².
    pub inertia: Mat3,
}

impl UrdfInertial {
    /// No mass, no inertia.
    pub fn zero() -> UrdfInertial {
        UrdfInertial { mass: 0.0, com: Vec3::zeros(), inertia: Mat3::zeros() }
    }
}

/// The `<limit>` of a joint, its attributes as given (absent ones `None`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UrdfLimit {
    /// `lower`, rad or m.
    pub lower: Option<f64>,
    /// `upper`, rad or m.
    pub upper: Option<f64>,
    /// `velocity`, rad/s or m/s.
    pub velocity: Option<f64>,
    /// `effort`, N·m or N.
    pub effort: Option<f64>,
}

/// A moving joint of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfChainJoint {
    /// The URDF joint name.
    pub name: String,
    /// Revolute (URDF `revolute` and `continuous`) or prismatic.
    pub kind: JointKind,
    /// Rotation of the joint frame in the frame of the previous moving joint's
    /// child body (the first joint: in the `base_link` frame), fixed joints in
    /// between composed in.
    pub rotation: Mat3,
    /// Origin of the joint frame in that frame, m.
    pub translation: Vec3,
    /// Unit axis of the motion, in the joint frame.
    pub axis: Vec3,
    /// The joint's `<limit>`, if it has one.
    pub limit: Option<UrdfLimit>,
}

/// The serial chain between `base_link` and `tip_link`.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfChain {
    /// The link the chain starts from (fixed base).
    pub base_link: String,
    /// The link the chain ends at.
    pub tip_link: String,
    /// The moving joints, base to tip.
    pub joints: Vec<UrdfChainJoint>,
    /// Body i: the child link of joint i with everything rigidly attached to it
    /// (fixed joints on the chain, lumped subtrees) merged in, in the child link
    /// frame. The mass may be 0.
    pub bodies: Vec<UrdfInertial>,
    /// Rotation of the `tip_link` frame in the frame of the last body.
    pub tip_rotation: Mat3,
    /// Origin of the `tip_link` frame in the frame of the last body, m.
    pub tip_translation: Vec3,
    /// What was accepted but deserves a look (lumped links, unusual inertias).
    pub warnings: Vec<String>,
}

/// Reads the chain from `base_link` (default: the root link) to `tip_link`
/// (default: the single leaf below `base_link`) of the URDF document `xml`.
pub fn read_urdf(xml: &str, base_link: Option<&str>, tip_link: Option<&str>) -> Result<UrdfChain, ModelError> {
    let robot = parse(xml)?;
    let tree = Tree::new(&robot)?;
    build_chain(&robot, &tree, base_link, tip_link)
}

// ---------------------------------------------------------------------------
// Rigid transforms and rotations.

/// A rigid transform: x_parent = rotation · x_child + translation.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Transform {
    rotation: Mat3,
    translation: Vec3,
}

impl Transform {
    fn identity() -> Transform {
        Transform { rotation: Mat3::identity(), translation: Vec3::zeros() }
    }

    /// self ∘ other: `other` maps c → b, `self` maps b → a.
    fn then(&self, other: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }
}

/// R = Rz(yaw)·Ry(pitch)·Rx(roll), the URDF `rpy` convention.
fn rpy_matrix(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    let rx = Mat3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
    let ry = Mat3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
    let rz = Mat3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0);
    rz * ry * rx
}

fn symmetric(m: Mat3) -> Mat3 {
    (m + m.transpose()) * 0.5
}

/// R·I·Rᵀ, symmetrized.
fn rotate_inertia(rotation: &Mat3, inertia: &Mat3) -> Mat3 {
    symmetric(rotation * inertia * rotation.transpose())
}

/// Principal moments, ascending.
fn principal_moments(inertia: &Mat3) -> [f64; 3] {
    let eig = nalgebra::SymmetricEigen::new(symmetric(*inertia)).eigenvalues;
    let mut m = [eig[0], eig[1], eig[2]];
    m.sort_by(f64::total_cmp);
    m
}

// ---------------------------------------------------------------------------
// The document as read.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum UrdfJointType {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
}

#[derive(Debug, Clone)]
struct LinkData {
    name: String,
    /// In the link frame; `None` without `<inertial>`.
    inertial: Option<UrdfInertial>,
}

#[derive(Debug, Clone)]
struct JointData {
    name: String,
    kind: UrdfJointType,
    origin: Transform,
    /// Unit; (1, 0, 0) by default; meaningless for fixed joints.
    axis: Vec3,
    limit: Option<UrdfLimit>,
    parent: String,
    child: String,
    mimic: bool,
}

#[derive(Debug, Default)]
struct Robot {
    links: Vec<LinkData>,
    joints: Vec<JointData>,
}

fn urdf_error(element: impl Into<String>, reason: impl Into<String>) -> ModelError {
    ModelError::Urdf { element: element.into(), reason: reason.into() }
}

fn link_element(name: &str) -> String {
    format!("<link name=\"{name}\">")
}

fn joint_element(name: &str) -> String {
    format!("<joint name=\"{name}\">")
}

/// The attributes of one element, as (key, value) in document order.
struct Attributes {
    element: String,
    pairs: Vec<(String, String)>,
}

impl Attributes {
    fn read(element: String, start: &BytesStart<'_>) -> Result<Attributes, ModelError> {
        let mut pairs = Vec::new();
        for attr in start.attributes() {
            let attr = attr.map_err(|e| urdf_error(&element, format!("malformed attribute: {e}")))?;
            let key = String::from_utf8_lossy(attr.key.as_ref()).into_owned();
            let value = attr
                .normalized_value(XmlVersion::Implicit1_0)
                .map_err(|e| urdf_error(&element, format!("attribute `{key}`: {e}")))?
                .into_owned();
            pairs.push((key, value));
        }
        Ok(Attributes { element, pairs })
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.pairs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    fn required(&self, key: &str) -> Result<&str, ModelError> {
        self.get(key).ok_or_else(|| urdf_error(&self.element, format!("attribute `{key}` is missing")))
    }

    fn number(&self, key: &str, text: &str) -> Result<f64, ModelError> {
        let t = text.trim();
        let value: f64 = t
            .parse()
            .map_err(|_| urdf_error(&self.element, format!("attribute `{key}` = \"{text}\" is not a number")))?;
        if !value.is_finite() {
            return Err(urdf_error(&self.element, format!("attribute `{key}` = \"{text}\" is not finite")));
        }
        Ok(value)
    }

    fn optional_number(&self, key: &str) -> Result<Option<f64>, ModelError> {
        self.get(key).map(|text| self.number(key, text)).transpose()
    }

    fn required_number(&self, key: &str) -> Result<f64, ModelError> {
        self.number(key, self.required(key)?)
    }

    /// Three numbers separated by white space; `default` when absent.
    fn triple(&self, key: &str, default: Vec3) -> Result<Vec3, ModelError> {
        let Some(text) = self.get(key) else {
            return Ok(default);
        };
        let parts: Vec<&str> = text.split_whitespace().collect();
        if parts.len() != 3 {
            return Err(urdf_error(
                &self.element,
                format!("attribute `{key}` = \"{text}\" must be 3 numbers separated by spaces, has {}", parts.len()),
            ));
        }
        let mut v = Vec3::zeros();
        for (i, p) in parts.iter().enumerate() {
            v[i] = self.number(key, p).map_err(|_| {
                urdf_error(&self.element, format!("attribute `{key}` = \"{text}\": `{p}` is not a finite number"))
            })?;
        }
        Ok(v)
    }

    /// `<origin xyz rpy>` (both default 0).
    fn origin(&self) -> Result<Transform, ModelError> {
        let xyz = self.triple("xyz", Vec3::zeros())?;
        let rpy = self.triple("rpy", Vec3::zeros())?;
        Ok(Transform { rotation: rpy_matrix(rpy.x, rpy.y, rpy.z), translation: xyz })
    }
}

#[derive(Default)]
struct InertialBuilder {
    origin: Option<Transform>,
    mass: Option<f64>,
    inertia: Option<Mat3>,
}

struct LinkBuilder {
    name: String,
    inertial: Option<UrdfInertial>,
    seen_inertial: bool,
}

struct JointBuilder {
    name: String,
    kind: UrdfJointType,
    origin: Option<Transform>,
    axis: Option<Vec3>,
    limit: Option<UrdfLimit>,
    parent: Option<String>,
    child: Option<String>,
    mimic: bool,
}

/// The streaming parser's state: the open elements and what is being built.
struct Parser {
    stack: Vec<String>,
    robot: Robot,
    link: Option<LinkBuilder>,
    inertial: Option<InertialBuilder>,
    joint: Option<JointBuilder>,
    seen_root: bool,
}

/// Stores `value` in `slot`; a second element `<child>` in `parent` is
/// accepted when it says the same as the first, refused when it differs.
fn set_once<T: PartialEq>(slot: &mut Option<T>, value: T, parent: &str, child: &str) -> Result<(), ModelError> {
    match slot {
        Some(old) if *old != value => {
            Err(urdf_error(parent, format!("has two <{child}> elements that differ; give one")))
        }
        _ => {
            *slot = Some(value);
            Ok(())
        }
    }
}

fn duplicate(element: &str, child: &str) -> ModelError {
    urdf_error(element, format!("has two <{child}> elements; give one"))
}

impl Parser {
    fn in_path(&self, path: &[&str]) -> bool {
        self.stack.len() == path.len() && self.stack.iter().zip(path).all(|(a, b)| a == b)
    }

    fn link_name(&self) -> &str {
        self.link.as_ref().map_or("", |l| l.name.as_str())
    }

    fn joint_name(&self) -> &str {
        self.joint.as_ref().map_or("", |j| j.name.as_str())
    }

    fn open(&mut self, name: &str, start: &BytesStart<'_>) -> Result<(), ModelError> {
        if self.stack.is_empty() {
            if self.seen_root {
                return Err(urdf_error(
                    "<robot>",
                    format!("a second root element <{name}> follows the <robot> element"),
                ));
            }
            if name != "robot" {
                return Err(urdf_error("<robot>", format!("the document's root element is <{name}>, not <robot>")));
            }
            self.seen_root = true;
            return Ok(());
        }
        if self.in_path(&["robot"]) {
            match name {
                "link" => {
                    let a = Attributes::read("<link>".into(), start)?;
                    let link_name = a.required("name")?.to_string();
                    self.link = Some(LinkBuilder { name: link_name, inertial: None, seen_inertial: false });
                }
                "joint" => {
                    let a = Attributes::read("<joint>".into(), start)?;
                    let joint_name = a.required("name")?.to_string();
                    let element = joint_element(&joint_name);
                    let a = Attributes { element: element.clone(), pairs: a.pairs };
                    let kind = match a.required("type")? {
                        "revolute" => UrdfJointType::Revolute,
                        "continuous" => UrdfJointType::Continuous,
                        "prismatic" => UrdfJointType::Prismatic,
                        "fixed" => UrdfJointType::Fixed,
                        t @ ("floating" | "planar" | "spherical") => {
                            return Err(urdf_error(
                                element,
                                format!(
                                    "type `{t}` is not supported: the engine models serial chains of revolute \
                                     and prismatic joints (fixed joints are merged)"
                                ),
                            ))
                        }
                        t => {
                            return Err(urdf_error(
                                element,
                                format!("unknown joint type `{t}` (revolute, continuous, prismatic or fixed)"),
                            ))
                        }
                    };
                    self.joint = Some(JointBuilder {
                        name: joint_name,
                        kind,
                        origin: None,
                        axis: None,
                        limit: None,
                        parent: None,
                        child: None,
                        mimic: false,
                    });
                }
                _ => {}
            }
            return Ok(());
        }
        if self.in_path(&["robot", "link"]) && name == "inertial" {
            let element = link_element(self.link_name());
            let link = self.link.as_mut().expect("inside <link>");
            if link.seen_inertial {
                return Err(duplicate(&element, "inertial"));
            }
            link.seen_inertial = true;
            self.inertial = Some(InertialBuilder::default());
            return Ok(());
        }
        if self.in_path(&["robot", "link", "inertial"]) {
            let element = format!("{}<inertial><{name}>", link_element(self.link_name()));
            let parent = format!("{}<inertial>", link_element(self.link_name()));
            let inertial = self.inertial.as_mut().expect("inside <inertial>");
            match name {
                "origin" => {
                    let origin = Attributes::read(element, start)?.origin()?;
                    set_once(&mut inertial.origin, origin, &parent, name)?;
                }
                "mass" => {
                    let a = Attributes::read(element, start)?;
                    let mass = a.required_number("value")?;
                    if mass < 0.0 {
                        return Err(urdf_error(&a.element, format!("value = {mass} is negative")));
                    }
                    set_once(&mut inertial.mass, mass, &parent, name)?;
                }
                "inertia" => {
                    let a = Attributes::read(element, start)?;
                    let mut v = [0.0; 6];
                    for (slot, key) in v.iter_mut().zip(["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]) {
                        *slot = a.required_number(key)?;
                    }
                    let [ixx, ixy, ixz, iyy, iyz, izz] = v;
                    let inertia = Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
                    set_once(&mut inertial.inertia, inertia, &parent, name)?;
                }
                _ => {}
            }
            return Ok(());
        }
        if self.in_path(&["robot", "joint"]) {
            let parent = joint_element(self.joint_name());
            let element = format!("{parent}<{name}>");
            let joint = self.joint.as_mut().expect("inside <joint>");
            match name {
                "origin" => {
                    let origin = Attributes::read(element, start)?.origin()?;
                    set_once(&mut joint.origin, origin, &parent, name)?;
                }
                "axis" => {
                    let a = Attributes::read(element, start)?;
                    let axis = a.triple("xyz", Vec3::new(1.0, 0.0, 0.0))?;
                    let norm = axis.norm();
                    // A zero axis is refused for moving joints when the joint
                    // is complete; it is meaningless for fixed ones.
                    let axis = if norm > 0.0 { axis / norm } else { axis };
                    set_once(&mut joint.axis, axis, &parent, name)?;
                }
                "limit" => {
                    let a = Attributes::read(element, start)?;
                    let limit = UrdfLimit {
                        lower: a.optional_number("lower")?,
                        upper: a.optional_number("upper")?,
                        velocity: a.optional_number("velocity")?,
                        effort: a.optional_number("effort")?,
                    };
                    set_once(&mut joint.limit, limit, &parent, name)?;
                }
                "parent" | "child" => {
                    let a = Attributes::read(element, start)?;
                    let link = a.required("link")?.to_string();
                    let slot = if name == "parent" { &mut joint.parent } else { &mut joint.child };
                    set_once(slot, link, &parent, name)?;
                }
                "mimic" => joint.mimic = true,
                _ => {}
            }
        }
        Ok(())
    }

    fn close(&mut self, name: &str) -> Result<(), ModelError> {
        if self.in_path(&["robot", "link", "inertial"]) && name == "inertial" {
            self.finish_inertial()
        } else if self.in_path(&["robot", "link"]) && name == "link" {
            let link = self.link.take().expect("inside <link>");
            self.robot.links.push(LinkData { name: link.name, inertial: link.inertial });
            Ok(())
        } else if self.in_path(&["robot", "joint"]) && name == "joint" {
            self.finish_joint()
        } else {
            Ok(())
        }
    }

    fn finish_inertial(&mut self) -> Result<(), ModelError> {
        let b = self.inertial.take().expect("inside <inertial>");
        let link = self.link.as_mut().expect("inside <link>");
        let element = format!("{}<inertial>", link_element(&link.name));
        let mass = b.mass.ok_or_else(|| urdf_error(&element, "has no <mass>"))?;
        let inertia = b.inertia.ok_or_else(|| urdf_error(&element, "has no <inertia>"))?;
        let origin = b.origin.unwrap_or_else(Transform::identity);
        link.inertial =
            Some(UrdfInertial { mass, com: origin.translation, inertia: rotate_inertia(&origin.rotation, &inertia) });
        Ok(())
    }

    fn finish_joint(&mut self) -> Result<(), ModelError> {
        let j = self.joint.take().expect("inside <joint>");
        let element = joint_element(&j.name);
        let parent = j.parent.ok_or_else(|| urdf_error(&element, "has no <parent link=\"…\"/>"))?;
        let child = j.child.ok_or_else(|| urdf_error(&element, "has no <child link=\"…\"/>"))?;
        if j.axis == Some(Vec3::zeros()) && j.kind != UrdfJointType::Fixed {
            return Err(urdf_error(format!("{element}<axis>"), "xyz is the zero vector; a moving joint needs an axis"));
        }
        self.robot.joints.push(JointData {
            name: j.name,
            kind: j.kind,
            origin: j.origin.unwrap_or_else(Transform::identity),
            axis: j.axis.unwrap_or_else(|| Vec3::new(1.0, 0.0, 0.0)),
            limit: j.limit,
            parent,
            child,
            mimic: j.mimic,
        });
        Ok(())
    }
}

/// A margin in percent, with two significant digits or more.
fn percent(value: f64) -> String {
    if value >= 1.0 {
        format!("{value:.1}")
    } else if value >= 0.01 {
        format!("{value:.2}")
    } else {
        format!("{value:.1e}")
    }
}

fn parse(xml: &str) -> Result<Robot, ModelError> {
    let xml = xml.strip_prefix('\u{feff}').unwrap_or(xml);
    let mut reader = Reader::from_str(xml);
    let mut parser = Parser {
        stack: Vec::new(),
        robot: Robot::default(),
        link: None,
        inertial: None,
        joint: None,
        seen_root: false,
    };
    loop {
        let position = reader.buffer_position();
        let event = reader.read_event().map_err(|e| {
            urdf_error(
                "document",
                format!("is not well-formed XML (near byte {}): {e}", reader.error_position().max(position)),
            )
        })?;
        match event {
            Event::Start(start) => {
                let name = local_name(&start);
                parser.open(&name, &start)?;
                parser.stack.push(name);
            }
            Event::Empty(start) => {
                let name = local_name(&start);
                parser.open(&name, &start)?;
                parser.stack.push(name.clone());
                parser.close(&name)?;
                parser.stack.pop();
            }
            Event::End(end) => {
                let name = String::from_utf8_lossy(end.local_name().as_ref()).into_owned();
                parser.close(&name)?;
                parser.stack.pop();
            }
            Event::Text(text) if parser.stack.is_empty() && !text.iter().all(u8::is_ascii_whitespace) => {
                return Err(urdf_error("document", "is not XML: text outside of any element"));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !parser.seen_root {
        return Err(urdf_error("<robot>", "the document has no <robot> element"));
    }
    if let Some(open) = parser.stack.last() {
        return Err(urdf_error("document", format!("ends inside <{open}>: not well-formed XML")));
    }
    Ok(parser.robot)
}

fn local_name(start: &BytesStart<'_>) -> String {
    String::from_utf8_lossy(start.local_name().as_ref()).into_owned()
}

// ---------------------------------------------------------------------------
// The tree.

struct Tree {
    /// Link name → index into `robot.links`.
    index: HashMap<String, usize>,
    /// Per link: the joint (index into `robot.joints`) whose child it is.
    parent_joint: Vec<Option<usize>>,
    /// Per link: the joints whose parent it is, in document order.
    child_joints: Vec<Vec<usize>>,
    /// Per joint: parent and child link indices.
    ends: Vec<(usize, usize)>,
    root: usize,
}

impl Tree {
    fn new(robot: &Robot) -> Result<Tree, ModelError> {
        let mut index = HashMap::new();
        for (i, link) in robot.links.iter().enumerate() {
            if index.insert(link.name.clone(), i).is_some() {
                return Err(urdf_error(link_element(&link.name), "the link name appears twice"));
            }
        }
        let mut joint_names = HashMap::new();
        for joint in &robot.joints {
            if joint_names.insert(joint.name.as_str(), ()).is_some() {
                return Err(urdf_error(joint_element(&joint.name), "the joint name appears twice"));
            }
        }
        if robot.links.is_empty() {
            return Err(urdf_error("<robot>", "has no <link>"));
        }
        let n = robot.links.len();
        let mut parent_joint: Vec<Option<usize>> = vec![None; n];
        let mut child_joints = vec![Vec::new(); n];
        let mut ends = Vec::with_capacity(robot.joints.len());
        for (j, joint) in robot.joints.iter().enumerate() {
            let element = joint_element(&joint.name);
            let find = |which: &str, name: &str| {
                index
                    .get(name)
                    .copied()
                    .ok_or_else(|| urdf_error(format!("{element}<{which}>"), format!("link `{name}` does not exist")))
            };
            let p = find("parent", &joint.parent)?;
            let c = find("child", &joint.child)?;
            if let Some(other) = parent_joint[c] {
                return Err(urdf_error(
                    link_element(&joint.child),
                    format!(
                        "is the child of two joints, `{}` and `{}`: a URDF is a tree",
                        robot.joints[other].name, joint.name
                    ),
                ));
            }
            parent_joint[c] = Some(j);
            child_joints[p].push(j);
            ends.push((p, c));
        }
        // A loop: following parents from some link never reaches a root.
        for start in 0..n {
            let mut link = start;
            let mut steps = 0;
            while let Some(j) = parent_joint[link] {
                link = ends[j].0;
                steps += 1;
                if steps > n {
                    // `link` is now on the loop: list it.
                    let first = link;
                    let mut names = vec![robot.links[first].name.clone()];
                    let mut joints = Vec::new();
                    let mut l = first;
                    loop {
                        let j = parent_joint[l].expect("on the loop");
                        joints.push(format!("`{}`", robot.joints[j].name));
                        l = ends[j].0;
                        names.push(robot.links[l].name.clone());
                        if l == first {
                            break;
                        }
                    }
                    names.reverse();
                    joints.reverse();
                    let first_joint = parent_joint[first].expect("on the loop");
                    return Err(urdf_error(
                        joint_element(&robot.joints[first_joint].name),
                        format!(
                            "closes a loop: joints {} connect links {} in a cycle; a URDF is a tree",
                            joints.join(", "),
                            names.join(" -> ")
                        ),
                    ));
                }
            }
        }
        let roots: Vec<usize> = (0..n).filter(|&i| parent_joint[i].is_none()).collect();
        if roots.len() != 1 {
            let names: Vec<String> = roots.iter().map(|&i| format!("`{}`", robot.links[i].name)).collect();
            return Err(urdf_error(
                "<robot>",
                format!(
                    "has {} root links ({}), links that are no joint's child: a URDF tree has exactly one",
                    roots.len(),
                    names.join(", ")
                ),
            ));
        }
        Ok(Tree { index, parent_joint, child_joints, ends, root: roots[0] })
    }

    /// The links of the subtree below `link` that have no children, in
    /// depth-first document order.
    fn leaves_below(&self, link: usize) -> Vec<usize> {
        let mut leaves = Vec::new();
        let mut todo = vec![link];
        while let Some(l) = todo.pop() {
            if self.child_joints[l].is_empty() {
                leaves.push(l);
            }
            for &j in self.child_joints[l].iter().rev() {
                todo.push(self.ends[j].1);
            }
        }
        leaves
    }
}

// ---------------------------------------------------------------------------
// The chain.

/// Mass properties collected for one body: each part's mass, centre of mass
/// and inertia about it, in the body frame.
#[derive(Default)]
struct BodyParts {
    parts: Vec<(f64, Vec3, Mat3)>,
}

impl BodyParts {
    /// Adds `inertial`, given in a frame placed in the body by `placement`.
    fn add(&mut self, inertial: &UrdfInertial, placement: &Transform) {
        let com = placement.rotation * inertial.com + placement.translation;
        let inertia = rotate_inertia(&placement.rotation, &inertial.inertia);
        self.parts.push((inertial.mass, com, inertia));
    }

    /// The exact combination: total mass, combined centre of mass, inertia
    /// about it by the parallel-axis theorem.
    fn combine(&self) -> UrdfInertial {
        let mass: f64 = self.parts.iter().map(|p| p.0).sum();
        let com = if mass > 0.0 {
            self.parts.iter().fold(Vec3::zeros(), |acc, (m, c, _)| acc + c * (m / mass))
        } else {
            Vec3::zeros()
        };
        let mut inertia = Mat3::zeros();
        for (m, c, i) in &self.parts {
            let d = c - com;
            inertia += i + (Mat3::identity() * d.norm_squared() - d * d.transpose()) * *m;
        }
        UrdfInertial { mass, com, inertia: symmetric(inertia) }
    }
}

fn build_chain(
    robot: &Robot,
    tree: &Tree,
    base_link: Option<&str>,
    tip_link: Option<&str>,
) -> Result<UrdfChain, ModelError> {
    let lookup = |key: &str, name: &str| {
        tree.index
            .get(name)
            .copied()
            .ok_or_else(|| urdf_error(format!("{key} = \"{name}\""), format!("the URDF has no link named `{name}`")))
    };
    let base = match base_link {
        Some(name) => lookup("base_link", name)?,
        None => tree.root,
    };
    let base_name = &robot.links[base].name;
    let tip = match tip_link {
        Some(name) => lookup("tip_link", name)?,
        None => {
            let leaves = tree.leaves_below(base);
            if leaves.len() != 1 {
                let names: Vec<String> = leaves.iter().map(|&i| format!("`{}`", robot.links[i].name)).collect();
                return Err(urdf_error(
                    "tip_link",
                    format!(
                        "is not given, and the tree below `{base_name}` has {} leaves ({}): name one as tip_link",
                        leaves.len(),
                        names.join(", ")
                    ),
                ));
            }
            leaves[0]
        }
    };
    let tip_name = &robot.links[tip].name;
    // The joints from base to tip.
    let mut path = Vec::new();
    let mut link = tip;
    while link != base {
        match tree.parent_joint[link] {
            Some(j) => {
                path.push(j);
                link = tree.ends[j].0;
            }
            None => {
                return Err(urdf_error(
                    format!("tip_link = \"{tip_name}\""),
                    format!("link `{tip_name}` is not below base_link `{base_name}`"),
                ))
            }
        }
    }
    path.reverse();
    let chain_element = format!("chain `{base_name}` -> `{tip_name}`");
    if path.iter().all(|&j| robot.joints[j].kind == UrdfJointType::Fixed) {
        let reason = if path.is_empty() {
            "is empty (base_link and tip_link are the same link): it has no moving joint".to_string()
        } else {
            "has no moving joint, only fixed ones".to_string()
        };
        return Err(urdf_error(chain_element, reason));
    }
    for &j in &path {
        let joint = &robot.joints[j];
        if joint.mimic {
            return Err(urdf_error(
                format!("{}<mimic>", joint_element(&joint.name)),
                "a joint of the chain cannot mimic another: the engine has no coupled joints",
            ));
        }
    }
    let on_path: Vec<bool> = {
        let mut v = vec![false; robot.joints.len()];
        for &j in &path {
            v[j] = true;
        }
        v
    };

    let mut joints = Vec::new();
    let mut bodies: Vec<BodyParts> = Vec::new();
    let mut warnings = Vec::new();
    // Frame of the current chain link in the current body (before the first
    // moving joint: in the base_link frame).
    let mut placement = Transform::identity();
    for &j in &path {
        let joint = &robot.joints[j];
        let child = tree.ends[j].1;
        let joint_placement = placement.then(&joint.origin);
        let kind = match joint.kind {
            UrdfJointType::Fixed => None,
            UrdfJointType::Revolute | UrdfJointType::Continuous => Some(JointKind::Revolute),
            UrdfJointType::Prismatic => Some(JointKind::Prismatic),
        };
        match kind {
            Some(kind) => {
                joints.push(UrdfChainJoint {
                    name: joint.name.clone(),
                    kind,
                    rotation: joint_placement.rotation,
                    translation: joint_placement.translation,
                    axis: joint.axis,
                    limit: joint.limit,
                });
                bodies.push(BodyParts::default());
                placement = Transform::identity();
            }
            None => placement = joint_placement,
        }
        if let Some(body) = bodies.last_mut() {
            add_link(robot, child, &placement, body, &mut warnings)?;
            lump_off_chain(robot, tree, child, &placement, &on_path, body, &mut warnings)?;
        }
    }
    Ok(UrdfChain {
        base_link: base_name.clone(),
        tip_link: tip_name.clone(),
        joints,
        bodies: bodies.iter().map(BodyParts::combine).collect(),
        tip_rotation: placement.rotation,
        tip_translation: placement.translation,
        warnings,
    })
}

/// Adds the inertial of `link`, placed by `placement` in the body, after
/// checking it.
fn add_link(
    robot: &Robot,
    link: usize,
    placement: &Transform,
    body: &mut BodyParts,
    warnings: &mut Vec<String>,
) -> Result<(), ModelError> {
    let data = &robot.links[link];
    if let Some(inertial) = &data.inertial {
        check_inertial(&data.name, inertial, warnings)?;
        body.add(inertial, placement);
    }
    Ok(())
}

/// Refuses an inertia no body can have (not positive definite with mass, a
/// negative principal moment without), and warns of an unusual one (mass 0
/// with inertia; principal moments violating the triangle inequality).
/// Checked only for the links that enter a body: the base's are ignored.
fn check_inertial(name: &str, inertial: &UrdfInertial, warnings: &mut Vec<String>) -> Result<(), ModelError> {
    let mass = inertial.mass;
    let moments = principal_moments(&inertial.inertia);
    let shown = format!("{:.4e}, {:.4e}, {:.4e}", moments[0], moments[1], moments[2]);
    let element = format!("{}<inertial><inertia>", link_element(name));
    if mass > 0.0 {
        if moments[0] <= 0.0 {
            return Err(urdf_error(
                element,
                format!(
                    "is not positive definite (principal moments {shown}) for mass {mass}: \
                     a body with mass has positive principal moments"
                ),
            ));
        }
    } else if moments[0] < 0.0 {
        return Err(urdf_error(element, format!("has a negative principal moment (principal moments {shown})")));
    } else if inertial.inertia != Mat3::zeros() {
        warnings
            .push(format!("link `{name}`: mass 0 with a nonzero inertia (principal moments {shown}); kept as given"));
    }
    let [i1, i2, i3] = moments;
    if i3 > 0.0 && i1 + i2 < i3 * (1.0 - TRIANGLE_TOLERANCE) {
        let margin = (i3 - i1 - i2) / i3 * 100.0;
        warnings.push(format!(
            "link `{name}`: principal moments {shown} violate I1 + I2 >= I3 by {} %; \
             accepted as given (MuJoCo would need balanceinertia)",
            percent(margin)
        ));
    }
    Ok(())
}

/// Lumps the subtrees hanging off the chain link `link` (placed by
/// `placement` in the body) into the body, at their joints' zero position.
fn lump_off_chain(
    robot: &Robot,
    tree: &Tree,
    link: usize,
    placement: &Transform,
    on_path: &[bool],
    body: &mut BodyParts,
    warnings: &mut Vec<String>,
) -> Result<(), ModelError> {
    let mut lumped = Vec::new();
    let mut matters = false;
    let mut todo: Vec<(usize, Transform)> =
        tree.child_joints[link].iter().rev().filter(|&&j| !on_path[j]).map(|&j| (j, *placement)).collect();
    while let Some((j, parent_placement)) = todo.pop() {
        let joint = &robot.joints[j];
        let child = tree.ends[j].1;
        let child_placement = parent_placement.then(&joint.origin);
        add_link(robot, child, &child_placement, body, warnings)?;
        if joint.kind != UrdfJointType::Fixed
            || robot.links[child].inertial.is_some_and(|i| i.mass > 0.0 || i.inertia != Mat3::zeros())
        {
            matters = true;
        }
        lumped.push(robot.links[child].name.as_str());
        for &k in tree.child_joints[child].iter().rev() {
            todo.push((k, child_placement));
        }
    }
    if matters {
        let mut names = String::new();
        for (i, name) in lumped.iter().enumerate() {
            let _ = write!(names, "{}`{name}`", if i == 0 { "" } else { ", " });
        }
        let chain_link = &robot.links[link].name;
        warnings.push(if lumped.len() == 1 {
            format!(
                "link {names} hangs off the chain at `{chain_link}` and is lumped into it \
                 at its joint's zero position"
            )
        } else {
            format!(
                "links {names} hang off the chain at `{chain_link}` and are lumped into it \
                 at their joints' zero position"
            )
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_is_fixed_axis_xyz() {
        let (r, p, y) = (0.3, -0.7, 1.1);
        let rx = nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), r);
        let ry = nalgebra::Rotation3::from_axis_angle(&Vec3::y_axis(), p);
        let rz = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), y);
        let expected = (rz * ry * rx).into_inner();
        assert!((rpy_matrix(r, p, y) - expected).amax() < 1e-15);
    }

    #[test]
    fn combine_of_one_part_is_exact() {
        let i = UrdfInertial {
            mass: 1.7,
            com: Vec3::new(0.1, 0.2, 0.3),
            inertia: Mat3::new(1.0, 0.1, 0.2, 0.1, 2.0, 0.3, 0.2, 0.3, 3.0),
        };
        let mut body = BodyParts::default();
        body.add(&i, &Transform::identity());
        assert_eq!(body.combine(), i);
    }

    #[test]
    fn triple_accepts_any_whitespace() {
        let a = Attributes { element: "<x>".into(), pairs: vec![("xyz".into(), " 1\t2\n 3 ".into())] };
        assert_eq!(a.triple("xyz", Vec3::zeros()).unwrap(), Vec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn percent_keeps_small_margins_readable() {
        assert_eq!(percent(0.7), "0.70");
        assert_eq!(percent(12.34), "12.3");
        assert_eq!(percent(0.0012), "1.2e-3");
    }
}
