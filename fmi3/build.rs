//! Keeps the engine crate's exports (the `fmi2…` functions of the FMI 2.0
//! library, fmi-sys's `callback_log`) out of this library's export table:
//! they come from rlibs, archives to the linker. GNU ld (Linux, mingw) only;
//! scripts/darwin-link.sh drops the option and cuts the export list itself.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-cdylib-link-arg=-Wl,--exclude-libs,ALL");
}
