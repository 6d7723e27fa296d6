//! Packs an FMI 2.0 co-simulation FMU from a model file.
//!
//! Usage: package_fmu [--model FILE] [--lib FILE] [--win64-lib FILE] [--darwin64-lib FILE] [--out FILE]
//!
//! * `--model`: the model file (TOML) the FMU runs; default: the reference
//!   manipulator, `models/reference_rrpr.toml` as compiled into the crate.
//! * `--lib`: the linux64 release cdylib; default `libstick_slip_manipulator.so`
//!   next to this executable (`cargo build --release` puts both there).
//! * `--win64-lib`: the win64 DLL (`scripts/build_fmu.sh` cross-builds it);
//!   without it the FMU has no win64 binary.
//! * `--darwin64-lib`: the universal (x86_64 + arm64) macOS dylib
//!   (`scripts/build_fmu.sh --platforms linux64,win64,darwin64` cross-builds
//!   it); without it the FMU has no darwin64 binary.
//! * `--out`: the `.fmu`; default `<target>/fmu/StickSlipManipulator.fmu`,
//!   `<target>` being the directory above this executable's.
//!
//! The FMU holds `modelDescription.xml` (written for the model by the same
//! code as `build.rs` uses), `binaries/linux64/StickSlipManipulator.so`,
//! `binaries/win64/StickSlipManipulator.dll` and
//! `binaries/darwin64/StickSlipManipulator.dylib` when given, and
//! `resources/model.toml` (the model file as given, which the FMU reads at
//! fmi2Instantiate and whose text the GUID is derived from). For the tools
//! that import it (FMI 2.0 §2.3): `documentation/index.html`, the FMU's
//! documentation written from the same model and variables as the
//! modelDescription (`description::documentation_html`), and `model.png`,
//! its icon, a picture of the chain (`fmi::icon`).

use std::io::Write;
use std::path::{Path, PathBuf};
use stick_slip_manipulator::fmi::description::{documentation_html, model_description_xml, MODEL_IDENTIFIER};
use stick_slip_manipulator::fmi::icon::model_icon;
use stick_slip_manipulator::model::{with_urdf_file_name, ModelSource, REFERENCE_RRPR_TOML};
use stick_slip_manipulator::Model;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, DateTime, ZipWriter};

fn main() {
    if let Err(e) = run() {
        eprintln!("package_fmu: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let exe_dir = std::env::current_exe()?.parent().map(Path::to_path_buf).ok_or("no directory of the executable")?;
    let mut model_path: Option<PathBuf> = None;
    let mut lib = exe_dir.join("libstick_slip_manipulator.so");
    let mut win64_lib: Option<PathBuf> = None;
    let mut darwin64_lib: Option<PathBuf> = None;
    let mut out = exe_dir.parent().unwrap_or(&exe_dir).join("fmu").join(format!("{MODEL_IDENTIFIER}.fmu"));
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().map(PathBuf::from).ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--model" => model_path = Some(value()?),
            "--lib" => lib = value()?,
            "--win64-lib" => win64_lib = Some(value()?),
            "--darwin64-lib" => darwin64_lib = Some(value()?),
            "--out" => out = value()?,
            "-h" | "--help" => {
                println!("usage: package_fmu [--model FILE] [--lib FILE] [--win64-lib FILE] [--darwin64-lib FILE] [--out FILE]");
                return Ok(());
            }
            _ => {
                return Err(format!(
                    "unknown argument {a} (usage: package_fmu [--model FILE] [--lib FILE] [--win64-lib FILE] [--darwin64-lib FILE] [--out FILE])"
                )
                .into())
            }
        }
    }
    let text = match &model_path {
        Some(p) => std::fs::read_to_string(p).map_err(|e| format!("cannot read {}: {e}", p.display()))?,
        None => REFERENCE_RRPR_TOML.to_string(),
    };
    let shown = model_path.as_deref().unwrap_or(Path::new("reference model")).display().to_string();
    let model = match &model_path {
        Some(p) => Model::from_file(p),
        None => Model::from_toml_str(&text),
    }
    .map_err(|e| format!("{shown}: {e}"))?;
    for warning in &model.warnings {
        eprintln!("package_fmu: warning: {shown}: {warning}");
    }
    // A URDF model carries its URDF in resources/, its model file naming it there.
    let mut resources = Vec::new();
    let source = match Model::urdf_reference(&text) {
        None => ModelSource::toml(text),
        Some(reference) => {
            let dir = model_path.as_deref().and_then(Path::parent).unwrap_or(Path::new("."));
            let urdf_path = dir.join(&reference);
            let urdf =
                std::fs::read_to_string(&urdf_path).map_err(|e| format!("cannot read {}: {e}", urdf_path.display()))?;
            let file_name = Path::new(&reference)
                .file_name()
                .and_then(|n| n.to_str())
                .filter(|n| *n != "model.toml")
                .ok_or_else(|| format!("{shown}: the URDF `{reference}` needs a file name other than model.toml"))?
                .to_string();
            let toml = with_urdf_file_name(&text, &file_name).ok_or_else(|| {
                format!("{shown}: cannot rewrite its `urdf = ...` line to name resources/{file_name}; put `urdf` on a line of its own")
            })?;
            let packaged = ModelSource { toml, urdf: Some(urdf) };
            // What the FMU will read must be the model that was checked here.
            if packaged.model().map_err(|e| format!("{shown} as packaged: {e}"))? != model {
                return Err(format!("{shown}: the packaged model file does not give the same model").into());
            }
            resources.push((format!("resources/{file_name}"), packaged.urdf.clone().unwrap_or_default()));
            packaged
        }
    };
    let text = source.fingerprint_text().into_owned();
    let mut binaries = vec![(format!("binaries/linux64/{MODEL_IDENTIFIER}.so"), read_library(&lib)?)];
    if let Some(dll) = &win64_lib {
        binaries.push((format!("binaries/win64/{MODEL_IDENTIFIER}.dll"), read_library(dll)?));
    }
    if let Some(dylib) = &darwin64_lib {
        binaries.push((format!("binaries/darwin64/{MODEL_IDENTIFIER}.dylib"), read_library(dylib)?));
    }
    let xml = model_description_xml(&model, &text);
    let documentation = documentation_html(&model, &text);
    let icon = model_icon(&model);

    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    // Written next to the target and renamed, so that a reader never sees half an FMU.
    let partial = out.with_extension("fmu.part");
    let mut zip = ZipWriter::new(std::fs::File::create(&partial)?);
    // Fixed time stamps: the same inputs give the same bytes.
    let options = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .last_modified_time(DateTime::default());
    zip.start_file("modelDescription.xml", options)?;
    zip.write_all(xml.as_bytes())?;
    zip.start_file("model.png", options)?;
    zip.write_all(&icon)?;
    zip.start_file("documentation/index.html", options)?;
    zip.write_all(documentation.as_bytes())?;
    for (name, binary) in &binaries {
        zip.start_file(name.as_str(), options.unix_permissions(0o755))?;
        zip.write_all(binary)?;
    }
    zip.start_file("resources/model.toml", options)?;
    zip.write_all(source.toml.as_bytes())?;
    for (name, content) in &resources {
        zip.start_file(name.as_str(), options)?;
        zip.write_all(content.as_bytes())?;
    }
    zip.finish()?;
    std::fs::rename(&partial, &out)?;
    let platforms: Vec<&str> = binaries.iter().filter_map(|(name, _)| name.split('/').nth(1)).collect();
    eprintln!(
        "package_fmu: wrote {} (model `{}`, {} joints; platforms {})",
        out.display(),
        model.name,
        model.nq(),
        platforms.join(", ")
    );
    Ok(())
}

fn read_library(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path)
        .map_err(|e| format!("cannot read the library {}: {e} (run `scripts/build_fmu.sh`)", path.display()))
}
