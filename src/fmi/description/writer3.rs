//! `modelDescription.xml` for FMI 3.0 (co-simulation only), written with
//! quick-xml from the same variables as the FMI 2.0 one
//! ([`variables`](super::variables) grouped by [`variables3`]).
//!
//! The header (model name, description, version, generation tool), the
//! units, log categories and default experiment are FMI 2.0's; the
//! `instantiationToken` is FMI 2.0's GUID. An array's attributes come from
//! its elements: causality, variability and `initial` are theirs (a count,
//! `Int32`, is `discrete`); the unit, when all elements share one (the joint
//! quantities of an arm with revolute and prismatic joints do not: then the
//! description names each element's unit), through `declaredType`: one
//! `Float64Type` per unit in the `TypeDefinitions`, named after its quantity,
//! with the unit and its first display unit; `min`/`max` the loosest over the
//! elements (FMI 3.0 has one range per
//! variable; the description gives each element's own where they differ,
//! the FMU checks those); `start` the elements' start values in
//! serialization order. The description is the elements' FMI 2.0
//! description with the joint named as "each joint", or, where the elements'
//! descriptions differ beyond that, each group of elements with its own.

use super::arrays::{split_name, variables3, Type3, Variable3};
use super::joints::joint_label;
use super::outputs::Arity;
use super::variables::{guid, variables, Causality, Initial, Quantity, Type, Variability, Variable};
use super::{in_fmi3_terms, Unit, DEFAULT_EXPERIMENT, LOG_CATEGORIES, MODEL_IDENTIFIER, UNITS};
use crate::model::{JointKind, Model};
use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::io;

/// A real number as an xs:double that every reader parses back to the same
/// bits (Rust's shortest round-trip digits); the same digits as the FMI 2.0
/// writer's.
fn real(x: f64) -> String {
    if x == 0.0 || (1e-4..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn boolean(b: bool) -> &'static str {
    if b {
        "true"
    } else {
        "false"
    }
}

/// The FMI 3.0 modelDescription of the FMU for `model`, parsed from
/// `model_text` (the instantiation token is FMI 2.0's GUID of the same text
/// and variables).
pub fn model_description_fmi3_xml(model: &Model, model_text: &str) -> String {
    let vars = variables(model);
    let token = guid(model_text, &vars);
    let vars3 = variables3(&vars);
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_document(&mut w, model, &vars, &vars3, &token).expect("writing to memory cannot fail");
    let mut xml = String::from_utf8(w.into_inner()).expect("quick-xml writes UTF-8");
    xml.push('\n');
    xml
}

/// "R flexible, R rigid, P flexible, R rigid", as in the FMI 2.0 description.
fn chain_summary(model: &Model) -> String {
    model
        .joints
        .iter()
        .map(|j| {
            let kind = match j.kind {
                JointKind::Revolute => 'R',
                JointKind::Prismatic => 'P',
            };
            let drive = if j.drive.is_flexible() { "flexible" } else { "rigid" };
            format!("{kind} {drive}")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn write_document(
    w: &mut Writer<Vec<u8>>,
    model: &Model,
    vars: &[Variable],
    vars3: &[Variable3],
    token: &str,
) -> io::Result<()> {
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let description = format!(
        "Manipulator with flexible drives and dry friction in the joints (stick-slip): model `{}`, {} joints ({})",
        model.name,
        model.nq(),
        chain_summary(model)
    );
    let tool = concat!("stick_slip_manipulator ", env!("CARGO_PKG_VERSION"));
    w.create_element("fmiModelDescription")
        .with_attributes([
            ("fmiVersion", "3.0"),
            ("modelName", model.name.as_str()),
            ("instantiationToken", token),
            ("description", description.as_str()),
            ("version", env!("CARGO_PKG_VERSION")),
            ("generationTool", tool),
            ("variableNamingConvention", "structured"),
        ])
        .write_inner_content(|w| {
            write_co_simulation(w)?;
            write_units(w)?;
            write_type_definitions(w, vars, vars3)?;
            write_log_categories(w)?;
            let (start, stop, step) = DEFAULT_EXPERIMENT;
            w.create_element("DefaultExperiment")
                .with_attributes([
                    ("startTime", real(start).as_str()),
                    ("stopTime", &real(stop)),
                    ("stepSize", &real(step)),
                    ("tolerance", &real(model.integrator.error_tolerance)),
                ])
                .write_empty()?;
            w.create_element("ModelVariables")
                .write_inner_content(|w| vars3.iter().try_for_each(|v| write_variable(w, model, vars, v)))?;
            write_model_structure(w, vars, vars3)
        })?;
    Ok(())
}

/// The FMI 2.0 capabilities with an FMI 3.0 name, and FMI 3.0's own:
/// event mode, intermediate update with early return on request, output
/// derivatives up to the second (q: q', q''; qd: qd').
fn write_co_simulation(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("CoSimulation")
        .with_attributes([
            ("modelIdentifier", MODEL_IDENTIFIER),
            ("needsExecutionTool", "false"),
            ("canBeInstantiatedOnlyOncePerProcess", "false"),
            ("canGetAndSetFMUState", "true"),
            ("canSerializeFMUState", "true"),
            ("providesDirectionalDerivatives", "false"),
            ("canHandleVariableCommunicationStepSize", "true"),
            ("maxOutputDerivativeOrder", "2"),
            ("providesIntermediateUpdate", "true"),
            ("canReturnEarlyAfterIntermediateUpdate", "true"),
            ("mightReturnEarlyFromDoStep", "true"),
            ("hasEventMode", "true"),
        ])
        .write_empty()?;
    Ok(())
}

fn write_units(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("UnitDefinitions").write_inner_content(|w| {
        for unit in &UNITS {
            w.create_element("Unit").with_attribute(("name", unit.name)).write_inner_content(|w| {
                let exponents = ["kg", "m", "s", "rad"].iter().zip(unit.base).filter(|(_, e)| *e != 0);
                let attributes: Vec<(&str, String)> = exponents.map(|(name, e)| (*name, e.to_string())).collect();
                w.create_element("BaseUnit")
                    .with_attributes(attributes.iter().map(|(k, v)| (*k, v.as_str())))
                    .write_empty()?;
                for (name, factor) in unit.display {
                    w.create_element("DisplayUnit")
                        .with_attributes([("name", *name), ("factor", real(*factor).as_str())])
                        .write_empty()?;
                }
                Ok(())
            })?;
        }
        Ok(())
    })?;
    Ok(())
}

/// The unit of the FMI 3.0 variable `v3`: its elements' when they are FMI 2.0
/// Reals that all have the same (none for `time`, the Int32 and Boolean
/// arrays, dimensionless quantities and arrays of mixed units).
fn array_unit(vars: &[Variable], v3: &Variable3) -> Option<&'static Unit> {
    let mut units = v3.elements.iter().map(|&e| match vars[e as usize].ty {
        Type::Real { unit, .. } if v3.ty == Type3::Float64 => unit,
        _ => None,
    });
    let first = units.next()??;
    if !units.all(|u| u == Some(first)) {
        return None;
    }
    Some(
        UNITS.iter().find(|u| u.name == first).unwrap_or_else(|| panic!("`{}`: unit {first} is not in UNITS", v3.name)),
    )
}

/// One `Float64Type` per unit that a variable has, in the order of [`UNITS`]:
/// named after the unit's quantity (`Length`: `unit="m"`,
/// `displayUnit="mm"`), the unit's first display unit as its `displayUnit`.
/// The variables name it in `declaredType` instead of carrying `unit` and
/// `displayUnit` themselves, as the FMI reference FMUs do: every importer
/// reads units that way, the `fmi` crate's schema among them, which refuses
/// `unit` on a variable.
fn write_type_definitions(w: &mut Writer<Vec<u8>>, vars: &[Variable], vars3: &[Variable3]) -> io::Result<()> {
    let used: Vec<&Unit> =
        UNITS.iter().filter(|u| vars3.iter().any(|v| array_unit(vars, v).is_some_and(|a| a.name == u.name))).collect();
    if used.is_empty() {
        // The schema wants at least one type in a TypeDefinitions element.
        return Ok(());
    }
    w.create_element("TypeDefinitions").write_inner_content(|w| {
        for unit in used {
            let mut attributes = vec![("name", unit.quantity), ("quantity", unit.quantity), ("unit", unit.name)];
            attributes.extend(unit.display.first().map(|(display, _)| ("displayUnit", *display)));
            w.create_element("Float64Type").with_attributes(attributes).write_empty()?;
        }
        Ok(())
    })?;
    Ok(())
}

fn write_log_categories(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("LogCategories").write_inner_content(|w| {
        for (name, description) in LOG_CATEGORIES {
            w.create_element("Category")
                .with_attributes([("name", name), ("description", in_fmi3_terms(description).as_str())])
                .write_empty()?;
        }
        Ok(())
    })?;
    Ok(())
}

/// The joint (0-based) an FMI 2.0 variable belongs to, if it is one of a
/// per-joint quantity.
fn element_joint(v: &Variable) -> Option<usize> {
    match v.quantity {
        Quantity::Input(_, j)
        | Quantity::Parameter(_, j)
        | Quantity::StartQ(j)
        | Quantity::StartQd(j)
        | Quantity::MotorTorque(j)
        | Quantity::StartThetaM(j)
        | Quantity::StartOmegaM(j) => Some(j),
        Quantity::Output(o) => match o.kind().arity {
            Arity::PerJoint | Arity::PerJointVector | Arity::PerRotor => Some(o.joint),
            Arity::Single | Arity::SingleWithRotors | Arity::Vector => None,
        },
        Quantity::Setting(_) | Quantity::UseStartValues | Quantity::StaticStart => None,
    }
}

/// The elements of an array, for naming groups of them in its description.
struct Elements<'a> {
    vars: Vec<&'a Variable>,
    /// Their FMI 2.0 indices (for a vector of joints: the joint numbers).
    indices: Vec<Vec<usize>>,
    /// A vector whose elements are joints: named "joints 1, 3".
    by_joint: bool,
}

impl Elements<'_> {
    /// "joint 3", "joints 1, 2, 4", or "[1,2], [2,2]": elements `members`.
    fn label(&self, members: &[usize]) -> String {
        if self.by_joint {
            let joints: Vec<String> = members.iter().map(|&e| self.indices[e][0].to_string()).collect();
            let plural = if joints.len() == 1 { "" } else { "s" };
            format!("joint{plural} {}", joints.join(", "))
        } else {
            let names: Vec<String> = members
                .iter()
                .map(|&e| {
                    let i: Vec<String> = self.indices[e].iter().map(usize::to_string).collect();
                    format!("[{}]", i.join(","))
                })
                .collect();
            names.join(", ")
        }
    }

    /// The elements grouped by `key`, groups in the order of their first
    /// element: (key, elements).
    fn groups<K: PartialEq>(&self, key: impl Fn(&Variable) -> K) -> Vec<(K, Vec<usize>)> {
        let mut groups: Vec<(K, Vec<usize>)> = Vec::new();
        for (e, v) in self.vars.iter().enumerate() {
            let k = key(v);
            match groups.iter_mut().find(|(g, _)| *g == k) {
                Some((_, members)) => members.push(e),
                None => groups.push((k, vec![e])),
            }
        }
        groups
    }
}

/// Stands for the joint's label in a description shared by several joints.
const JOINT: &str = "\u{1}joint\u{1}";

/// The description of an array: its elements' FMI 2.0 description with
/// "each joint" for the joint, or the groups of elements with different
/// descriptions each with its own; which joints a vector over some of them
/// covers; each element's unit and range where they differ.
fn array_description(model: &Model, elements: &Elements) -> String {
    let template = |v: &Variable| match element_joint(v) {
        Some(j) => v.description.replace(&joint_label(model, j), JOINT),
        None => v.description.clone(),
    };
    let groups = elements.groups(template);
    let mut text = if let [(only, _)] = groups.as_slice() {
        only.replace(JOINT, "each joint")
    } else {
        let parts: Vec<String> = groups
            .iter()
            .map(|(t, members)| format!("{}: {}", elements.label(members), t.replace(JOINT, "the joint")))
            .collect();
        parts.join("; ")
    };
    let n = elements.vars.len();
    if elements.by_joint && elements.indices.iter().enumerate().any(|(e, i)| i[0] != e + 1) {
        text.push_str(&format!(" (elements: {})", elements.label(&(0..n).collect::<Vec<_>>())));
    }
    let units = elements.groups(|v| match v.ty {
        Type::Real { unit, .. } => unit,
        Type::Boolean { .. } => None,
    });
    if units.len() > 1 {
        let parts: Vec<String> = units
            .iter()
            .map(|(u, members)| format!("{} ({})", u.unwrap_or("no unit"), elements.label(members)))
            .collect();
        text.push_str(&format!("; unit per element: {}", parts.join(", ")));
    }
    let ranges = elements.groups(|v| match v.ty {
        Type::Real { min, max, .. } => (min, max),
        Type::Boolean { .. } => (None, None),
    });
    if ranges.len() > 1 {
        let bound = |b: Option<f64>, none: &str| b.map_or_else(|| none.to_string(), real);
        let parts: Vec<String> = ranges
            .iter()
            .map(|((min, max), members)| {
                format!("[{}, {}] for {}", bound(*min, "-inf"), bound(*max, "inf"), elements.label(members))
            })
            .collect();
        text.push_str(&format!(
            "; min and max are the loosest over the elements, whose own ranges the FMU checks: {}",
            parts.join(", ")
        ));
    }
    text
}

/// Bounds and start of one FMI 2.0 Real.
struct RealAttributes {
    min: Option<f64>,
    max: Option<f64>,
    start: Option<f64>,
}

/// The loosest bound of `bounds`: `pick` of them if every element has one.
fn loosest(bounds: impl Iterator<Item = Option<f64>>, pick: fn(f64, f64) -> f64) -> Option<f64> {
    bounds.collect::<Option<Vec<f64>>>().and_then(|b| b.into_iter().reduce(pick))
}

fn write_variable(w: &mut Writer<Vec<u8>>, model: &Model, vars: &[Variable], v3: &Variable3) -> io::Result<()> {
    let vr = v3.value_reference.to_string();
    if v3.elements.is_empty() {
        // The independent variable.
        w.create_element("Float64")
            .with_attributes([
                ("name", v3.name.as_str()),
                ("valueReference", vr.as_str()),
                ("causality", "independent"),
                ("variability", "continuous"),
            ])
            .write_empty()?;
        return Ok(());
    }
    let members: Vec<&Variable> = v3
        .elements
        .iter()
        .map(|&e| {
            let v = &vars[e as usize];
            assert_eq!(v.value_reference, e, "FMI 2.0 value reference = position in the list");
            v
        })
        .collect();
    let first = members[0];
    let description = if v3.dimensions.is_empty() {
        first.description.clone()
    } else {
        let indices: Vec<Vec<usize>> = members.iter().map(|v| split_name(&v.name).1).collect();
        let by_joint = v3.dimensions.len() == 1 && members.iter().all(|v| element_joint(v).is_some());
        array_description(model, &Elements { vars: members.clone(), indices, by_joint })
    };
    let causality = match first.causality {
        Causality::Parameter => "parameter",
        Causality::Input => "input",
        Causality::Output => "output",
    };
    let variability = match (first.variability, v3.ty) {
        (Variability::Fixed, _) => "fixed",
        (Variability::Tunable, _) => "tunable",
        (Variability::Continuous, Type3::Float64) => "continuous",
        (Variability::Discrete | Variability::Continuous, _) => "discrete",
    };
    let mut a: Vec<(&str, String)> = vec![
        ("name", v3.name.clone()),
        ("valueReference", vr),
        ("description", in_fmi3_terms(&description)),
        ("causality", causality.into()),
        ("variability", variability.into()),
    ];
    if first.causality == Causality::Input {
        // q*, q*', q*'' and tau_m may be set in intermediate update mode.
        a.push(("intermediateUpdate", "true".into()));
    }
    match first.initial {
        Some(Initial::Exact) => a.push(("initial", "exact".into())),
        Some(Initial::Calculated) => a.push(("initial", "calculated".into())),
        None => {}
    }
    let needs_start = first.causality != Causality::Output;
    let element = match v3.ty {
        Type3::Float64 => {
            let reals: Vec<RealAttributes> = members
                .iter()
                .map(|v| match v.ty {
                    Type::Real { min, max, start, .. } => RealAttributes { min, max, start },
                    Type::Boolean { .. } => unreachable!("a Float64 of FMI 2.0 Reals"),
                })
                .collect();
            a.extend(array_unit(vars, v3).map(|u| ("declaredType", u.quantity.to_string())));
            a.extend(loosest(reals.iter().map(|r| r.min), f64::min).map(|x| ("min", real(x))));
            a.extend(loosest(reals.iter().map(|r| r.max), f64::max).map(|x| ("max", real(x))));
            let starts: Option<Vec<String>> = reals.iter().map(|r| r.start.map(real)).collect();
            assert!(!needs_start || starts.is_some(), "`{}` needs a start value for every element", v3.name);
            a.extend(starts.map(|s| ("start", s.join(" "))));
            "Float64"
        }
        Type3::Int32 => "Int32",
        Type3::Boolean => {
            let starts: Option<Vec<&str>> = members
                .iter()
                .map(|v| match v.ty {
                    Type::Boolean { start } => start.map(boolean),
                    Type::Real { .. } => unreachable!("a Boolean of FMI 2.0 Booleans"),
                })
                .collect();
            assert!(!needs_start || starts.is_some(), "`{}` needs a start value for every element", v3.name);
            a.extend(starts.map(|s| ("start", s.join(" "))));
            "Boolean"
        }
    };
    assert!(!needs_start || v3.ty != Type3::Int32, "`{}`: an Int32 parameter or input needs a start value", v3.name);
    let start = w.create_element(element).with_attributes(a.iter().map(|(k, v)| (*k, v.as_str())));
    if v3.dimensions.is_empty() {
        start.write_empty()?;
    } else {
        start.write_inner_content(|w| {
            for d in &v3.dimensions {
                w.create_element("Dimension").with_attribute(("start", d.to_string().as_str())).write_empty()?;
            }
            Ok(())
        })?;
    }
    Ok(())
}

/// As in FMI 2.0: outputs have no direct feedthrough (the state at the last
/// communication point; setting an input changes none of them until the
/// next step: empty `dependencies`); in initialization mode they depend on
/// inputs, start values and parameters (no `dependencies`: all knowns).
/// No calculated parameters, no clocks, no event indicators (co-simulation).
fn write_model_structure(w: &mut Writer<Vec<u8>>, vars: &[Variable], vars3: &[Variable3]) -> io::Result<()> {
    let outputs: Vec<String> = vars3
        .iter()
        .filter(|v| v.elements.first().is_some_and(|&e| vars[e as usize].causality == Causality::Output))
        .map(|v| v.value_reference.to_string())
        .collect();
    w.create_element("ModelStructure").write_inner_content(|w| {
        for vr in &outputs {
            w.create_element("Output")
                .with_attributes([("valueReference", vr.as_str()), ("dependencies", "")])
                .write_empty()?;
        }
        for vr in &outputs {
            w.create_element("InitialUnknown").with_attribute(("valueReference", vr.as_str())).write_empty()?;
        }
        Ok(())
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::writer::model_description_xml;
    use super::*;
    use crate::model::{Model, REFERENCE_RRPR_MOTOR_TOML, REFERENCE_RRPR_TOML};
    use quick_xml::events::BytesStart;
    use quick_xml::{Reader, XmlVersion};
    use std::collections::BTreeMap;

    /// One element of the parsed XML: its name, attributes and the
    /// `Dimension` starts below it.
    #[derive(Debug, Clone)]
    struct Element {
        tag: String,
        attributes: BTreeMap<String, String>,
        dimensions: Vec<usize>,
    }

    impl Element {
        fn get(&self, key: &str) -> Option<&str> {
            self.attributes.get(key).map(String::as_str)
        }
    }

    fn element(e: &BytesStart) -> Element {
        let attributes = e
            .attributes()
            .map(|a| {
                let a = a.expect("well-formed attribute");
                let value = a.normalized_value(XmlVersion::Implicit1_0).expect("escaped value").into_owned();
                (String::from_utf8(a.key.as_ref().to_vec()).unwrap(), value)
            })
            .collect();
        Element { tag: String::from_utf8(e.name().as_ref().to_vec()).unwrap(), attributes, dimensions: Vec::new() }
    }

    /// The XML parsed back: the root, the model variables (with their
    /// dimensions) and every other element, in document order.
    struct Parsed {
        root: Element,
        variables: Vec<Element>,
        others: Vec<Element>,
    }

    impl Parsed {
        fn variable(&self, name: &str) -> &Element {
            self.variables
                .iter()
                .find(|v| v.get("name") == Some(name))
                .unwrap_or_else(|| panic!("no variable `{name}`"))
        }

        fn all(&self, tag: &str) -> Vec<&Element> {
            self.others.iter().filter(|e| e.tag == tag).collect()
        }

        /// The unit and display unit of variable `name` through its
        /// `declaredType` (a variable carries neither itself).
        fn unit(&self, name: &str) -> (Option<&str>, Option<&str>) {
            let v = self.variable(name);
            assert_eq!((v.get("unit"), v.get("displayUnit")), (None, None), "`{name}` carries a unit itself");
            let Some(declared) = v.get("declaredType") else { return (None, None) };
            let types = self.all("Float64Type");
            let t =
                types.iter().find(|t| t.get("name") == Some(declared)).unwrap_or_else(|| panic!("no type {declared}"));
            (t.get("unit"), t.get("displayUnit"))
        }
    }

    fn parse(xml: &str) -> Parsed {
        let mut reader = Reader::from_str(xml);
        let mut path: Vec<String> = Vec::new();
        let (mut root, mut variables, mut others) = (None, Vec::new(), Vec::new());
        loop {
            let (e, empty) = match reader.read_event().expect("well-formed XML") {
                Event::Start(e) => (element(&e), false),
                Event::Empty(e) => (element(&e), true),
                Event::End(_) => {
                    path.pop();
                    continue;
                }
                Event::Eof => break,
                _ => continue,
            };
            match path.last().map(String::as_str) {
                None => root = Some(e.clone()),
                Some("ModelVariables") => variables.push(e.clone()),
                Some(_) if e.tag == "Dimension" && path.len() >= 2 && path[path.len() - 2] == "ModelVariables" => {
                    let v: &mut Element = variables.last_mut().expect("a variable holds the Dimension");
                    v.dimensions.push(e.get("start").expect("Dimension start").parse().unwrap());
                }
                Some(_) => others.push(e.clone()),
            }
            if !empty {
                path.push(e.tag);
            }
        }
        Parsed { root: root.expect("a root element"), variables, others }
    }

    fn fmi3(model: &Model, text: &str) -> Parsed {
        parse(&model_description_fmi3_xml(model, text))
    }

    #[test]
    fn the_reference_arm_is_described_with_arrays() {
        let model = Model::reference_rrpr();
        let vars = variables(&model);
        let vars3 = variables3(&vars);
        let xml = model_description_fmi3_xml(&model, REFERENCE_RRPR_TOML);
        let p = parse(&xml);
        assert_eq!(p.root.get("fmiVersion"), Some("3.0"));
        assert_eq!(p.root.get("instantiationToken"), Some(guid(REFERENCE_RRPR_TOML, &vars).as_str()));
        assert_eq!(p.variables.len(), vars3.len());
        for (v, v3) in p.variables.iter().zip(&vars3) {
            assert_eq!(v.get("name"), Some(v3.name.as_str()));
            assert_eq!(v.get("valueReference"), Some(v3.value_reference.to_string().as_str()));
            assert_eq!(v.dimensions, v3.dimensions, "{}", v3.name);
            if let Some(start) = v.get("start") {
                assert_eq!(start.split(' ').count(), v3.elements.len(), "{}", v3.name);
            }
        }
        let time = &p.variables[0];
        assert_eq!(
            (time.get("name"), time.get("valueReference"), time.get("causality")),
            (Some("time"), Some("0"), Some("independent"))
        );
        assert_eq!(p.variable("q").dimensions, [4]);
        assert_eq!(p.variable("f").dimensions, [4, 3]);
        assert_eq!(p.variable("f").tag, "Float64");
        assert_eq!(p.unit("f"), (Some("N"), None));
        assert_eq!(p.variable("f").get("declaredType"), Some("Force"));
        assert_eq!(p.unit("x_E"), (Some("m"), Some("mm")));
        assert_eq!(p.unit("eps"), (Some("m"), Some("mm")));
        // Joint 3 is prismatic: q mixes rad and m, so it names each element's unit instead.
        assert_eq!(p.unit("q"), (None, None));
        let q = p.variable("q");
        assert!(q.get("description").unwrap().contains("unit per element: rad (joints 1, 2, 4), m (joint 3)"), "{q:?}");
        assert!(q.get("description").unwrap().starts_with("Joint coordinate q of each joint"), "{q:?}");
        // k exists for the flexible joints 1 and 3 only.
        let k = p.variable("k");
        assert_eq!(k.dimensions, [2]);
        assert!(k.get("description").unwrap().contains("(elements: joints 1, 3)"), "{k:?}");
        assert_eq!(k.get("variability"), Some("tunable"));
        assert_eq!(k.get("start"), Some("1000000 1000000"));
        assert_eq!(p.variable("n_stick").tag, "Int32");
        assert_eq!(p.variable("n_stick").get("variability"), Some("discrete"));
        assert_eq!(p.variable("stick").tag, "Boolean");
        assert_eq!(p.variable("use_start_values").get("start"), Some("false"));
        assert_eq!(p.variable("h_max").get("variability"), Some("fixed"));
        for name in ["q_star", "qd_star", "qdd_star"] {
            let v = p.variable(name);
            assert_eq!((v.get("causality"), v.get("intermediateUpdate")), (Some("input"), Some("true")), "{name}");
            assert_eq!(v.get("start"), Some("0 0 0 0"), "{name}");
        }
        assert!(p
            .variables
            .iter()
            .filter(|v| v.get("causality") != Some("input"))
            .all(|v| v.get("intermediateUpdate").is_none()));
        // Every output once in Output and in InitialUnknown, in order.
        let outputs: Vec<&str> = p
            .variables
            .iter()
            .filter(|v| v.get("causality") == Some("output"))
            .map(|v| v.get("valueReference").unwrap())
            .collect();
        let listed: Vec<&str> = p.all("Output").iter().map(|e| e.get("valueReference").unwrap()).collect();
        let initial: Vec<&str> = p.all("InitialUnknown").iter().map(|e| e.get("valueReference").unwrap()).collect();
        assert_eq!((&listed, &initial), (&outputs, &outputs));
        assert!(p.all("Output").iter().all(|e| e.get("dependencies") == Some("")));
        let cs = &p.all("CoSimulation")[0];
        for (flag, value) in [
            ("modelIdentifier", MODEL_IDENTIFIER),
            ("canHandleVariableCommunicationStepSize", "true"),
            ("canGetAndSetFMUState", "true"),
            ("canSerializeFMUState", "true"),
            ("hasEventMode", "true"),
            ("providesIntermediateUpdate", "true"),
            ("canReturnEarlyAfterIntermediateUpdate", "true"),
            ("maxOutputDerivativeOrder", "2"),
        ] {
            assert_eq!(cs.get(flag), Some(value), "{flag}");
        }
        assert!(cs.get("fixedInternalStepSize").is_none());
        let f = p.variable("f").get("description").unwrap();
        assert!(f.starts_with("[1,1]: Component 1 of the force exerted by link 0 on link 1"), "{f}");
    }

    /// Header, units, log categories and default experiment are FMI 2.0's,
    /// and the FMI 2.0 modelDescription is the one build.rs wrote (the FMI 2.0
    /// writer untouched by FMI 3.0).
    #[test]
    fn what_fmi_2_0_also_declares_is_the_same() {
        let model = Model::reference_rrpr();
        let xml2 = model_description_xml(&model, REFERENCE_RRPR_TOML);
        let xml3 = model_description_fmi3_xml(&model, REFERENCE_RRPR_TOML);
        let written =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/modelDescription/modelDescription.xml"))
                .expect("build.rs writes modelDescription/modelDescription.xml");
        assert_eq!(xml2, written);
        let (p2, p3) = (parse(&xml2), parse(&xml3));
        for key in ["modelName", "description", "version", "generationTool", "variableNamingConvention"] {
            assert_eq!(p2.root.get(key), p3.root.get(key), "{key}");
        }
        assert_eq!(p2.root.get("guid"), p3.root.get("instantiationToken"));
        let section = |xml: &str, tag: &str| {
            let start = xml.find(&format!("<{tag}")).unwrap_or_else(|| panic!("no {tag}"));
            let end = xml[start..]
                .find(&format!("</{tag}>"))
                .map_or_else(|| xml[start..].find("/>").unwrap() + 2, |e| e + tag.len() + 3);
            xml[start..start + end].to_string()
        };
        for tag in ["UnitDefinitions", "DefaultExperiment"] {
            assert_eq!(section(&xml2, tag), section(&xml3, tag), "{tag}");
        }
        // The log categories' descriptions in FMI 3.0's terms (fmi3Warning, ...).
        assert_eq!(in_fmi3_terms(&section(&xml2, "LogCategories")), section(&xml3, "LogCategories"));
        assert!(!section(&xml3, "LogCategories").contains("fmi2"));
    }

    #[test]
    fn every_fmi_2_0_variable_is_an_element_of_one_fmi_3_0_variable() {
        for (model, text) in [
            (Model::reference_rrpr(), REFERENCE_RRPR_TOML),
            (Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap(), REFERENCE_RRPR_MOTOR_TOML),
        ] {
            let vars = variables(&model);
            let p = fmi3(&model, text);
            let elements: usize = p.variables[1..].iter().map(|v| v.dimensions.iter().product::<usize>()).sum();
            assert_eq!(elements, vars.len(), "{}", model.name);
        }
    }

    #[test]
    fn the_motor_arm_declares_its_torque_inputs_for_intermediate_update() {
        let model = Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap();
        let p = fmi3(&model, REFERENCE_RRPR_MOTOR_TOML);
        let tau_m = p.variable("tau_m");
        assert_eq!(tau_m.dimensions, [2]);
        assert_eq!(
            (p.unit("tau_m").0, tau_m.get("intermediateUpdate"), tau_m.get("start")),
            (Some("N.m"), Some("true"), Some("0 0"))
        );
        assert!(tau_m.get("description").unwrap().ends_with("(elements: joints 1, 3)"), "{tau_m:?}");
        assert!(tau_m.get("description").unwrap().starts_with("Motor torque tau_m of each joint"), "{tau_m:?}");
        assert_eq!(p.variable("static_start").tag, "Boolean");
        assert_eq!(p.variable("n_stick_m").tag, "Int32");
        assert_eq!(p.unit("theta_m"), (Some("rad"), Some("deg")));
    }

    #[test]
    fn an_all_revolute_urdf_arm_declares_units_and_display_units() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/models/urdf/xarm6/xarm6.toml");
        let model = Model::from_file(file).unwrap();
        let text = std::fs::read_to_string(file).unwrap();
        let p = fmi3(&model, &text);
        for (name, unit, display) in [
            ("q", "rad", Some("deg")),
            ("qd", "rad/s", Some("deg/s")),
            ("qdd", "rad/s2", Some("deg/s2")),
            ("F_drive", "N.m", None),
        ] {
            assert_eq!(p.variable(name).dimensions, [6], "{name}");
            assert_eq!(p.unit(name), (Some(unit), display), "{name}");
        }
        assert_eq!(p.variable("f").dimensions, [6, 3]);
    }

    #[test]
    fn different_element_ranges_give_the_loosest_range_and_say_so() {
        let model = Model::reference_rrpr();
        let mut vars = variables(&model);
        for v in vars.iter_mut().filter(|v| v.name.starts_with("q_star[")) {
            if let Type::Real { min, max, .. } = &mut v.ty {
                if v.name == "q_star[3]" {
                    (*min, *max) = (Some(-2.0), Some(0.5));
                } else {
                    (*min, *max) = (Some(-1.0), Some(1.0));
                }
            }
        }
        let vars3 = variables3(&vars);
        let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
        write_variable(&mut w, &model, &vars, &vars3[1]).unwrap();
        let p = parse(&format!("<ModelVariables>{}</ModelVariables>", String::from_utf8(w.into_inner()).unwrap()));
        let q_star = p.variable("q_star");
        assert_eq!((q_star.get("min"), q_star.get("max")), (Some("-2"), Some("1")));
        assert!(
            q_star
                .get("description")
                .unwrap()
                .ends_with("whose own ranges the FMU checks: [-1, 1] for joints 1, 2, 4, [-2, 0.5] for joint 3"),
            "{q_star:?}"
        );
    }

    /// Each unit once, through a `Float64Type` named after its quantity, and
    /// every Float64 array whose FMI 2.0 elements share a unit names that
    /// type: no variable carries `unit` or `displayUnit` itself, every type is
    /// used, and the units are the FMI 2.0 elements'.
    #[test]
    fn units_come_through_type_definitions_once_each() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/models/urdf/xarm6/xarm6.toml");
        let urdf = std::fs::read_to_string(file).unwrap();
        for (model, text) in [
            (Model::reference_rrpr(), REFERENCE_RRPR_TOML.to_string()),
            (Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap(), REFERENCE_RRPR_MOTOR_TOML.to_string()),
            (Model::from_file(file).unwrap(), urdf),
        ] {
            let vars = variables(&model);
            let vars3 = variables3(&vars);
            let p = fmi3(&model, &text);
            let types = p.all("Float64Type");
            let names: Vec<&str> = types.iter().map(|t| t.get("name").unwrap()).collect();
            let units: Vec<&str> = types.iter().map(|t| t.get("unit").unwrap()).collect();
            let distinct: std::collections::BTreeSet<&str> = units.iter().copied().collect();
            assert_eq!(distinct.len(), units.len(), "{}: one type per unit: {units:?}", model.name);
            for t in &types {
                let unit = UNITS.iter().find(|u| Some(u.name) == t.get("unit")).expect("a unit of UNITS");
                assert_eq!((t.get("name"), t.get("quantity")), (Some(unit.quantity), Some(unit.quantity)));
                assert_eq!(t.get("displayUnit"), unit.display.first().map(|(d, _)| *d));
            }
            let mut used = Vec::new();
            for (v, v3) in p.variables.iter().zip(&vars3) {
                let element_units: Vec<Option<&str>> = v3
                    .elements
                    .iter()
                    .map(|&e| match vars[e as usize].ty {
                        Type::Real { unit, .. } => unit,
                        Type::Boolean { .. } => None,
                    })
                    .collect();
                let shared =
                    element_units.first().copied().flatten().filter(|u| element_units.iter().all(|x| x == &Some(*u)));
                let expected = if v.tag == "Float64" { shared } else { None };
                assert_eq!(p.unit(&v3.name).0, expected, "{}: `{}`", model.name, v3.name);
                used.extend(v.get("declaredType"));
            }
            assert!(names.iter().all(|n| used.contains(n)), "{}: a type no variable uses", model.name);
            assert!(!types.is_empty() && types.len() < UNITS.len(), "{}", model.name);
        }
    }
}
