# shellcheck shell=bash
# scripts/darwin64.sh -- the darwin64 cross toolchain. SOURCED (after
# scripts/env.sh with STICKSLIP_DARWIN64=1, which installs what it needs) by
# scripts/build_fmu.sh when darwin64 is among its platforms (the default).
#
# The FMU's darwin64 binary is one universal (fat) Mach-O dylib with an x86_64
# and an arm64 slice. Each slice is built like the win64 DLL: Debian's Rust
# (`rustc-web`, `cargo-web`) compiles std from `rust-web-src` (-Zbuild-std,
# RUSTC_BOOTSTRAP=1), here for x86_64-apple-darwin and aarch64-apple-darwin.
# No Apple SDK is needed:
#   * C compiler (fmi-sys's logger.c): `zig cc` from the PyPI package `ziglang`
#     (pinned in scripts/darwin64-requirements.txt, in a venv of its own,
#     $DARWIN64_ZIG_VENV), which carries
#     the macOS headers (scripts/darwin-cc.sh);
#   * linker: LLVM's ld64.lld (the rustup toolchain's rust-lld, else Debian's
#     ld64.lld) against the libSystem stubs (libSystem.tbd) of the same zig
#     package (scripts/darwin-link.sh, which also says why not zig's linker);
#   * universal file: `llvm-lipo` of Debian's LLVM (package llvm-14).
# Minimum macOS: 10.13 for x86_64, 11.0 for arm64 (the first macOS on Apple
# silicon), see _darwin64_env.
# The cargo build goes to $DARWIN64_CARGO_DIR (the win64 build's cache outside
# the clone, $STICKSLIP_CACHE_DIR/cross, see darwin64_cargo and scripts/win64.sh
# for how it is invalidated), the zig venv and SDK stubs to
# $STICKSLIP_CACHE_DIR/darwin64, the universal dylib to $DARWIN64_TARGET_DIR
# (<target>/darwin64, the clone's own).
#
#   darwin64_cargo SUBCOMMAND ARGS...  /usr/bin/cargo for both Apple targets
#                                      at once (niced), in a subshell
#   darwin64_build                     both slices, merged into $DARWIN64_DYLIB
#                                      (and the FMI 3.0 library's into $DARWIN64_DYLIB3)

# shellcheck source=scripts/cross-wrapper.sh
source "$STICKSLIP_ROOT/scripts/cross-wrapper.sh"

DARWIN64_TARGET_DIR="${CARGO_TARGET_DIR:-$STICKSLIP_ROOT/target}/darwin64"
DARWIN64_CACHE_DIR="${STICKSLIP_CACHE_DIR:?scripts/env.sh sets STICKSLIP_CACHE_DIR}/darwin64"
DARWIN64_CARGO_DIR="$STICKSLIP_CACHE_DIR/cross"   # shared with win64, see darwin64_cargo
DARWIN64_LOCK="$DARWIN64_CARGO_DIR.lock"          # = WIN64_LOCK
DARWIN64_ZIG_VENV="${STICKSLIP_ZIG_VENV:-$DARWIN64_CACHE_DIR/zig-venv}"
DARWIN64_DYLIB="$DARWIN64_TARGET_DIR/StickSlipManipulator.dylib"
# The FMI 3.0 library (crate fmi3/), universal too (package_fmu --fmi3 splits it).
DARWIN64_DYLIB3="$DARWIN64_TARGET_DIR/StickSlipManipulator-fmi3.dylib"
DARWIN64_INSTALL_NAME=@rpath/StickSlipManipulator.dylib
# The only library the dylib may load: every macOS has it (in the dyld shared cache).
DARWIN64_SYSTEM_LIBS=/usr/lib/libSystem.B.dylib
DARWIN64_TRIPLES=(x86_64-apple-darwin aarch64-apple-darwin)
declare -A DARWIN64_MIN_MACOS=([x86_64-apple-darwin]=10.13 [aarch64-apple-darwin]=11.0)

# An LLVM tool of Debian's LLVM: NAME, else NAME-14.
_darwin64_llvm() {
    local t
    for t in "$1" "$1-14" "/usr/lib/llvm-14/bin/$1"; do
        if command -v "$t" >/dev/null 2>&1; then command -v "$t"; return 0; fi
    done
    echo "darwin64.sh: $1 not found (Debian package llvm-14; scripts/env.sh installs it)" >&2
    return 1
}

# The Mach-O linker: the rustup toolchain's rust-lld, else Debian's ld64.lld.
_darwin64_lld() {
    local sysroot host lld t
    if command -v rustc >/dev/null 2>&1 && [ "$(command -v rustc)" != /usr/bin/rustc ]; then
        sysroot=$(rustc --print sysroot) && host=$(rustc -vV | sed -n 's/^host: //p')
        lld="$sysroot/lib/rustlib/$host/bin/rust-lld"
        if [ -x "$lld" ]; then echo "$lld -flavor darwin"; return 0; fi
    fi
    for t in ld64.lld ld64.lld-19 ld64.lld-16 ld64.lld-15; do
        if command -v "$t" >/dev/null 2>&1; then command -v "$t"; return 0; fi
    done
    echo "darwin64.sh: no ld64.lld (rustup's rust-lld or Debian's lld-19)" >&2
    return 1
}

# The libSystem stubs for the linker: zig's libSystem.tbd, whose targets
# name arm64 code as `arm64e` and `arm64e.x1` (zig's own linker accepts arm64
# for those), rewritten for ld64.lld to `arm64` (the same symbols: arm64
# processes on Apple silicon bind to the very same libSystem). Into
# $DARWIN64_CACHE_DIR/sdk-<hash of zig's stubs>, with zig's SDKSettings.json
# (the SDK version). Prints that directory.
_darwin64_sdk() {
    local from="$1" to
    to="$DARWIN64_CACHE_DIR/sdk-$(cat "$from/libSystem.tbd" "$from/SDKSettings.json" | sha256sum | cut -c1-16)"
    printf '%s\n' "$to"
    [ -f "$to/libSystem.tbd" ] && return 0
    mkdir -p "$to" && cp "$from/SDKSettings.json" "$to/" || return 1
    "$DARWIN64_ZIG_VENV/bin/python" - "$from/libSystem.tbd" "$to/libSystem.tbd" <<'PY' || return 1
import re, sys
text = open(sys.argv[1]).read()
text = re.sub(r",\s*arm64e\.x1-[a-z]+", "", text)
text = re.sub(r"arm64e\.x1-[a-z]+,\s*", "", text)
assert "arm64e.x1" not in text, "an arm64e.x1 target left"
text = text.replace("arm64e-", "arm64-")
open(sys.argv[2] + ".tmp", "w").write(text)
PY
    mv "$to/libSystem.tbd.tmp" "$to/libSystem.tbd"
}

_darwin64_env() {
    local triple var include zigdir cc link
    zigdir=$("$DARWIN64_ZIG_VENV/bin/python" -c 'import os, ziglang; print(os.path.dirname(ziglang.__file__))' 2>/dev/null) || {
        echo "darwin64.sh: no ziglang in $DARWIN64_ZIG_VENV (scripts/env.sh installs it with STICKSLIP_DARWIN64=1)" >&2
        return 1
    }
    export RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1
    # The cross builds keep their own cache (the shared target dir), not sccache.
    unset RUSTC_WRAPPER
    # Both targets build in one cargo run, so one MACOSX_DEPLOYMENT_TARGET:
    # x86_64's 10.13. rustc raises it to its arm64 minimum, 11.0, for
    # aarch64-apple-darwin (max of the variable and the architecture's
    # minimum); the C compiler and linker wrappers take each architecture's
    # own from DARWIN64_MIN_MACOS_X86_64 / _ARM64.
    export MACOSX_DEPLOYMENT_TARGET="${DARWIN64_MIN_MACOS[x86_64-apple-darwin]}"
    export DARWIN64_MIN_MACOS_X86_64="${DARWIN64_MIN_MACOS[x86_64-apple-darwin]}"
    export DARWIN64_MIN_MACOS_ARM64="${DARWIN64_MIN_MACOS[aarch64-apple-darwin]}"
    DARWIN64_SDK=$(_darwin64_sdk "$zigdir/lib/libc/darwin") || return 1
    export DARWIN64_ZIG="$zigdir/zig" DARWIN64_SDK DARWIN64_INSTALL_NAME
    # rustc asks xcrun for the SDK unless SDKROOT names one (it only warns).
    export SDKROOT="$DARWIN64_SDK"
    DARWIN64_LLD=$(_darwin64_lld) || return 1
    export DARWIN64_LLD
    # bindgen (fmi-sys) parses the FMI headers for the Apple target with
    # libclang: clang's builtin headers (stddef.h) and zig's macOS headers.
    include=$(ls -d "${LIBCLANG_PATH:-/usr/lib/llvm-14/lib}"/clang/*/include 2>/dev/null | sort -V | tail -n1)
    # The wrappers' copies named by their content (scripts/cross-wrapper.sh):
    # the linker's path is in every unit's fingerprint, std's included.
    cc=$(cross_wrapper darwin-cc.sh) && link=$(cross_wrapper darwin-link.sh) || return 1
    for triple in "${DARWIN64_TRIPLES[@]}"; do
        var=$(echo "$triple" | tr 'a-z-' 'A-Z_')
        export "CC_${triple//-/_}=$cc"
        export "CARGO_TARGET_${var}_LINKER=$link"
        export "BINDGEN_EXTRA_CLANG_ARGS_${triple//-/_}=-I$include -isystem $zigdir/lib/libc/include/any-darwin-any"
    done
}

# Both Apple targets in one cargo run (--target twice): the two std builds
# and dependency trees fill each other's idle cores. Its cargo target dir is
# win64's ($DARWIN64_CARGO_DIR = <target>/win64): the same compiler
# (/usr/bin/rustc) and release profile, so the host build scripts and proc
# macros (bindgen, clang-sys, syn, serde_derive, build.rs's nalgebra) that
# the win64 build compiled are reused, not compiled again; each target's
# artifacts have their own directory below it. std is built without its
# `backtrace` feature (-Zbuild-std-features=panic-unwind): no gimli,
# addr2line, object, miniz_oxide to compile twice; the dylib is linked
# stripped, so there would be no symbols to show, and panics are caught at
# the C boundary either way.
darwin64_cargo() (
    _darwin64_env || exit 1
    local targets=() t
    for t in "${DARWIN64_TRIPLES[@]}"; do targets+=(--target "$t"); done
    nice /usr/bin/cargo "$1" -Zbuild-std=std,panic_unwind -Zbuild-std-features=panic-unwind -Zchecksum-freshness \
        "${targets[@]}" --target-dir "$DARWIN64_CARGO_DIR" "${@:2}"
)

# Both slices (release), merged into the universal $DARWIN64_DYLIB. The
# linker output is already stripped and (arm64) signed; lipo copies the
# slices unchanged, so the signature stays valid.
darwin64_build() {
    local triple lipo slices=() slices3=()
    lipo=$(_darwin64_llvm llvm-lipo) || return 1
    for triple in "${DARWIN64_TRIPLES[@]}"; do
        slices+=("$DARWIN64_CARGO_DIR/$triple/fmi2/libstick_slip_manipulator.dylib")
        slices3+=("$DARWIN64_CARGO_DIR/$triple/release/libstick_slip_manipulator_fmi3.dylib")
    done
    mkdir -p "$DARWIN64_TARGET_DIR" "$DARWIN64_CACHE_DIR"
    rm -f "$DARWIN64_DYLIB" "$DARWIN64_DYLIB3"
    # Build and merge under the shared cache's lock: another clone's build
    # cannot replace the slices in between. Both FMI versions' libraries, the
    # FMI 2.0 one without the FMI 3.0 layer (profile fmi2, scripts/build_fmu.sh).
    (
        flock 9
        darwin64_cargo build --release -p stick_slip_manipulator_fmi3 --lib &&
            darwin64_cargo build --profile fmi2 -p stick_slip_manipulator --lib --no-default-features &&
            "$lipo" -create "${slices[@]}" -output "$DARWIN64_DYLIB" &&
            "$lipo" -create "${slices3[@]}" -output "$DARWIN64_DYLIB3"
    ) 9>"$DARWIN64_LOCK"
}
