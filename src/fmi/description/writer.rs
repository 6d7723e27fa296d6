//! `modelDescription.xml` (FMI 2.0, co-simulation only) written with quick-xml.
//!
//! Only attributes of the FMI 2.0 schema are written, and of those only the
//! ones strict readers (the `fmi` crate) know.

use super::variables::{guid, variables, Causality, Initial, Type, Variability, Variable};
use super::{DEFAULT_EXPERIMENT, LOG_CATEGORIES, MODEL_IDENTIFIER, UNITS};
use crate::model::{JointKind, Model};
use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::io;

/// A real number as an xs:double that every reader parses back to the same
/// bits (Rust's shortest round-trip digits).
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

/// The modelDescription of the FMU for `model`, parsed from `model_text`
/// (the GUID is derived from the text and the variable layout).
pub fn model_description_xml(model: &Model, model_text: &str) -> String {
    let vars = variables(model);
    let guid = guid(model_text, &vars);
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_document(&mut w, model, &vars, &guid).expect("writing to memory cannot fail");
    let mut xml = String::from_utf8(w.into_inner()).expect("quick-xml writes UTF-8");
    xml.push('\n');
    xml
}

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

fn write_document(w: &mut Writer<Vec<u8>>, model: &Model, vars: &[Variable], guid: &str) -> io::Result<()> {
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
            ("fmiVersion", "2.0"),
            ("modelName", model.name.as_str()),
            ("guid", guid),
            ("description", description.as_str()),
            ("version", env!("CARGO_PKG_VERSION")),
            ("generationTool", tool),
            ("variableNamingConvention", "structured"),
        ])
        .write_inner_content(|w| {
            write_co_simulation(w)?;
            write_units(w)?;
            write_log_categories(w)?;
            let (start, stop, step) = DEFAULT_EXPERIMENT;
            w.create_element("DefaultExperiment")
                .with_attributes([
                    ("startTime", real(start).as_str()),
                    ("stopTime", &real(stop)),
                    ("stepSize", &real(step)),
                    // The relative tolerance of the model's error control,
                    // which fmi2SetupExperiment's tolerance overrides.
                    ("tolerance", &real(model.integrator.error_tolerance)),
                ])
                .write_empty()?;
            w.create_element("ModelVariables")
                .write_inner_content(|w| vars.iter().try_for_each(|v| write_variable(w, v)))?;
            write_model_structure(w, vars)
        })?;
    Ok(())
}

fn write_co_simulation(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("CoSimulation")
        .with_attributes([
            ("modelIdentifier", MODEL_IDENTIFIER),
            ("needsExecutionTool", "false"),
            ("canHandleVariableCommunicationStepSize", "true"),
            ("canInterpolateInputs", "true"),
            ("maxOutputDerivativeOrder", "0"),
            ("canRunAsynchronuously", "false"),
            ("canBeInstantiatedOnlyOncePerProcess", "false"),
            ("canNotUseMemoryManagementFunctions", "true"),
            ("canGetAndSetFMUstate", "true"),
            ("canSerializeFMUstate", "true"),
            ("providesDirectionalDerivative", "false"),
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

fn write_log_categories(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("LogCategories").write_inner_content(|w| {
        for (name, description) in LOG_CATEGORIES {
            w.create_element("Category")
                .with_attributes([("name", name), ("description", description)])
                .write_empty()?;
        }
        Ok(())
    })?;
    Ok(())
}

fn write_variable(w: &mut Writer<Vec<u8>>, v: &Variable) -> io::Result<()> {
    let vr = v.value_reference.to_string();
    let causality = match v.causality {
        Causality::Parameter => "parameter",
        Causality::Input => "input",
        Causality::Output => "output",
    };
    let variability = match v.variability {
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    };
    let mut attributes = vec![
        ("name", v.name.as_str()),
        ("valueReference", vr.as_str()),
        ("description", v.description.as_str()),
        ("causality", causality),
        ("variability", variability),
    ];
    match v.initial {
        Some(Initial::Exact) => attributes.push(("initial", "exact")),
        Some(Initial::Calculated) => attributes.push(("initial", "calculated")),
        None => {}
    }
    w.create_element("ScalarVariable").with_attributes(attributes).write_inner_content(|w| {
        match v.ty {
            Type::Real { unit, min, max, start } => {
                let mut a: Vec<(&str, String)> = Vec::new();
                a.extend(unit.map(|u| ("unit", u.to_string())));
                a.extend(min.map(|x| ("min", real(x))));
                a.extend(max.map(|x| ("max", real(x))));
                a.extend(start.map(|x| ("start", real(x))));
                w.create_element("Real").with_attributes(a.iter().map(|(k, v)| (*k, v.as_str()))).write_empty()?;
            }
            Type::Boolean { start } => {
                let a: Vec<(&str, &str)> = start.map(|s| ("start", boolean(s))).into_iter().collect();
                w.create_element("Boolean").with_attributes(a).write_empty()?;
            }
        }
        Ok(())
    })?;
    Ok(())
}

/// Outputs have no direct feedthrough: they are the state at the last
/// communication point, so setting an input changes none of them until the
/// next step (empty `dependencies`). During initialization they depend on
/// inputs, start values and parameters (no `dependencies`: all knowns).
fn write_model_structure(w: &mut Writer<Vec<u8>>, vars: &[Variable]) -> io::Result<()> {
    let outputs: Vec<String> =
        vars.iter().filter(|v| v.causality == Causality::Output).map(|v| (v.value_reference + 1).to_string()).collect();
    w.create_element("ModelStructure").write_inner_content(|w| {
        w.create_element("Outputs").write_inner_content(|w| {
            for index in &outputs {
                w.create_element("Unknown")
                    .with_attributes([("index", index.as_str()), ("dependencies", "")])
                    .write_empty()?;
            }
            Ok(())
        })?;
        w.create_element("InitialUnknowns").write_inner_content(|w| {
            for index in &outputs {
                w.create_element("Unknown").with_attribute(("index", index.as_str())).write_empty()?;
            }
            Ok(())
        })?;
        Ok(())
    })?;
    Ok(())
}
