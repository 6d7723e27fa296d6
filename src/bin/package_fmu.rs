//! Packs an FMI 2.0 co-simulation FMU from a model file, or with `--fmi3`
//! an FMI 3.0 one.
//!
//! Usage: package_fmu [--fmi3] [--model FILE] [--lib FILE] [--win64-lib FILE] [--darwin64-lib FILE] [--out FILE]
//!
//! * `--fmi3`: the FMI 3.0 FMU (layout below) instead of the FMI 2.0 one.
//! * `--model`: the model file (TOML) the FMU runs; default: the reference
//!   manipulator, `models/reference_rrpr.toml` as compiled into the crate.
//! * `--lib`: the linux64 release cdylib; default `libstick_slip_manipulator.so`
//!   next to this executable (`cargo build --release` puts both there), with
//!   `--fmi3` `libstick_slip_manipulator_fmi3.so`.
//! * `--win64-lib`: the win64 DLL (`scripts/build_fmu.sh` cross-builds it);
//!   without it the FMU has no win64 binary.
//! * `--darwin64-lib`: the universal (x86_64 + arm64) macOS dylib
//!   (`scripts/build_fmu.sh --platforms linux64,win64,darwin64` cross-builds
//!   it); without it the FMU has no darwin64 binary. FMI 3.0 has a directory
//!   per architecture, so with `--fmi3` the universal file is split into its
//!   two thin slices (read from its fat Mach-O header; anything but a
//!   universal file of exactly an x86_64 and an arm64 slice is refused).
//! * `--out`: the `.fmu`; default `<target>/fmu/StickSlipManipulator.fmu`,
//!   with `--fmi3` `<target>/fmu/StickSlipManipulator-fmi3.fmu`, `<target>`
//!   being the directory above this executable's.
//!
//! The FMI 2.0 FMU holds `modelDescription.xml` (written for the model by the
//! same code as `build.rs` uses), `binaries/linux64/StickSlipManipulator.so`,
//! `binaries/win64/StickSlipManipulator.dll` and
//! `binaries/darwin64/StickSlipManipulator.dylib` when given, and
//! `resources/model.toml` (the model file as given, which the FMU reads at
//! fmi2Instantiate and whose text the GUID is derived from; a URDF model's
//! URDF beside it). For the tools that import it (FMI 2.0 §2.3):
//! `documentation/index.html`, the FMU's documentation written from the same
//! model and variables as the modelDescription (`description::documentation_html`),
//! and `model.png`, its icon, a picture of the chain (`fmi::icon`).
//!
//! The FMI 3.0 FMU holds the FMI 3.0 `modelDescription.xml`
//! (`description::model_description_fmi3_xml`: the same variables, grouped
//! into arrays), `binaries/x86_64-linux/StickSlipManipulator.so`,
//! `binaries/x86_64-windows/StickSlipManipulator.dll`,
//! `binaries/x86_64-darwin/StickSlipManipulator.dylib` and
//! `binaries/aarch64-darwin/StickSlipManipulator.dylib` (FMI 3.0 §2.5's
//! platform tuples), the same `resources/` and `documentation/index.html`, and
//! the icon as `terminalsAndIcons/icon.png` (FMI 3.0 §2.4.8: the FMU icon
//! without terminals; `terminalsAndIcons.xml` is optional and left out, the
//! FMU declaring no terminals).

use std::io::Write;
use std::path::{Path, PathBuf};
use stick_slip_manipulator::fmi::description::{
    documentation_html, model_description_fmi3_xml, model_description_xml, MODEL_IDENTIFIER,
};
use stick_slip_manipulator::fmi::icon::model_icon;
use stick_slip_manipulator::model::{with_urdf_file_name, ModelSource, REFERENCE_RRPR_TOML};
use stick_slip_manipulator::Model;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, DateTime, ZipWriter};

const USAGE: &str =
    "usage: package_fmu [--fmi3] [--model FILE] [--lib FILE] [--win64-lib FILE] [--darwin64-lib FILE] [--out FILE]";

fn main() {
    if let Err(e) = run() {
        eprintln!("package_fmu: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let exe_dir = std::env::current_exe()?.parent().map(Path::to_path_buf).ok_or("no directory of the executable")?;
    let mut fmi3 = false;
    let mut model_path: Option<PathBuf> = None;
    let mut lib: Option<PathBuf> = None;
    let mut win64_lib: Option<PathBuf> = None;
    let mut darwin64_lib: Option<PathBuf> = None;
    let mut out: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().map(PathBuf::from).ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--fmi3" => fmi3 = true,
            "--model" => model_path = Some(value()?),
            "--lib" => lib = Some(value()?),
            "--win64-lib" => win64_lib = Some(value()?),
            "--darwin64-lib" => darwin64_lib = Some(value()?),
            "--out" => out = Some(value()?),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            _ => return Err(format!("unknown argument {a} ({USAGE})").into()),
        }
    }
    let (lib_name, fmu_name) = if fmi3 {
        ("libstick_slip_manipulator_fmi3.so", format!("{MODEL_IDENTIFIER}-fmi3.fmu"))
    } else {
        ("libstick_slip_manipulator.so", format!("{MODEL_IDENTIFIER}.fmu"))
    };
    let lib = lib.unwrap_or_else(|| exe_dir.join(lib_name));
    let out = out.unwrap_or_else(|| exe_dir.parent().unwrap_or(&exe_dir).join("fmu").join(fmu_name));
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
    let so = read_library(&lib)?;
    let dll = win64_lib.as_deref().map(read_library).transpose()?;
    let dylib = darwin64_lib.as_deref().map(read_library).transpose()?;
    let documentation = documentation_html(&model, &text);
    let icon = model_icon(&model);

    let mut binaries = Vec::new();
    let (xml, icon_path) = if fmi3 {
        binaries.push(Entry::binary(format!("binaries/x86_64-linux/{MODEL_IDENTIFIER}.so"), so));
        if let Some(dll) = dll {
            binaries.push(Entry::binary(format!("binaries/x86_64-windows/{MODEL_IDENTIFIER}.dll"), dll));
        }
        if let (Some(dylib), Some(path)) = (dylib, &darwin64_lib) {
            let (x86_64, arm64) =
                darwin_slices(&dylib).map_err(|e| format!("--darwin64-lib {}: {e}", path.display()))?;
            binaries.push(Entry::binary(format!("binaries/x86_64-darwin/{MODEL_IDENTIFIER}.dylib"), x86_64));
            binaries.push(Entry::binary(format!("binaries/aarch64-darwin/{MODEL_IDENTIFIER}.dylib"), arm64));
        }
        (model_description_fmi3_xml(&model, &text), "terminalsAndIcons/icon.png")
    } else {
        binaries.push(Entry::binary(format!("binaries/linux64/{MODEL_IDENTIFIER}.so"), so));
        if let Some(dll) = dll {
            binaries.push(Entry::binary(format!("binaries/win64/{MODEL_IDENTIFIER}.dll"), dll));
        }
        if let Some(dylib) = dylib {
            binaries.push(Entry::binary(format!("binaries/darwin64/{MODEL_IDENTIFIER}.dylib"), dylib));
        }
        (model_description_xml(&model, &text), "model.png")
    };
    let platforms: Vec<String> = binaries.iter().filter_map(|b| b.name.split('/').nth(1)).map(str::to_string).collect();

    let mut entries = vec![
        Entry::file("modelDescription.xml", xml.into_bytes()),
        Entry::file(icon_path, icon),
        Entry::file("documentation/index.html", documentation.into_bytes()),
    ];
    entries.extend(binaries);
    entries.push(Entry::file("resources/model.toml", source.toml.into_bytes()));
    entries.extend(resources.into_iter().map(|(name, content)| Entry::file(name, content.into_bytes())));
    write_fmu(&out, &entries)?;
    eprintln!(
        "package_fmu: wrote {} (model `{}`, {} joints; platforms {})",
        out.display(),
        model.name,
        model.nq(),
        platforms.join(", ")
    );
    Ok(())
}

/// One file of the archive.
struct Entry {
    /// Its path in the archive.
    name: String,
    /// Its content.
    bytes: Vec<u8>,
    /// A shared library: stored with mode 0755.
    executable: bool,
}

impl Entry {
    fn file(name: impl Into<String>, bytes: Vec<u8>) -> Entry {
        Entry { name: name.into(), bytes, executable: false }
    }

    fn binary(name: String, bytes: Vec<u8>) -> Entry {
        Entry { name, bytes, executable: true }
    }
}

/// Writes the archive `out` of `entries`, in their order, for FMI 2.0 and 3.0
/// alike: deflated, with fixed time stamps (the same inputs give the same
/// bytes), written next to `out` and renamed, so that a reader never sees
/// half an FMU.
fn write_fmu(out: &Path, entries: &[Entry]) -> Result<(), Box<dyn std::error::Error>> {
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let partial = out.with_extension("fmu.part");
    let mut zip = ZipWriter::new(std::fs::File::create(&partial)?);
    let options = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .last_modified_time(DateTime::default());
    for entry in entries {
        let options = if entry.executable { options.unix_permissions(0o755) } else { options };
        zip.start_file(entry.name.as_str(), options)?;
        zip.write_all(&entry.bytes)?;
    }
    zip.finish()?;
    std::fs::rename(&partial, out)?;
    Ok(())
}

/// The x86_64 and the arm64 slice of a universal (fat) Mach-O file: its
/// big-endian header `FAT_MAGIC` (0xcafebabe), the number of architectures
/// and per architecture a `fat_arch` (cputype, cpusubtype, offset, size,
/// align); each slice must be a 64-bit Mach-O (`MH_MAGIC_64`) of the
/// cputype its entry names. Anything else (a thin dylib, the 64-bit fat
/// header, other or missing architectures) is an error saying what was found.
fn darwin_slices(fat: &[u8]) -> Result<(Vec<u8>, Vec<u8>), String> {
    const FAT_MAGIC: u32 = 0xcafe_babe;
    const FAT_MAGIC_64: u32 = 0xcafe_babf;
    const MH_MAGIC_64: u32 = 0xfeed_facf;
    const CPU_TYPE_X86_64: u32 = 0x0100_0007;
    const CPU_TYPE_ARM64: u32 = 0x0100_000c;
    let word = |at: usize, big: bool| -> Option<u32> {
        let bytes: [u8; 4] = fat.get(at..at.checked_add(4)?)?.try_into().ok()?;
        Some(if big { u32::from_be_bytes(bytes) } else { u32::from_le_bytes(bytes) })
    };
    match word(0, true) {
        Some(FAT_MAGIC) => {}
        Some(FAT_MAGIC_64) => {
            return Err("a universal Mach-O with the 64-bit fat header (FAT_MAGIC_64), which is not supported".into())
        }
        _ if word(0, false) == Some(MH_MAGIC_64) => {
            return Err("a thin (single-architecture) Mach-O, not a universal x86_64 + arm64 dylib".into())
        }
        Some(magic) => return Err(format!("not a universal Mach-O file (magic 0x{magic:08x}, not 0xcafebabe)")),
        None => return Err(format!("not a universal Mach-O file ({} bytes)", fat.len())),
    }
    let count = word(4, true).unwrap_or(0);
    if count == 0 || count > 32 {
        return Err(format!("a fat header of {count} architectures"));
    }
    let (mut x86_64, mut arm64) = (None, None);
    for i in 0..count as usize {
        let entry = 8 + 20 * i;
        let field = |k: usize| word(entry + 4 * k, true).ok_or(format!("fat_arch {i} is cut off"));
        let (cputype, offset, size) = (field(0)?, field(2)? as usize, field(3)? as usize);
        let slice = offset.checked_add(size).and_then(|end| fat.get(offset..end)).ok_or(format!(
            "the slice of fat_arch {i} (offset {offset}, size {size}) lies outside the {} bytes",
            fat.len()
        ))?;
        let slot = match cputype {
            CPU_TYPE_X86_64 => &mut x86_64,
            CPU_TYPE_ARM64 => &mut arm64,
            other => {
                return Err(format!(
                "an architecture of cputype 0x{other:08x} (only x86_64 0x01000007 and arm64 0x0100000c are expected)"
            ))
            }
        };
        let header = (slice.get(0..4), slice.get(4..8));
        let thin = |b: Option<&[u8]>| b.and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
        if thin(header.0) != Some(MH_MAGIC_64) || thin(header.1) != Some(cputype) {
            return Err(format!("the slice of cputype 0x{cputype:08x} is not a 64-bit Mach-O of that cputype"));
        }
        if slot.replace(slice.to_vec()).is_some() {
            return Err(format!("two slices of cputype 0x{cputype:08x}"));
        }
    }
    match (x86_64, arm64) {
        (Some(x), Some(a)) => Ok((x, a)),
        (x, _) => Err(format!("no {} slice", if x.is_none() { "x86_64" } else { "arm64" })),
    }
}

fn read_library(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path)
        .map_err(|e| format!("cannot read the library {}: {e} (run `scripts/build_fmu.sh`)", path.display()))
}

#[cfg(test)]
mod tests {
    use super::darwin_slices;

    /// A 64-bit Mach-O "slice" of `cputype`: its header's magic and cputype, then `body`.
    fn thin(cputype: u32, body: &[u8]) -> Vec<u8> {
        [0xfeed_facf_u32.to_le_bytes(), cputype.to_le_bytes()]
            .concat()
            .into_iter()
            .chain(body.iter().copied())
            .collect()
    }

    /// A universal file of `slices` (cputype, bytes), each at a 4 KiB boundary.
    fn fat(slices: &[(u32, Vec<u8>)]) -> Vec<u8> {
        let mut file = [0xcafe_babe_u32.to_be_bytes(), (slices.len() as u32).to_be_bytes()].concat();
        let mut offset = 4096;
        let mut data = Vec::new();
        for (cputype, bytes) in slices {
            for field in [*cputype, 3, offset as u32, bytes.len() as u32, 12] {
                file.extend(field.to_be_bytes());
            }
            data.push((offset, bytes));
            offset += bytes.len().div_ceil(4096) * 4096;
        }
        for (at, bytes) in data {
            file.resize(at, 0);
            file.extend(bytes);
        }
        file
    }

    #[test]
    fn a_universal_dylib_is_split_into_its_slices() {
        let (x, a) = (thin(0x0100_0007, b"x86_64 code"), thin(0x0100_000c, &[7; 5000]));
        for order in
            [[(0x0100_0007, x.clone()), (0x0100_000c, a.clone())], [(0x0100_000c, a.clone()), (0x0100_0007, x.clone())]]
        {
            assert_eq!(darwin_slices(&fat(&order)), Ok((x.clone(), a.clone())));
        }
    }

    #[test]
    fn anything_else_is_refused_with_what_it_is() {
        let (x, a) = (thin(0x0100_0007, b"x"), thin(0x0100_000c, b"a"));
        let cases: [(Vec<u8>, &str); 7] = [
            (x.clone(), "thin (single-architecture) Mach-O"),
            (b"\x7fELF....".to_vec(), "not a universal Mach-O file (magic 0x7f454c46"),
            (vec![0xca, 0xfe], "not a universal Mach-O file (2 bytes)"),
            (fat(&[(0x0100_0007, x.clone())]), "no arm64 slice"),
            (fat(&[(0x0100_0007, x.clone()), (0x0000_0007, thin(7, b"i386"))]), "cputype 0x00000007"),
            (fat(&[(0x0100_0007, x.clone()), (0x0100_000c, x.clone())]), "not a 64-bit Mach-O of that cputype"),
            ([&fat(&[(0x0100_0007, x), (0x0100_000c, a)])[..4200]].concat(), "lies outside"),
        ];
        for (file, expected) in cases {
            let e = darwin_slices(&file).unwrap_err();
            assert!(e.contains(expected), "{e:?} should say {expected:?}");
        }
        let mut fat64 = fat(&[]);
        fat64[3] = 0xbf;
        assert!(darwin_slices(&fat64).unwrap_err().contains("FAT_MAGIC_64"));
    }
}
