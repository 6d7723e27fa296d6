//! Malformed URDFs never crash and never give a wrong number: valid URDF
//! texts (tests/urdf/*.urdf and the shipped arms models/urdf/*/*.urdf, each
//! with a model file naming it) are mutated — bytes flipped, truncated,
//! elements duplicated or deleted, attribute values (whole, or one number of
//! `xyz="a b c"`) replaced with NaN, inf, 1e308, −1, 0, empty and garbage —
//! and read through `Model::from_toml_with`, the model file's reader of the
//! URDF returning the mutated text. Each result is either an error with a
//! non-empty message (the element or field and the reason), or a model that
//! validates, makes a simulator and runs 2 ms with zero inputs (and 0.5 N·m
//! on its motor drives) to a finite state or a `StepError` with a message.
//! Nothing panics. One source, `reference_rrpr_motor`, drives the reference
//! arm's joints 1 and 3 with motors (one with damping and a clearance).
//!
//! Motor drive entries generated field by field (tests/engine/common/motor_tables.rs:
//! each field omitted, admissible, extreme or garbage; misspelt keys and
//! types) on the joints j1 to j4 of the reference URDF arm are read exactly
//! as written or refused, as in a DH file; an accepted one steps like the
//! rest with a random motor torque (when its rotor's time constants against
//! the gear are at least 1e-7 s, `motor_tables::resolvable`).
//!
//! Two kinds of test: deterministic sweeps and proptest properties. The
//! sweeps replace every attribute value (and every number of a vector) of
//! every source: in the elements the reader reads numbers from (`<origin>`,
//! `<mass>`, `<inertia>`, `<axis>`, `<limit>` of a joint or an inertial) by
//! every special value, where anything that is not a number (NaN, inf,
//! 1e400, empty, garbage, a wrong count) must be refused, never read as some
//! number; everywhere else (names, visual, collision, dynamics, gazebo …) by
//! a few, where the model is refused or unchanged. They delete and duplicate
//! every element (a duplicate is refused or changes nothing) and truncate
//! at every 97th byte. The properties combine random edits; they run
//! `STICKSLIP_URDF_FUZZ_CASES` cases each (default 1000, under a second in
//! a release build; the whole file about 7 s on 2 cores). A long run:
//! `STICKSLIP_URDF_FUZZ_CASES=200000 cargo test --release --test engine urdf_fuzz`.

use proptest::prelude::*;
use stick_slip_manipulator::stepper::MotorTorques;
use stick_slip_manipulator::{DriveInputs, Model, ModelError, Simulator, StepError};

use crate::common::motor_tables;
use motor_tables::{resolvable, table, torque, Table};

/// A URDF with a model file naming it (the model file's `urdf` name is
/// ignored: the reader returns the mutated text whatever it asks for).
struct Source {
    name: &'static str,
    urdf: &'static str,
    toml: &'static str,
}

const SOURCES: [Source; 7] = [
    Source {
        name: "reference_rrpr",
        urdf: include_str!("../../models/urdf/reference_rrpr/reference_rrpr.urdf"),
        toml: include_str!("../../models/urdf/reference_rrpr/reference_rrpr.toml"),
    },
    Source {
        name: "kuka_iiwa",
        urdf: include_str!("../../models/urdf/kuka_iiwa/kuka_iiwa.urdf"),
        toml: include_str!("../../models/urdf/kuka_iiwa/kuka_iiwa.toml"),
    },
    Source {
        name: "xarm6",
        urdf: include_str!("../../models/urdf/xarm6/xarm6_robot.urdf"),
        toml: include_str!("../../models/urdf/xarm6/xarm6.toml"),
    },
    Source {
        name: "arm",
        urdf: include_str!("../urdf/arm.urdf"),
        toml: r#"urdf = "arm.urdf"
tip_link = "tcp"
end_point = [0.0, 0.0, 0.02]
[joints.joint1]
drive = { type = "flexible", k = 2.0e4, h = 3.0, clearance = 1e-4 }
[joints.joint2]
drive = { type = "flexible", k = 1.0e5, h = 10.0 }
[joints.joint3]
drive = { type = "flexible", k = 5.0e3, h = 1.0 }
"#,
    },
    Source {
        name: "plain",
        urdf: include_str!("../urdf/plain.urdf"),
        toml: r#"urdf = "plain.urdf"
[joints.shoulder]
drive = { type = "flexible", k = 1.0e4, h = 2.0 }
[joints.elbow]
drive = { type = "flexible", k = 1.0e5 }
"#,
    },
    Source {
        name: "robust",
        urdf: include_str!("../urdf/robust.urdf"),
        toml: r#"urdf = "robust.urdf"
[joints.shoulder]
drive = { type = "flexible", k = 1.0e4, h = 2.0 }
"#,
    },
    Source {
        name: "reference_rrpr_motor",
        urdf: include_str!("../../models/urdf/reference_rrpr/reference_rrpr.urdf"),
        toml: MOTOR_TOML,
    },
];

/// The reference URDF arm with motors on j1 and j3 (the rotors of
/// models/reference_rrpr_motor.toml; j3's gear with damping and a clearance).
const MOTOR_TOML: &str = r#"urdf = "reference_rrpr.urdf"
base_link = "base"
tip_link = "gripper_tip"
[joints.j1]
drive = { type = "motor", k = 1.0e6, gear_ratio = 100.0, rotor_inertia = 3.0e-4, motor_viscous = 2.0e-4, motor_coulomb = 0.03 }
friction = { mu_k = 0.2, mu_s = 0.2 }
bearings = { reaction_point = [0.0, -0.54, 0.0], l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1 }
[joints.j3]
drive = { type = "motor", k = 1.0e6, h = 100.0, clearance = 1e-5, gear_ratio = 628.3185307179587, rotor_inertia = 1.2e-4, motor_viscous = 1.0e-4, motor_coulomb = 0.02 }
friction = { mu_k = 0.2, mu_s = 0.2 }
slider = { centre = [0.0, 0.0, -0.7], a = 0.2, b = 0.07, c = 0.07 }
"#;

/// What a mutation puts in place of an attribute value or of one of its numbers.
const VALUES: [&str; 20] = [
    "NaN", "nan", "inf", "-inf", "1e308", "-1e308", "1e400", "-1", "0", "-0", "", "garbage", "1e-308", "0 0 0", "1 2",
    "1 2 3 4", "0x10", "1,5", "  ", "&amp;",
];

// ---------------------------------------------------------------------------
// The check
// ---------------------------------------------------------------------------

/// What a mutated source gave.
#[derive(Debug, Default, Clone, Copy)]
struct Tally {
    refused: usize,
    stepped: usize,
    step_errors: usize,
}

impl std::ops::AddAssign for Tally {
    fn add_assign(&mut self, o: Tally) {
        self.refused += o.refused;
        self.stepped += o.stepped;
        self.step_errors += o.step_errors;
    }
}

/// Every field of a model error is non-empty (the Display adds a prefix of
/// its own, so look inside).
fn assert_model_error_says_something(e: &ModelError, what: &str) {
    let parts: Vec<&str> = match e {
        ModelError::Io { path, reason } => vec![path, reason],
        ModelError::Syntax { reason } => vec![reason],
        ModelError::InvalidParameter { field, reason, .. } => vec![field, reason],
        ModelError::Urdf { element, reason } => vec![element, reason],
        ModelError::Invalid { field, reason } => vec![field, reason],
    };
    assert!(parts.iter().all(|p| !p.trim().is_empty()), "{what}: an error with an empty part: {e:?}");
}

/// The motor torque of the steps (N·m on every joint; joints without a
/// motor drive ignore it).
const TAU: f64 = 0.5;

/// Reads `urdf` through `source`'s model file; an accepted model validates
/// and runs 2 ms with zero drive inputs (and `TAU` on its motors) to a
/// finite state or a step error.
fn loads_or_refuses(source: &Source, urdf: &str, what: &str) -> Tally {
    let model = match Model::from_toml_with(source.toml, &|_| Ok(urdf.to_string())) {
        Err(e) => {
            assert_model_error_says_something(&e, what);
            return Tally { refused: 1, ..Tally::default() };
        }
        Ok(model) => model,
    };
    steps_or_fails(model, TAU, what)
}

/// A loaded model validates and runs 2 ms with zero drive inputs and the
/// motor torque `tau` to a finite state or a step error.
fn steps_or_fails(model: Model, tau: f64, what: &str) -> Tally {
    if let Err(e) = model.validate() {
        panic!("{what}: an accepted model does not validate: {e}");
    }
    let n = model.nq();
    let mut sim = Simulator::new(model).unwrap_or_else(|e| panic!("{what}: a valid model makes no simulator: {e}"));
    let zero = vec![0.0; n];
    let inputs = DriveInputs { q_star: &zero, qd_star: &zero, qdd_star: &zero };
    let tau = vec![tau; n];
    sim.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &zero, tau_m_accel: &zero })
        .unwrap_or_else(|e| panic!("{what}: a torque within its range is refused: {e}"));
    let step_error = |e: StepError| {
        assert!(!e.to_string().trim().is_empty(), "{what}: a step error without a message: {e:?}");
        eprintln!("{what}: {e}");
        Tally { step_errors: 1, ..Tally::default() }
    };
    if let Err(e) = sim.initialize(0.0, &inputs, None) {
        return step_error(e);
    }
    if let Err((quantity, value)) = sim.state().check_finite() {
        panic!("{what}: initialization succeeded with {quantity} = {value}");
    }
    for _ in 0..2 {
        if let Err(e) = sim.advance(&inputs, 1e-3) {
            return step_error(e);
        }
        if let Err((quantity, value)) = sim.state().check_finite() {
            panic!("{what}: a step succeeded with {quantity} = {value}");
        }
    }
    Tally { stepped: 1, ..Tally::default() }
}

/// The same chain, masses and end point (names and warnings aside).
fn same_model(a: &Model, b: &Model) -> bool {
    a.joints == b.joints && a.links == b.links && a.end_point == b.end_point && a.gravity == b.gravity
}

// ---------------------------------------------------------------------------
// Where the mutations go
// ---------------------------------------------------------------------------

/// Byte spans of the elements of `text`: `<name …/>`, or `<name …>` to the
/// first `</name>` after it (the URDF elements used here do not nest in
/// themselves).
fn element_spans(text: &str) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    for (i, _) in text.match_indices('<') {
        let rest = &text[i + 1..];
        if rest.starts_with(['/', '?', '!']) {
            continue;
        }
        let name_len = rest.find(|c: char| c.is_whitespace() || c == '>' || c == '/').unwrap_or(rest.len());
        let Some(gt) = rest.find('>') else { continue };
        if name_len == 0 || name_len > gt {
            continue;
        }
        let open_end = i + 1 + gt + 1;
        if rest[..gt].ends_with('/') {
            spans.push((i, open_end));
        } else {
            let close = format!("</{}>", &rest[..name_len]);
            if let Some(c) = text[open_end..].find(&close) {
                spans.push((i, open_end + c + close.len()));
            }
        }
    }
    spans
}

/// Byte spans of the attribute values of `text` (between the quotes of `="…"`).
fn value_spans(text: &str) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut from = 0;
    while let Some(at) = text[from..].find("=\"") {
        let start = from + at + 2;
        let Some(len) = text[start..].find('"') else { break };
        spans.push((start, start + len));
        from = start + len + 1;
    }
    spans
}

/// Byte spans of the whitespace-separated tokens inside attribute values
/// of several tokens (`xyz="a b c"`).
fn token_spans(text: &str) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    for (s, e) in value_spans(text) {
        if text[s..e].split_whitespace().count() < 2 {
            continue;
        }
        let mut token_start = None;
        for (i, c) in text[s..e].char_indices().chain(std::iter::once((e - s, ' '))) {
            match (c.is_whitespace(), token_start) {
                (false, None) => token_start = Some(s + i),
                (true, Some(t)) => {
                    spans.push((t, s + i));
                    token_start = None;
                }
                _ => {}
            }
        }
    }
    spans
}

/// One mutation of `text`: what it is, where (an index reduced modulo the
/// candidates) and a byte of choice.
fn mutate(text: &str, kind: u8, at: usize, pick: u8) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let replace = |spans: Vec<(usize, usize)>, with: &str| -> String {
        if spans.is_empty() {
            return text.to_string();
        }
        let (s, e) = spans[at % spans.len()];
        format!("{}{}{}", &text[..s], with, &text[e..])
    };
    match kind % 6 {
        0 if !bytes.is_empty() => {
            let i = at % bytes.len();
            bytes[i] ^= 1 << (pick % 8);
            String::from_utf8_lossy(&bytes).into_owned()
        }
        1 => {
            let cut = at % (bytes.len() + 1);
            String::from_utf8_lossy(&bytes[..cut]).into_owned()
        }
        2 => {
            let spans = element_spans(text);
            if spans.is_empty() {
                return text.to_string();
            }
            let (s, e) = spans[at % spans.len()];
            format!("{}{}{}", &text[..e], &text[s..e], &text[e..])
        }
        3 => replace(element_spans(text), ""),
        4 => replace(value_spans(text), VALUES[pick as usize % VALUES.len()]),
        5 => replace(token_spans(text), VALUES[pick as usize % VALUES.len()]),
        _ => text.to_string(),
    }
}

// ---------------------------------------------------------------------------
// The sources themselves, and the sweeps
// ---------------------------------------------------------------------------

#[test]
fn every_source_loads_and_steps_unmutated() {
    for s in &SOURCES {
        let t = loads_or_refuses(s, s.urdf, s.name);
        assert_eq!(t.stepped, 1, "{}: {t:?}", s.name);
        assert!(element_spans(s.urdf).len() > 10 && value_spans(s.urdf).len() > 10, "{}", s.name);
    }
}

/// Values that are not a number (or not the right count of numbers) for any
/// numeric attribute.
const NOT_NUMBERS: [&str; 12] =
    ["NaN", "nan", "inf", "-inf", "1e400", "", "garbage", "1 2 3 4", "0x10", "1,5", "&amp;", "  "];

/// True when the attribute value at `start` belongs to an element the URDF
/// reader reads numbers from: `<origin>`, `<mass>`, `<inertia>`, `<axis>`,
/// `<limit>` directly in a `<joint>` or an `<inertial>` (not in `<visual>`,
/// `<collision>`, `<dynamics>`, `<gazebo>` …, and not in a comment).
fn read_by_the_reader(text: &str, start: usize) -> bool {
    let before = &text[..start];
    if before.rfind("<!--").is_some_and(|c| before.rfind("-->").is_none_or(|e| e < c)) {
        return false;
    }
    let tag_at = before.rfind('<').expect("an attribute is inside a tag");
    let tag: String = before[tag_at + 1..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    if !["origin", "mass", "inertia", "axis", "limit"].contains(&tag.as_str()) {
        return false;
    }
    // The innermost open element around the tag.
    let last = |t: &str| before[..tag_at].rfind(t).map_or(0, |i| i + 1);
    let opened = ["<inertial", "<joint ", "<visual", "<collision", "<gazebo", "<transmission"];
    let innermost = opened.iter().max_by_key(|t| last(t)).unwrap();
    let closed = ["</inertial", "</joint>", "</visual", "</collision", "</gazebo", "</transmission"]
        .iter()
        .map(|t| last(t))
        .max()
        .unwrap();
    matches!(*innermost, "<inertial" | "<joint ") && last(innermost) > closed
}

#[test]
fn every_attribute_value_replaced_by_every_special_value() {
    let mut total = Tally::default();
    let mut read = 0;
    for s in &SOURCES {
        let original = Model::from_toml_with(s.toml, &|_| Ok(s.urdf.to_string())).unwrap();
        let mut tally = Tally::default();
        for (start, end) in value_spans(s.urdf).into_iter().chain(token_spans(s.urdf)) {
            let numeric = read_by_the_reader(s.urdf, start);
            read += usize::from(numeric);
            // Names, types, meshes, colours: a few values suffice.
            let values: &[&str] = if numeric { &VALUES } else { &["", "garbage", "NaN", "-1", "&amp;"] };
            for v in values {
                let text = format!("{}{}{}", &s.urdf[..start], v, &s.urdf[end..]);
                let what = format!("{}: `{}` at byte {start} replaced by `{v}`", s.name, &s.urdf[start..end]);
                if numeric {
                    let t = loads_or_refuses(s, &text, &what);
                    // Never a number made up for one that is not there.
                    assert!(!(NOT_NUMBERS.contains(v) && t.refused == 0), "{what}: accepted");
                    tally += t;
                } else {
                    // What the reader does not read changes nothing (names
                    // may: a refusal is fine; then no simulation is needed).
                    match Model::from_toml_with(s.toml, &|_| Ok(text.clone())) {
                        Ok(m) => assert!(same_model(&m, &original), "{what}: accepted as a different model"),
                        Err(e) => {
                            assert_model_error_says_something(&e, &what);
                            tally.refused += 1;
                        }
                    }
                }
            }
        }
        eprintln!("{}: {tally:?}", s.name);
        // The sweep reached both sides: refusals and models that run.
        assert!(tally.refused > 100 && tally.stepped > 10, "{}: {tally:?}", s.name);
        total += tally;
    }
    eprintln!("all sources: {total:?}; {read} values the reader reads");
    assert!(read > 300, "the classification of the attributes found only {read}");
}

#[test]
fn every_element_deleted_or_duplicated_and_truncations() {
    for s in &SOURCES {
        let original = Model::from_toml_with(s.toml, &|_| Ok(s.urdf.to_string())).unwrap();
        let mut tally = Tally::default();
        for (start, end) in element_spans(s.urdf) {
            let element = &s.urdf[start..end.min(start + 40)];
            let deleted = format!("{}{}", &s.urdf[..start], &s.urdf[end..]);
            tally += loads_or_refuses(s, &deleted, &format!("{}: `{element}…` deleted", s.name));
            let doubled = format!("{}{}", &s.urdf[..end], &s.urdf[start..]);
            let what = format!("{}: `{element}…` duplicated", s.name);
            tally += loads_or_refuses(s, &doubled, &what);
            // An element given twice says nothing new: refused, or the same model.
            if let Ok(m) = Model::from_toml_with(s.toml, &|_| Ok(doubled.clone())) {
                assert!(same_model(&m, &original), "{what}: accepted as a different model");
            }
        }
        for cut in (0..s.urdf.len()).step_by(97) {
            if s.urdf.is_char_boundary(cut) {
                tally += loads_or_refuses(s, &s.urdf[..cut], &format!("{}: truncated at {cut}", s.name));
            }
        }
        eprintln!("{}: {tally:?}", s.name);
        assert!(tally.refused > 10 && tally.stepped > 10, "{}: {tally:?}", s.name);
    }
}

fn cases() -> u32 {
    std::env::var("STICKSLIP_URDF_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(1000)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_urdf_loads_or_refuses_and_never_panics(
        source in 0..SOURCES.len(),
        edits in proptest::collection::vec((0u8..6, any::<usize>(), any::<u8>()), 1..5),
    ) {
        let s = &SOURCES[source];
        let mut text = s.urdf.to_string();
        for (kind, at, pick) in &edits {
            text = mutate(&text, *kind, *at, *pick);
        }
        loads_or_refuses(s, &text, &format!("{}: edits {edits:?}", s.name));
    }

    #[test]
    fn urdf_with_arbitrary_text_inserted_loads_or_refuses(
        source in 0..SOURCES.len(),
        at in any::<prop::sample::Index>(),
        insert in "\\PC{0,40}",
    ) {
        let s = &SOURCES[source];
        let mut i = at.index(s.urdf.len() + 1);
        while !s.urdf.is_char_boundary(i) {
            i -= 1;
        }
        let text = format!("{}{insert}{}", &s.urdf[..i], &s.urdf[i..]);
        loads_or_refuses(s, &text, &format!("{}: `{insert}` inserted at {i}", s.name));
    }
}

/// The motor source's model file with `table` as the drive of the reference
/// arm's joint j1 to j4 (replacing the drive of j1 and j3, an entry of its
/// own for j2 and j4).
fn with_motor_table(table: &Table) -> String {
    let name = format!("j{}", table.joint);
    let header = format!("[joints.{name}]\n");
    match MOTOR_TOML.find(&header) {
        Some(at) => {
            let line_start = at + header.len();
            let line_end = line_start + MOTOR_TOML[line_start..].find('\n').unwrap();
            assert!(MOTOR_TOML[line_start..].starts_with("drive = "));
            format!("{}{}{}", &MOTOR_TOML[..line_start], table.toml(), &MOTOR_TOML[line_end..])
        }
        None => format!("{MOTOR_TOML}{header}{}\n", table.toml()),
    }
}

proptest! {
    // A fixed seed unless STICKSLIP_MOTOR_FUZZ_SEED says otherwise (see `motor_tables::seed`).
    #![proptest_config(ProptestConfig { cases: cases() / 2, failure_persistence: None, rng_seed: motor_tables::seed(), ..ProptestConfig::default() })]

    #[test]
    fn generated_motor_entries_are_read_exactly_or_refused(table in table(), tau in torque()) {
        let urdf = SOURCES[6].urdf;
        let toml = with_motor_table(&table);
        let what = format!("motor entry on j{}: {}", table.joint, table.toml());
        match (Model::from_toml_with(&toml, &|_| Ok(urdf.to_string())), table.expected()) {
            (Ok(model), Some(drive)) => {
                prop_assert_eq!(model.joints[table.joint - 1].drive, drive, "{}", what);
                if resolvable(&drive) {
                    steps_or_fails(model, tau, &what);
                }
            }
            (Err(e), None) => assert_model_error_says_something(&e, &what),
            (Ok(model), None) => prop_assert!(false, "{what}: accepted as {:?}", model.joints[table.joint - 1].drive),
            (Err(e), Some(drive)) => prop_assert!(false, "{what}: refused ({drive:?}): {e}"),
        }
    }
}

#[test]
fn the_motor_source_has_motors_on_j1_and_j3_and_the_table_helper_places_entries() {
    let m = Model::from_toml_with(MOTOR_TOML, &|_| Ok(SOURCES[6].urdf.to_string())).unwrap();
    assert_eq!(m.motor_joints(), [0, 2]);
    assert_eq!(m.joints[0].drive, Model::reference_rrpr_motor().joints[0].drive);
    assert!(m.joints[2].drive.spring().is_some_and(|s| s.clearance == 1e-5 && s.damping == 100.0));
    for joint in 1..=4 {
        let table = Table { fields: vec![motor_tables::Field::Omitted; 7], kind: "motor", extra_key: None, joint };
        let text = with_motor_table(&table);
        assert_eq!(text.matches("[joints.").count(), if joint % 2 == 1 { 2 } else { 3 });
        assert!(text.contains(&format!("[joints.j{joint}]\ndrive = {{ type = \"motor\" }}")), "{text}");
    }
}

#[test]
fn mutations_change_the_text() {
    let s = &SOURCES[0];
    for kind in 0..6 {
        assert_ne!(mutate(s.urdf, kind, 1234, 3), s.urdf, "mutation {kind} changed nothing");
    }
}
