# shellcheck shell=bash
# scripts/win64.sh -- the win64 cross toolchain. SOURCED (after scripts/env.sh,
# which installs the Debian packages) by scripts/build_fmu.sh and scripts/test.sh.
#
# The rustup toolchain here has no x86_64-pc-windows-gnu standard library and
# no network to fetch one, so the win64 side is built with Debian's compiler
# (`rustc-web`, `cargo-web`: /usr/bin/rustc, /usr/bin/cargo), which compiles
# std itself from `rust-web-src` (-Zbuild-std; RUSTC_BOOTSTRAP=1 because
# build-std is unstable), and links with mingw-w64 (`gcc-mingw-w64-x86-64`).
# Everything goes to its own target dir, $WIN64_TARGET_DIR, so the two
# toolchains never share fingerprints. That dir is a cache outside the clone
# ($STICKSLIP_CACHE_DIR/cross, see scripts/env.sh), shared by every clone of
# this machine: std (-Zbuild-std), the dependencies and the build scripts
# are compiled once, not in every fresh clone. It can never hand a clone
# another clone's build of the project's own code: cargo decides freshness
# of path packages by the content of their files (-Zchecksum-freshness, not
# their mtimes, which a fresh clone sets to "now" and an older clone to the
# past), of registry packages by their version and checksum in Cargo.lock,
# of std by the compiler's version; builds from two clones at once are
# serialized on $WIN64_LOCK, build and copy of the result together.
#
#   win64_cargo SUBCOMMAND ARGS...  /usr/bin/cargo for the Windows target (niced), in a
#                                   subshell: nothing leaks into the Linux builds
#   win64_wine_prefix               makes the test-only wine prefix (see below)

# shellcheck source=scripts/cross-wrapper.sh
source "$STICKSLIP_ROOT/scripts/cross-wrapper.sh"

WIN64_TARGET=x86_64-pc-windows-gnu
WIN64_TARGET_DIR="${STICKSLIP_CACHE_DIR:?scripts/env.sh sets STICKSLIP_CACHE_DIR}/cross"
WIN64_LOCK="$WIN64_TARGET_DIR.lock"
WIN64_RELEASE="$WIN64_TARGET_DIR/$WIN64_TARGET/release"
WIN64_FMI2="$WIN64_TARGET_DIR/$WIN64_TARGET/fmi2"   # the FMI 2.0 library (profile fmi2, scripts/build_fmu.sh)
# The DLLs the FMU's DLL may import (lower case, an extended regex matched
# whole): Windows' own, present on every Windows 10/11 (the api-ms-win-* API
# sets since Windows 7/8). Anything else (libgcc_s_seh-1, libwinpthread-1)
# would have to be shipped; mingw links those statically.
WIN64_SYSTEM_DLLS='(kernel32|ntdll|msvcrt|advapi32|userenv|ws2_32|bcrypt|bcryptprimitives|api-ms-win-[a-z0-9-]+)\.dll'

_win64_env() {
    local include
    export RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1
    # The cross builds keep their own cache (the shared target dir), not sccache.
    unset RUSTC_WRAPPER
    # bindgen (fmi-sys) parses the FMI headers for the mingw target with
    # libclang, which then needs clang's own builtin headers (mm_malloc.h):
    # those of the libclang env.sh found.
    include=$(ls -d "${LIBCLANG_PATH:-/usr/lib/llvm-14/lib}"/clang/*/include 2>/dev/null | sort -V | tail -n1)
    export BINDGEN_EXTRA_CLANG_ARGS_x86_64_pc_windows_gnu="-I$include"
    # The linker wrapper's copy named by its content (scripts/cross-wrapper.sh):
    # its path is in every unit's fingerprint.
    CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER=$(cross_wrapper mingw-link.sh) || return 1
    export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER
    export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUNNER=wine
    # The wine prefix: per wine version (a new wine makes a new prefix).
    export WINEPREFIX="$STICKSLIP_CACHE_DIR/wineprefix-$(wine --version 2>/dev/null | tr -c 'A-Za-z0-9.\n-' _)"
    export WINEDEBUG=-all WINEDLLOVERRIDES="mscoree,mshtml="
}

win64_cargo() (
    _win64_env || exit 1
    nice /usr/bin/cargo "$1" -Zbuild-std=std,panic_unwind -Zchecksum-freshness --target "$WIN64_TARGET" \
        --target-dir "$WIN64_TARGET_DIR" "${@:2}"
)

# A wine prefix for the tests only, under the target dir. Rust's std imports
# ProcessPrng from bcryptprimitives.dll, which every Windows 10/11 has in
# system32 but wine 8 does not implement; the prefix gets a stand-in
# (tests/win64/bcryptprimitives.c) in its system32, so that any Windows program
# of this build runs with a plain `wine` runner. The FMU never contains it.
win64_wine_prefix() (
    _win64_env || exit 1
    local src="$STICKSLIP_ROOT/tests/win64/bcryptprimitives.c" standin
    # Named by the content of its source: a changed stand-in is compiled anew.
    standin="$WIN64_TARGET_DIR/bcryptprimitives-$(sha256sum "$src" | cut -c1-16).dll"
    command -v wine >/dev/null || { echo "win64.sh: wine not found (scripts/env.sh installs it)" >&2; exit 1; }
    mkdir -p "$WIN64_TARGET_DIR"
    # .stickslip-ready marks a prefix wineboot finished: one interrupted half-way is made again.
    if [ ! -f "$WINEPREFIX/.stickslip-ready" ]; then
        echo "win64.sh: creating the wine prefix $WINEPREFIX" >&2
        rm -rf "$WINEPREFIX"
        wineboot -i </dev/null >&2 && wineserver -w && touch "$WINEPREFIX/.stickslip-ready"
    fi
    if [ ! -f "$standin" ]; then
        x86_64-w64-mingw32-gcc -O2 -shared -s -o "$standin.tmp$$" "$src" -ladvapi32 && mv "$standin.tmp$$" "$standin"
    fi
    cp "$standin" "$WINEPREFIX/drive_c/windows/system32/bcryptprimitives.dll"
)
