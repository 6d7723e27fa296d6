//! Build script: writes `modelDescription/modelDescription.xml` for the
//! default model (`models/reference_rrpr.toml`) and keeps the shared library's
//! symbol table to the FMI functions.
//!
//! The model file is read by the engine's own parser and the XML is written by
//! the FMU's own description code: both are compiled into this script from
//! `src/` (the `#[path]` modules below), so the file cannot drift from what
//! the library does at run time. Those modules may therefore depend only on
//! each other and on the build-dependencies in Cargo.toml.

#[allow(dead_code, unused_imports)]
#[path = "src/fmi/description/mod.rs"]
mod description;
#[allow(dead_code)]
#[path = "src/error.rs"]
mod error;
#[allow(dead_code)]
#[path = "src/math.rs"]
mod math;
#[allow(dead_code, unused_imports)]
#[path = "src/model/mod.rs"]
mod model;
/// The engine's state, which the output table reads (`crate::stepper::State`).
#[allow(dead_code)]
#[path = "src/stepper/state.rs"]
mod state;
mod stepper {
    pub use super::state::State;
}

use std::path::Path;

fn main() {
    let inputs = [
        "build.rs",
        "models/reference_rrpr.toml",
        "src/model",
        "src/error.rs",
        "src/math.rs",
        "src/stepper/state.rs",
        "src/fmi/description",
    ];
    for path in inputs {
        println!("cargo:rerun-if-changed={path}");
    }
    // fmi-sys compiles an exported `callback_log` helper into the crate; only
    // our own `fmi2…` functions may be visible to FMI importers. Symbols of
    // static archives (all dependencies are rlibs) stay local. GNU ld for
    // Windows ignores this for the .def export list rustc writes; there
    // scripts/mingw-link.sh (the win64 linker) cuts that list instead.
    println!("cargo:rustc-cdylib-link-arg=-Wl,--exclude-libs,ALL");

    let text = model::REFERENCE_RRPR_TOML;
    let model = match model::Model::from_toml_str(text) {
        Ok(m) => m,
        Err(e) => panic!("models/reference_rrpr.toml: {e}"),
    };
    let xml = description::model_description_xml(&model, text);
    let root = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let dir = Path::new(&root).join("modelDescription");
    let file = dir.join("modelDescription.xml");
    // Rewrite only on change, so that the file's time stamp means something.
    if std::fs::read_to_string(&file).ok().as_deref() != Some(xml.as_str()) {
        std::fs::create_dir_all(&dir).expect("create modelDescription/");
        std::fs::write(&file, xml).unwrap_or_else(|e| panic!("write {}: {e}", file.display()));
    }
}
