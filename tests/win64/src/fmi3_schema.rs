//! Why the `fmi` crate (0.8) cannot import our FMI 3.0 FMU as it is, and the
//! one change that lets it: shared by the FMI 3.0 masters of `tests/win64`
//! and by `tests/engine/fmi3_crate.rs` of the main crate (which includes this file
//! with `#[path]`; plain std only, so that it compiles in both packages).
//!
//! The crate parses `modelDescription.xml` with `fmi-schema` 0.8, whose
//! `<Float64>`/`<Float32>` variable structs (`impl_float_type!` in
//! `fmi-schema/src/fmi3/variable/mod.rs`) are derived with
//! `strict(unknown_attribute, unknown_element)` but declare only `name`,
//! `valueReference`, `description`, `causality`, `variability`,
//! `canHandleMultipleSetPerTimeInstant`, `clocks`, `declaredType`,
//! `Dimension`, `intermediateUpdate`, `previous`, `start`, `initial`, `min`,
//! `max`, `derivative`, `reinit`, `Annotations` and `Alias`. The FMI 3.0
//! schema (`fmi3Variable.xsd`, type `fmi3Float64`) also allows the
//! `fmi3RealBaseAttributes` `quantity`, `unit`, `displayUnit`,
//! `relativeQuantity`, `unbounded` and `nominal`: any FMU that gives a float
//! variable its unit directly is refused with
//! `Schema(XmlParse(UnknownField { name: "FmiFloat64", field: "unit" }))`.
//! (Its `<Float64Type>` type definitions do have `unit` and `displayUnit`:
//! the crate only reads units given through `declaredType`.) The current
//! rust-fmi main branch (checked up to 2026-04-26, commit ead2422) has the
//! same struct.
//!
//! Our modelDescription is valid FMI 3.0 (fmpy validates it against the
//! standard's XSD) and stays as it is. The masters hand the crate a copy
//! of the FMU whose `modelDescription.xml` lacks the `unit` and
//! `displayUnit` attributes of its float variables — nothing else differs,
//! and none of them is read by the masters — and use the crate's own
//! import unchanged otherwise. They first import the FMU unchanged: should
//! a later `fmi` crate read the units, they use it as it is; any other
//! refusal than this one fails ([`assert_known_refusal`]).

/// What fmi-schema 0.8 answers for a `<Float64>` with a `unit` attribute
/// (the `Debug` form of the crate's error).
pub const FLOAT64_UNIT_REJECTED: &str = r#"UnknownField { name: "FmiFloat64", field: "unit" }"#;

/// The attributes removed from float variables.
pub const UNIT_ATTRIBUTES: [&str; 2] = ["unit", "displayUnit"];

/// Panics unless `error` (of an import of the unchanged FMU) is the
/// refusal explained above: any other is a real error.
pub fn assert_known_refusal(error: &dyn std::fmt::Debug) {
    let text = format!("{error:?}");
    assert!(
        text.contains(FLOAT64_UNIT_REJECTED),
        "the fmi crate refuses the FMU for another reason than the known one ({FLOAT64_UNIT_REJECTED}): {text}"
    );
}

/// `xml` without the `unit` and `displayUnit` attributes of its `<Float64>`
/// and `<Float32>` elements (variables; `<Float64Type>` definitions keep
/// theirs), and how many attributes were removed. Everything else, the
/// other attributes' text and quoting included, is copied unchanged.
pub fn strip_float_units(xml: &str) -> (String, usize) {
    let mut out = String::with_capacity(xml.len());
    let mut removed = 0;
    let mut rest = xml;
    while let Some(open) = rest.find('<') {
        out.push_str(&rest[..open]);
        rest = &rest[open..];
        let float_tag = ["<Float64", "<Float32"]
            .into_iter()
            .find(|tag| rest.starts_with(tag) && rest[tag.len()..].starts_with(char::is_whitespace));
        let Some(tag) = float_tag else {
            out.push('<');
            rest = &rest[1..];
            continue;
        };
        let end = tag_end(rest);
        out.push_str(tag);
        out.push_str(&strip_attributes(&rest[tag.len()..end], &mut removed));
        rest = &rest[end..];
    }
    out.push_str(rest);
    (out, removed)
}

/// The length of the start tag at the beginning of `s`, up to and with its
/// `>` (a `>` inside a quoted attribute value does not end it).
fn tag_end(s: &str) -> usize {
    let mut quote = None;
    for (i, c) in s.char_indices() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '>') => return i + 1,
            _ => {}
        }
    }
    panic!("modelDescription.xml: unterminated start tag `{}`", &s[..s.len().min(80)])
}

/// The attribute list `attrs` of a start tag (after its name, with the
/// closing `>` or `/>`) without the unit attributes.
fn strip_attributes(attrs: &str, removed: &mut usize) -> String {
    let mut out = String::with_capacity(attrs.len());
    let mut rest = attrs;
    loop {
        let trimmed = rest.trim_start();
        let space = &rest[..rest.len() - trimmed.len()];
        let Some(eq) = trimmed.find('=').filter(|&eq| !trimmed[..eq].contains(['>', '/'])) else {
            out.push_str(rest); // `>` or `/>`, with what precedes it
            return out;
        };
        let name = trimmed[..eq].trim_end();
        let after = trimmed[eq + 1..].trim_start();
        let quote = after.chars().next().expect("attribute value");
        assert!(quote == '"' || quote == '\'', "attribute `{name}` without a quoted value");
        let close = after[1..].find(quote).expect("closing quote") + 2;
        let attribute_len = trimmed.len() - after.len() + close;
        if UNIT_ATTRIBUTES.contains(&name) {
            *removed += 1;
        } else {
            out.push_str(space);
            out.push_str(&trimmed[..attribute_len]);
        }
        rest = &trimmed[attribute_len..];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_only_the_units_of_float_variables() {
        let xml = r#"<Float64Type name="T" unit="m"/><Float64 name="q" valueReference="4" description="a > b, unit='rad'" unit="rad" displayUnit="deg" min="0"><Dimension start="4"/></Float64><Int32 name="n" valueReference="8"/><Float32 name='x' unit='m'/>"#;
        let (out, removed) = strip_float_units(xml);
        assert_eq!(removed, 3);
        assert_eq!(
            out,
            r#"<Float64Type name="T" unit="m"/><Float64 name="q" valueReference="4" description="a > b, unit='rad'" min="0"><Dimension start="4"/></Float64><Int32 name="n" valueReference="8"/><Float32 name='x'/>"#
        );
    }
}
