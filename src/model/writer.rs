//! The model written back (issue 42, item 4): a [`Model`] read from a model
//! file, then given identified link inertias (`with_standard_parameters`)
//! and tunable parameters (settings), written as a model file again, and for
//! a URDF model with the URDF whose `<inertial>`s hold the new links. The
//! engine reads the written files back to the same model: [`model_file`]
//! checks that before it returns them.
//!
//! The model does not keep everything its file said, so the source it was
//! read from ([`ModelSource`]) supplies the rest: the Denavit–Hartenberg rows
//! (the last row's a and α live only in the link frames and the end point),
//! the URDF document, `base_link` and `tip_link`. Everything a setting or the
//! standard parameters can change comes from the model: links, drives,
//! friction and contact geometry, and so do gravity, the end point, the
//! integrator settings and the name.
//!
//! The frames the readers apply are undone:
//! * Denavit–Hartenberg ([`super::dh`]): the file gives the link data, the
//!   slider centre and the end point in the study's frame i, which the engine
//!   turns into its link frame by T_i = Trans_x(a_i)·Rot_x(α_i); written back
//!   through T_i⁻¹. The bearing reference point, on z_{i−1} in frame i−1, is
//!   the engine's height on the joint axis plus d_i.
//! * URDF ([`super::urdf_model`]): the engine's link frame is the child link
//!   frame turned by R_a; the centre of mass, the inertia and the slider
//!   centre are turned back by R_a, the bearing reference point is put back
//!   on the axis a, and the end point goes back into `tip_link`'s frame
//!   through the fixed joints after the last moving one. The reader merges
//!   into body i the child link of moving joint i and everything rigidly
//!   attached to it (links on fixed joints after it, subtrees hanging off
//!   the chain): the model's link i is written as the child link's
//!   `<inertial>` (origin at the centre of mass, rpy 0, the full tensor about
//!   it), and the `<inertial>` of every other link of the body is removed
//!   (replaced by a comment naming the link that now carries its mass). The
//!   rest of the document is kept byte for byte, and so is the `<inertial>`
//!   of a body whose link did not change and had nothing merged into it.
//!
//! Numbers are written in Rust's shortest round-trip form (`{:?}`), so that
//! reading gives the same bits; a value converted back from the engine's
//! frame is written with 15 significant digits where those give the model's
//! value again through the reader's conversion bit for bit (the file's 0.06,
//! not 0.06000000000000005).

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::ops::Range;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};
use serde::Deserialize;

use super::urdf::{read_urdf, UrdfChain};
use super::{
    axis_alignment, trailing_placement, ContactGeometry, DhRow, Drive, IntegratorSettings, JointKind, Link, Model,
    ModelSource, Parameter,
};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};

/// A model file and, for a URDF model, the URDF it names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WrittenModel {
    /// The model file (TOML).
    pub toml: String,
    /// The URDF the model file names, for a URDF model.
    pub urdf: Option<String>,
}

/// Relative tolerance of the read-back check: the written files must give
/// every value of the model again to this, plus [`ABSOLUTE`] (the frame
/// conversions round; measured up to a few 1e-16).
const RELATIVE: f64 = 1e-12;
/// Absolute part of the read-back tolerance, in the value's SI unit.
const ABSOLUTE: f64 = 1e-15;

/// Writes `model` as a model file (and for a URDF model a URDF) from which
/// the engine reads `model` again. `source` is the model file (with its URDF)
/// that `model` was read from before settings and standard parameters were
/// applied: it supplies the Denavit–Hartenberg rows, the URDF document and
/// the chain's ends. `urdf_file_name` is the name the written model file
/// gives its URDF (`urdf = "…"`, relative to the model file); a
/// Denavit–Hartenberg model ignores it.
///
/// The written text begins with a comment that says where it comes from and
/// what differs from `source`. Errors: a source that does not parse, and a
/// model that is not the source's chain (another number of joints, other
/// joint kinds or placements: the written files would not read back to it),
/// named by the first value that differs.
pub fn model_file(model: &Model, source: &ModelSource, urdf_file_name: &str) -> Result<WrittenModel, ModelError> {
    let original = source.model()?;
    let file: SourceFile = toml::from_str(&source.toml).map_err(|e| ModelError::Syntax { reason: e.to_string() })?;
    let header = header(model, &original, &file);
    // A source naming a URDF came with it: `original` was read from both.
    let written = match (&file.urdf, &source.urdf) {
        (Some(_), Some(xml)) => urdf_files(model, &original, &file, xml, urdf_file_name, &header)?,
        _ => WrittenModel { toml: dh_file(model, &file, &header)?, urdf: None },
    };
    let read = ModelSource { toml: written.toml.clone(), urdf: written.urdf.clone() }.model().map_err(|e| {
        ModelError::Invalid { field: "written model".into(), reason: format!("does not read back: {e}") }
    })?;
    if let Some(field) = first_difference(model, &read) {
        return Err(ModelError::Invalid {
            field,
            reason: format!(
                "the model differs from its source `{}` beyond what a model file written from that source can say \
                 (its joints, their kinds and placements)",
                original.name
            ),
        });
    }
    Ok(written)
}

// ---------------------------------------------------------------------------
// What the source file gives that the model does not keep.

/// The keys of a model file the writer takes from the source (the reader
/// checks the file; unknown keys are ignored here).
#[derive(Deserialize)]
struct SourceFile {
    urdf: Option<String>,
    base_link: Option<String>,
    tip_link: Option<String>,
    #[serde(default)]
    joint: Vec<SourceRow>,
}

/// A Denavit–Hartenberg row of the source.
#[derive(Deserialize)]
struct SourceRow {
    theta: f64,
    d: f64,
    a: f64,
    alpha: f64,
}

impl SourceRow {
    fn dh(&self) -> DhRow {
        DhRow { theta: self.theta, d: self.d, a: self.a, alpha: self.alpha }
    }
}

// ---------------------------------------------------------------------------
// Numbers and TOML values.

/// `x` in the shortest form that reads back to the same bits.
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn vector(v: &Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// A TOML string (quoted, escaped).
fn string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// A TOML key: bare where it can be.
fn key(s: &str) -> String {
    let bare = !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if bare {
        s.to_string()
    } else {
        string(s)
    }
}

/// `back` (a value converted back into the file's frame), or, where one
/// gives `target` again through the reader's conversion `forward` bit for
/// bit, the same with the fewest significant digits (1 to 15) and the
/// entries below 1e-12 of the largest one as 0: the tidiest number that
/// reads back to the same model.
fn tidy<const N: usize, U: PartialEq>(back: [f64; N], forward: impl Fn(&[f64; N]) -> U, target: &U) -> [f64; N] {
    let largest = back.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    (0..15)
        .map(|digits| {
            back.map(
                |x| {
                    if x.abs() < 1e-12 * largest {
                        0.0
                    } else {
                        format!("{x:.digits$e}").parse::<f64>().unwrap_or(x)
                    }
                },
            )
        })
        .find(|short| forward(short) == *target)
        .unwrap_or(back)
}

/// A symmetric tensor's six entries [xx, xy, xz, yy, yz, zz] (upper triangle).
fn upper(m: &Mat3) -> [f64; 6] {
    [m[(0, 0)], m[(0, 1)], m[(0, 2)], m[(1, 1)], m[(1, 2)], m[(2, 2)]]
}

/// The tensor of six entries, as the readers build it.
fn tensor(e: &[f64; 6]) -> Mat3 {
    let [xx, xy, xz, yy, yz, zz] = *e;
    Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

fn symmetric(m: Mat3) -> Mat3 {
    (m + m.transpose()) * 0.5
}

/// Link data in a frame turned by `r` (and moved by `t`) from the engine's:
/// the centre of mass and the inertia about it, tidied against the reader's
/// conversion `(r·c + t, r·I·rᵀ)` back to the model's `link`.
fn link_in_frame(link: &Link, r: &Mat3, t: &Vec3) -> (Vec3, [f64; 6]) {
    let com = tidy((r.transpose() * (link.com - t)).into(), |c| r * Vec3::from(*c) + t, &link.com);
    let inertia =
        tidy(upper(&symmetric(r.transpose() * link.inertia * r)), |e| r * tensor(e) * r.transpose(), &link.inertia);
    (Vec3::from(com), inertia)
}

fn drive_toml(drive: &Drive) -> String {
    match *drive {
        Drive::Rigid => "{ type = \"rigid\" }".into(),
        Drive::Flexible { stiffness, damping, clearance } => format!(
            "{{ type = \"flexible\", k = {}, h = {}, clearance = {} }}",
            num(stiffness),
            num(damping),
            num(clearance)
        ),
        Drive::Motor { stiffness, damping, clearance, rotor } => format!(
            "{{ type = \"motor\", k = {}, h = {}, clearance = {}, gear_ratio = {}, rotor_inertia = {}, \
             motor_viscous = {}, motor_coulomb = {} }}",
            num(stiffness),
            num(damping),
            num(clearance),
            num(rotor.gear_ratio),
            num(rotor.inertia),
            num(rotor.viscous),
            num(rotor.coulomb)
        ),
    }
}

/// The `drive`, `friction` and `bearings` / `slider` lines of a joint, the
/// reaction point and slider centre given in the file's frames.
fn joint_lines(out: &mut String, model: &Model, i: usize, reaction_point: Vec3, centre: Vec3) {
    let joint = &model.joints[i];
    let _ = writeln!(out, "drive = {}", drive_toml(&joint.drive));
    let Some(friction) = joint.friction else { return };
    let c = friction.coefficients;
    let _ = writeln!(
        out,
        "friction = {{ mu_k = {}, mu_s = {}, v_s = {}, viscous = {} }}",
        num(c.mu_kinetic),
        num(c.mu_static),
        num(c.stribeck_velocity),
        num(c.viscous)
    );
    let _ = match friction.geometry {
        ContactGeometry::Bearings { l_a, l_b, d_a, d_b, d_c, .. } => writeln!(
            out,
            "bearings = {{ reaction_point = {}, l_a = {}, l_b = {}, d_a = {}, d_b = {}, d_c = {} }}",
            vector(&reaction_point),
            num(l_a),
            num(l_b),
            num(d_a),
            num(d_b),
            num(d_c)
        ),
        ContactGeometry::Slider { a, b, c, .. } => {
            writeln!(out, "slider = {{ centre = {}, a = {}, b = {}, c = {} }}", vector(&centre), num(a), num(b), num(c))
        }
    };
}

/// The engine's bearing reference height and slider centre of joint `i`
/// (zero where the joint has none).
fn contact_points(model: &Model, i: usize) -> (f64, Vec3) {
    match model.joints[i].friction.map(|f| f.geometry) {
        Some(ContactGeometry::Bearings { reaction_point, .. }) => (reaction_point.z, Vec3::zeros()),
        Some(ContactGeometry::Slider { centre, .. }) => (0.0, centre),
        None => (0.0, Vec3::zeros()),
    }
}

fn integrator_toml(out: &mut String, s: &IntegratorSettings) {
    let _ = write!(
        out,
        "\n[integrator]\nh_min = {}\nh_max = {}\nerror_tolerance = {}\nbeta = {}\ngamma = {}\ntolerance = {}\n\
         max_iterations = {}\n",
        num(s.h_min),
        num(s.h_max),
        num(s.error_tolerance),
        num(s.beta),
        num(s.gamma),
        num(s.tolerance),
        s.max_iterations
    );
}

// ---------------------------------------------------------------------------
// The header: where the file comes from, what changed.

/// The comment that opens a written model file.
fn header(model: &Model, original: &Model, file: &SourceFile) -> String {
    let from = match &file.urdf {
        Some(urdf) => format!("the model `{}` (urdf = {})", original.name, string(urdf)),
        None => format!("the model `{}`", original.name),
    };
    let mut changes = Vec::new();
    if model.name != original.name {
        changes.push(format!("name: {} -> {}", original.name, model.name));
    }
    let n = model.nq().min(original.nq());
    for i in 0..n {
        let (new, old) = (&model.links[i], &original.links[i]);
        let mut parts = Vec::new();
        if new.mass != old.mass {
            parts.push(format!("m {} -> {} kg", num(old.mass), num(new.mass)));
        }
        if new.com != old.com {
            parts.push("centre of mass".to_string());
        }
        if new.inertia != old.inertia {
            parts.push("inertia".to_string());
        }
        if !parts.is_empty() {
            let name = model.joint_names[i].as_ref().map_or(String::new(), |s| format!(" (joint `{s}`)"));
            changes.push(format!("link {}{name}: {}", i + 1, parts.join(", ")));
        }
    }
    for i in 0..n {
        for p in Parameter::ALL.into_iter().filter(|&p| p != Parameter::Mass) {
            if let (Some(new), Some(old)) = (model.parameter(p, i), original.parameter(p, i)) {
                if new != old {
                    changes.push(format!("{}[{}]: {} -> {}", p.name(), i + 1, num(old), num(new)));
                }
            }
        }
    }
    if model.integrator != original.integrator {
        changes.push(format!("integrator: {:?} -> {:?}", original.integrator, model.integrator));
    }
    if model.gravity != original.gravity {
        changes.push(format!("gravity: {} -> {}", vector(&original.gravity), vector(&model.gravity)));
    }
    let mut text = format!("# Written by stickslip identify (the engine's model writer) from {from}.\n");
    if changes.is_empty() {
        text.push_str("# Nothing changed: the original model, written out in full.\n");
    } else {
        text.push_str("# Changed (the identified values):\n");
        for change in changes {
            let _ = writeln!(text, "#   {change}");
        }
        text.push_str("# Everything else as the original has it.\n");
    }
    text.push_str("# All quantities SI: m, kg, s, rad, N, N·m.\n");
    text
}

// ---------------------------------------------------------------------------
// Denavit–Hartenberg models.

fn dh_file(model: &Model, file: &SourceFile, header: &str) -> Result<String, ModelError> {
    if file.joint.len() != model.nq() {
        return Err(ModelError::Invalid {
            field: "joint".into(),
            reason: format!("the model has {} joints, its source {} rows", model.nq(), file.joint.len()),
        });
    }
    let rows: Vec<DhRow> = file.joint.iter().map(SourceRow::dh).collect();
    let last = trailing_placement(&rows[rows.len() - 1]);
    let end_point = tidy(
        (last.rotation.transpose() * (model.end_point - last.translation)).into(),
        |e| last.apply(&Vec3::from(*e)),
        &model.end_point,
    );
    let mut out = String::from(header);
    out.push_str(
        "#\n# Kinematics: standard (distal) Denavit-Hartenberg rows,\n\
         #   A_i = Rot_z(theta_i)·Trans_z(d_i)·Trans_x(a_i)·Rot_x(alpha_i);\n\
         # link data in the link's frame i, the inertia tensor about the centre of mass.\n\n",
    );
    let _ = writeln!(out, "name = {}", string(&model.name));
    let _ = writeln!(out, "gravity = {}", vector(&model.gravity));
    let _ = writeln!(out, "end_point = {}", vector(&Vec3::from(end_point)));
    integrator_toml(&mut out, &model.integrator);
    for (i, (joint, row)) in model.joints.iter().zip(&rows).enumerate() {
        let trailing = trailing_placement(row);
        let (height, centre) = contact_points(model, i);
        // (on z_{i−1}) the engine's height on the joint axis is the file's minus d_i.
        let [z] = tidy([height + row.d], |z| z[0] - row.d, &height);
        let centre = tidy(
            (trailing.rotation.transpose() * (centre - trailing.translation)).into(),
            |c| trailing.apply(&Vec3::from(*c)),
            &centre,
        );
        let kind = match joint.kind {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        };
        let _ = write!(
            out,
            "\n# Joint {}\n[[joint]]\ntype = \"{kind}\"\ntheta = {}\nd = {}\na = {}\nalpha = {}\n",
            i + 1,
            num(row.theta),
            num(row.d),
            num(row.a),
            num(row.alpha)
        );
        joint_lines(&mut out, model, i, Vec3::new(0.0, 0.0, z), Vec3::from(centre));
        let link = &model.links[i];
        let (com, e) = link_in_frame(link, &trailing.rotation, &trailing.translation);
        let _ = writeln!(
            out,
            "link = {{ mass = {}, com = {}, inertia = {{ xx = {}, yy = {}, zz = {}, xy = {}, xz = {}, yz = {} }} }}",
            num(link.mass),
            vector(&com),
            num(e[0]),
            num(e[3]),
            num(e[5]),
            num(e[1]),
            num(e[2]),
            num(e[4])
        );
    }
    Ok(out)
}

// ---------------------------------------------------------------------------
// URDF models.

fn urdf_files(
    model: &Model,
    original: &Model,
    file: &SourceFile,
    xml: &str,
    urdf_file_name: &str,
    header: &str,
) -> Result<WrittenModel, ModelError> {
    let chain = read_urdf(xml, file.base_link.as_deref(), file.tip_link.as_deref())?;
    if chain.joints.len() != model.nq() {
        return Err(ModelError::Invalid {
            field: "joint".into(),
            reason: format!("the model has {} joints, its source's URDF chain {}", model.nq(), chain.joints.len()),
        });
    }
    let (urdf, merged) = urdf_text(model, original, &chain, xml)?;
    let mut out = String::from(header);
    let source_urdf = file.urdf.as_deref().unwrap_or_default();
    let _ = writeln!(
        out,
        "#\n# The URDF {}: {} with each moving link's <inertial> holding the model's link (its\n# whole \
         body, in the child link frame: origin at the centre of mass, rpy 0, the inertia about it).",
        string(urdf_file_name),
        string(source_urdf)
    );
    for (carrier, links) in &merged {
        let links: Vec<String> = links.iter().map(|l| format!("`{l}`")).collect();
        let _ = writeln!(
            out,
            "# Link `{carrier}` holds the mass of {} too, which the reader merges into it: their\n\
             # <inertial> elements are removed.",
            links.join(", ")
        );
    }
    let _ = writeln!(out, "\nname = {}", string(&model.name));
    let _ = writeln!(out, "urdf = {}", string(urdf_file_name));
    let _ = writeln!(out, "base_link = {}", string(&chain.base_link));
    let _ = writeln!(out, "tip_link = {}", string(&chain.tip_link));
    let _ = writeln!(out, "gravity = {}", vector(&model.gravity));
    // end_point (engine) = R_a,nᵀ·(tip_rotation·E + tip_translation)
    let ra_last = axis_alignment(&chain.joints[chain.joints.len() - 1].axis);
    let end_point = tidy(
        (chain.tip_rotation.transpose() * (ra_last * model.end_point - chain.tip_translation)).into(),
        |e| ra_last.transpose() * (chain.tip_rotation * Vec3::from(*e) + chain.tip_translation),
        &model.end_point,
    );
    let _ = writeln!(out, "end_point = {}", vector(&Vec3::from(end_point)));
    integrator_toml(&mut out, &model.integrator);
    for (i, uj) in chain.joints.iter().enumerate() {
        let ra = axis_alignment(&uj.axis);
        let (height, centre) = contact_points(model, i);
        let reaction_point = tidy((uj.axis * height).into(), |p| uj.axis.dot(&Vec3::from(*p)), &height);
        let centre = tidy((ra * centre).into(), |c| ra.transpose() * Vec3::from(*c), &centre);
        let _ = writeln!(out, "\n[joints.{}]", key(&uj.name));
        joint_lines(&mut out, model, i, Vec3::from(reaction_point), Vec3::from(centre));
    }
    Ok(WrittenModel { toml: out, urdf: Some(urdf) })
}

/// A top-level `<link>` of a URDF document: where it and its `<inertial>` are.
struct LinkSpan {
    /// The whole element, `<link` to the end of `</link>` or `/>`.
    element: Range<usize>,
    /// Where its end tag `</link>` starts; `None` for `<link … />`.
    end_tag: Option<usize>,
    /// Its `<inertial>` element.
    inertial: Option<Range<usize>>,
}

/// The document's links by name and its joints' (parent, child) links, in
/// byte offsets of `xml`.
struct Document {
    links: BTreeMap<String, LinkSpan>,
    /// Parent link name → child link names.
    children: BTreeMap<String, Vec<String>>,
    /// Joint name → child link name.
    child_of: BTreeMap<String, String>,
}

fn xml_error(reason: impl Into<String>) -> ModelError {
    ModelError::Urdf { element: "document".into(), reason: reason.into() }
}

fn attribute(start: &BytesStart<'_>, key: &str) -> Result<Option<String>, ModelError> {
    for attr in start.attributes() {
        let attr = attr.map_err(|e| xml_error(format!("malformed attribute: {e}")))?;
        if attr.key.as_ref() == key.as_bytes() {
            let value = attr.normalized_value(XmlVersion::Implicit1_0).map_err(|e| xml_error(e.to_string()))?;
            return Ok(Some(value.into_owned()));
        }
    }
    Ok(None)
}

/// The positions of the links, their `<inertial>`s and the joints' ends in
/// `xml`, as the reader reads them (local names, top-level elements of
/// `<robot>`).
fn scan(xml: &str, offset: usize) -> Result<Document, ModelError> {
    let mut reader = Reader::from_str(xml);
    let mut stack: Vec<String> = Vec::new();
    let mut doc = Document { links: BTreeMap::new(), children: BTreeMap::new(), child_of: BTreeMap::new() };
    let mut link: Option<(String, LinkSpan)> = None;
    let mut joint: (Option<String>, Option<String>, Option<String>) = (None, None, None);
    let mut inertial_start = 0;
    loop {
        let before = reader.buffer_position() as usize + offset;
        let event = reader.read_event().map_err(|e| xml_error(format!("is not well-formed XML: {e}")))?;
        let after = reader.buffer_position() as usize + offset;
        let (start, empty) = match &event {
            Event::Start(s) => (Some(s), false),
            Event::Empty(s) => (Some(s), true),
            _ => (None, false),
        };
        if let Some(s) = start {
            let name = String::from_utf8_lossy(s.local_name().as_ref()).into_owned();
            let path: Vec<&str> = stack.iter().map(String::as_str).collect();
            match (path.as_slice(), name.as_str()) {
                (["robot"], "link") => {
                    let link_name = attribute(s, "name")?.unwrap_or_default();
                    let span = LinkSpan { element: before..after, end_tag: None, inertial: None };
                    if empty {
                        doc.links.insert(link_name, span);
                    } else {
                        link = Some((link_name, span));
                    }
                }
                (["robot", "link"], "inertial") => {
                    inertial_start = before;
                    if let (true, Some((_, span))) = (empty, link.as_mut()) {
                        span.inertial = Some(before..after);
                    }
                }
                (["robot"], "joint") => joint = (attribute(s, "name")?, None, None),
                (["robot", "joint"], "parent") => joint.1 = attribute(s, "link")?,
                (["robot", "joint"], "child") => joint.2 = attribute(s, "link")?,
                _ => {}
            }
            if !empty {
                stack.push(name);
            }
            continue;
        }
        match event {
            Event::End(e) => {
                let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
                stack.pop();
                let path: Vec<&str> = stack.iter().map(String::as_str).collect();
                match (path.as_slice(), name.as_str()) {
                    (["robot", "link"], "inertial") => {
                        if let Some((_, span)) = link.as_mut() {
                            span.inertial = Some(inertial_start..after);
                        }
                    }
                    (["robot"], "link") => {
                        if let Some((link_name, mut span)) = link.take() {
                            span.element.end = after;
                            span.end_tag = Some(before);
                            doc.links.insert(link_name, span);
                        }
                    }
                    (["robot"], "joint") => {
                        if let (Some(name), Some(parent), Some(child)) = std::mem::take(&mut joint) {
                            doc.children.entry(parent).or_default().push(child.clone());
                            doc.child_of.insert(name, child);
                        }
                    }
                    _ => {}
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(doc)
}

impl Document {
    /// `link` and every link below it.
    fn subtree(&self, link: &str) -> BTreeSet<String> {
        let mut found = BTreeSet::new();
        let mut todo = vec![link.to_string()];
        while let Some(l) = todo.pop() {
            if found.insert(l.clone()) {
                todo.extend(self.children.get(&l).into_iter().flatten().cloned());
            }
        }
        found
    }
}

/// The white space that indents the line `pos` is on, if only white space
/// precedes `pos` there.
fn indent_at(xml: &str, pos: usize) -> &str {
    let line = xml[..pos].rfind('\n').map_or(0, |i| i + 1);
    let indent = &xml[line..pos];
    if indent.chars().all(char::is_whitespace) {
        indent
    } else {
        ""
    }
}

/// The `<inertial>` element of `link` (engine frame) in the URDF child link
/// frame turned by `ra` from it, its lines indented by `indent`.
fn inertial_element(link: &Link, ra: &Mat3, indent: &str) -> String {
    let (com, e) = link_in_frame(link, &ra.transpose(), &Vec3::zeros());
    format!(
        "<inertial>\n{indent}  <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n{indent}  <mass value=\"{}\"/>\n\
         {indent}  <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n{indent}</inertial>",
        num(com.x),
        num(com.y),
        num(com.z),
        num(link.mass),
        num(e[0]),
        num(e[1]),
        num(e[2]),
        num(e[3]),
        num(e[4]),
        num(e[5])
    )
}

/// The moving links of a URDF into which the reader merged other links
/// with an `<inertial>`, each with those links, in document order.
type Merged = Vec<(String, Vec<String>)>;

/// The URDF with the model's links as the moving links' `<inertial>`s and
/// the `<inertial>`s of the links merged into them removed; and per moving
/// link the links whose `<inertial>` was removed.
fn urdf_text(model: &Model, original: &Model, chain: &UrdfChain, xml: &str) -> Result<(String, Merged), ModelError> {
    let bom = if xml.starts_with('\u{feff}') { '\u{feff}'.len_utf8() } else { 0 };
    let doc = scan(&xml[bom..], bom)?;
    let child = |joint: &str| {
        doc.child_of.get(joint).cloned().ok_or_else(|| xml_error(format!("has no joint `{joint}` with a child link")))
    };
    let carriers = chain.joints.iter().map(|j| child(&j.name)).collect::<Result<Vec<_>, _>>()?;
    let mut edits: Vec<(Range<usize>, String)> = Vec::new();
    let mut merged_report = Vec::new();
    for (i, carrier) in carriers.iter().enumerate() {
        let mut body = doc.subtree(carrier);
        if let Some(next) = carriers.get(i + 1) {
            for l in doc.subtree(next) {
                body.remove(&l);
            }
        }
        let mut merged: Vec<String> = body
            .iter()
            .filter(|l| *l != carrier && doc.links.get(*l).is_some_and(|s| s.inertial.is_some()))
            .cloned()
            .collect();
        merged.sort_by_key(|l| doc.links[l].element.start);
        let span = doc.links.get(carrier).ok_or_else(|| xml_error(format!("has no link `{carrier}`")))?;
        let link = &model.links[i];
        let unchanged = merged.is_empty() && original.links.get(i) == Some(link);
        let massless = link.mass == 0.0 && link.inertia == Mat3::zeros();
        let ra = axis_alignment(&chain.joints[i].axis);
        match (&span.inertial, span.end_tag) {
            _ if unchanged => {}
            (Some(range), _) => {
                edits.push((range.clone(), inertial_element(link, &ra, indent_at(xml, range.start))));
            }
            (None, _) if massless => {}
            (None, Some(end_tag)) => {
                let outer = indent_at(xml, span.element.start);
                let inner = format!("{outer}  ");
                let element = inertial_element(link, &ra, &inner);
                edits.push((end_tag..end_tag, format!("  {element}\n{outer}")));
            }
            (None, None) => {
                let outer = indent_at(xml, span.element.start);
                let tag = xml[span.element.clone()].trim_end_matches("/>").trim_end();
                let element = inertial_element(link, &ra, &format!("{outer}  "));
                edits.push((span.element.clone(), format!("{tag}>\n{outer}  {element}\n{outer}</link>")));
            }
        }
        for l in &merged {
            let range = doc.links[l].inertial.clone().expect("filtered on an <inertial>");
            let note =
                format!("<!-- <inertial> merged into link {} by stickslip identify -->", carrier.replace("--", "- -"));
            edits.push((range, note));
        }
        if !merged.is_empty() {
            merged_report.push((carrier.clone(), merged));
        }
    }
    edits.sort_by_key(|(range, _)| range.start);
    let mut out = String::with_capacity(xml.len() + 1024);
    let mut at = 0;
    for (range, text) in edits {
        out.push_str(&xml[at..range.start]);
        out.push_str(&text);
        at = range.end;
    }
    out.push_str(&xml[at..]);
    Ok((out, merged_report))
}

// ---------------------------------------------------------------------------
// The read-back check.

/// The model's values in groups, each named by its field, and the text of
/// what must match exactly (names, kinds, integrator settings).
fn values(model: &Model) -> (String, Vec<(String, Vec<f64>)>) {
    let mut exact = format!("{:?} {:?} {:?}", model.name, model.joint_names, model.integrator);
    let mut groups = vec![
        ("gravity".to_string(), model.gravity.as_slice().to_vec()),
        ("end_point".to_string(), model.end_point.as_slice().to_vec()),
    ];
    for (i, (j, l)) in model.joints.iter().zip(&model.links).enumerate() {
        let f = |name: &str| format!("joint[{}].{name}", i + 1);
        let drive = match j.drive {
            Drive::Rigid => vec![],
            Drive::Flexible { stiffness, damping, clearance } => vec![stiffness, damping, clearance],
            Drive::Motor { stiffness, damping, clearance, rotor } => {
                vec![stiffness, damping, clearance, rotor.gear_ratio, rotor.inertia, rotor.viscous, rotor.coulomb]
            }
        };
        let friction = j.friction.map_or(vec![], |f| {
            let c = f.coefficients;
            let mut v = vec![c.mu_kinetic, c.mu_static, c.stribeck_velocity, c.viscous];
            match f.geometry {
                ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c } => {
                    v.extend(reaction_point.iter().chain(&[l_a, l_b, d_a, d_b, d_c]))
                }
                ContactGeometry::Slider { centre, a, b, c } => v.extend(centre.iter().chain(&[a, b, c])),
            }
            v
        });
        let _ = write!(
            exact,
            " {:?} {} {:?}",
            j.kind,
            drive.len(),
            j.friction.map(|f| std::mem::discriminant(&f.geometry))
        );
        groups.extend([
            (f("placement.rotation"), j.placement.rotation.as_slice().to_vec()),
            (f("placement.translation"), j.placement.translation.as_slice().to_vec()),
            (f("offset"), vec![j.offset]),
            (f("reported_axes"), j.reported_axes.as_slice().to_vec()),
            (f("drive"), drive),
            (f("friction"), friction),
            (f("link.mass"), vec![l.mass]),
            (f("link.com"), l.com.as_slice().to_vec()),
            (f("link.inertia"), l.inertia.as_slice().to_vec()),
        ]);
    }
    (exact, groups)
}

/// The first field in which `b` differs from `a` beyond the read-back
/// tolerance, if any.
fn first_difference(a: &Model, b: &Model) -> Option<String> {
    let ((exact_a, groups_a), (exact_b, groups_b)) = (values(a), values(b));
    if exact_a != exact_b || groups_a.len() != groups_b.len() {
        return Some("chain (name, joint names and kinds, drive and contact kinds, integrator)".into());
    }
    groups_a.iter().zip(&groups_b).find_map(|((field, x), (_, y))| {
        let scale = x.iter().chain(y).fold(0.0_f64, |m, v| m.max(v.abs()));
        let off = x.len() != y.len() || x.iter().zip(y).any(|(p, q)| (p - q).abs() > RELATIVE * scale + ABSOLUTE);
        off.then(|| field.clone())
    })
}
