//! The model-file parser never panics: arbitrary text, and arbitrary
//! mutations of the reference model file (characters replaced, deleted,
//! inserted; numbers replaced by extreme ones), either give an error or a
//! model that validates, and such a model simulates a communication step to
//! a finite state or an error, without panicking.

use proptest::prelude::*;
use stick_slip_manipulator::model::REFERENCE_RRPR_TOML;
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

/// Numbers a mutation may put in place of one in the file.
const EXTREMES: [&str; 14] =
    ["0", "-0.0", "1e300", "-1e300", "1e-300", "nan", "inf", "-inf", "1e12", "2.0", "-1", "1e-9", "99", "0.5"];

fn parses_or_refuses(text: &str) {
    let Ok(model) = Model::from_toml_str(text) else { return };
    model.validate().expect("a parsed model is valid");
    let n = model.nq();
    let mut sim = Simulator::new(model).expect("a valid model makes a simulator");
    let zero = vec![0.0; n];
    let inputs = DriveInputs { q_star: &zero, qd_star: &zero, qdd_star: &zero };
    if sim.initialize(0.0, &inputs, None).is_ok() && sim.advance(&inputs, 1e-3).is_ok() {
        assert!(sim.state().check_finite().is_ok(), "{:?}", sim.state().check_finite());
    }
}

/// Byte offsets of the numbers in the reference file.
fn number_spans() -> Vec<(usize, usize)> {
    let bytes = REFERENCE_RRPR_TOML.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric() && bytes[i - 1] != b'_');
        if starts {
            let start = if i > 0 && bytes[i - 1] == b'-' { i - 1 } else { i };
            let mut end = i;
            while end < bytes.len() && (bytes[end].is_ascii_digit() || matches!(bytes[end], b'.' | b'e' | b'E' | b'-' | b'+')) {
                end += 1;
            }
            spans.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    spans
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_text(text in "\\PC{0,400}") {
        parses_or_refuses(&text);
    }

    #[test]
    fn mutated_reference_file(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..3, any::<char>()), 1..6),
    ) {
        let mut text: Vec<char> = REFERENCE_RRPR_TOML.chars().collect();
        for (at, kind, c) in edits {
            if text.is_empty() {
                break;
            }
            let i = at.index(text.len());
            match kind {
                0 => text[i] = c,
                1 => { text.remove(i); }
                _ => text.insert(i, c),
            }
        }
        parses_or_refuses(&text.into_iter().collect::<String>());
    }

    #[test]
    fn extreme_numbers_in_the_reference_file(
        picks in proptest::collection::vec((any::<prop::sample::Index>(), 0..EXTREMES.len()), 1..4),
    ) {
        let spans = number_spans();
        let mut chosen: Vec<(usize, usize, &str)> =
            picks.iter().map(|(at, e)| { let (s, t) = spans[at.index(spans.len())]; (s, t, EXTREMES[*e]) }).collect();
        chosen.sort_by_key(|c| std::cmp::Reverse(c.0));
        chosen.dedup_by_key(|c| c.0);
        let mut text = REFERENCE_RRPR_TOML.to_string();
        for (start, end, number) in chosen {
            text.replace_range(start..end, number);
        }
        parses_or_refuses(&text);
    }
}

#[test]
fn the_reference_file_has_numbers_to_mutate() {
    let spans = number_spans();
    assert!(spans.len() > 50, "{} numbers", spans.len());
    for (s, e) in spans {
        let text = &REFERENCE_RRPR_TOML[s..e];
        assert!(text.parse::<f64>().is_ok(), "`{text}` is not a number");
    }
}
