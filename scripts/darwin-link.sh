#!/usr/bin/env bash
# scripts/darwin-link.sh -- the linker of the darwin64 builds
# (CARGO_TARGET_{X86_64,AARCH64}_APPLE_DARWIN_LINKER, set by scripts/darwin64.sh).
#
# rustc calls a C compiler driver for Apple targets; here LLVM's Mach-O linker
# (ld64.lld: the rustup toolchain's rust-lld, or Debian's ld64.lld) is called
# directly instead, with the driver's arguments turned into ld64's and with
# macOS's system library stubs (libSystem.tbd) from the `ziglang` package.
# Why not `zig cc` as linker too: zig's Mach-O linker ignores
# `-exported_symbols_list` (every Rust symbol, some 2,200, stays exported),
# which ld64.lld honours. What the link does beyond rustc's arguments:
#   * the export list rustc writes is cut to the `_fmi2` functions and the four
#     beyond FMI, `_stickslip_inverse_dynamics`,
#     `_stickslip_joint_torque_regressor`, `_stickslip_run_experiment` and
#     `_stickslip_write_model` (the FMI 3.0 library, an
#     output named *fmi3*: the `_fmi3` ones only): rustc lists every
#     `#[no_mangle]` function of every crate, so fmi-sys's `callback_log`
#     would be exported too (mingw-link.sh does the same for win64);
#   * `-install_name @rpath/StickSlipManipulator.dylib`, not the build path;
#   * `-platform_version macos MIN <sdk>`: the minimum macOS of the
#     architecture, DARWIN64_MIN_MACOS_X86_64 / _ARM64 (10.13 for x86_64,
#     11.0 for arm64, set by scripts/darwin64.sh), the SDK version
#     from zig's SDKSettings.json;
#   * `-S -x`: no debug map, no local symbols (stripped at link time: stripping
#     afterwards would break the arm64 signature);
#   * arm64 output is ad-hoc code-signed by the linker (`-adhoc_codesign`),
#     as Apple's ld64 does; Apple silicon loads no unsigned arm64 code;
#   * `-Wl,--exclude-libs,ALL` (build.rs, for GNU ld) is dropped: ld64 has no
#     such option, the export list does that job here.
set -euo pipefail
: "${DARWIN64_SDK:?scripts/darwin64.sh sets DARWIN64_SDK}" "${DARWIN64_LLD:?}" "${DARWIN64_INSTALL_NAME:?}"
arch="" min="${MACOSX_DEPLOYMENT_TARGET:-}" skip="" flat=() args=() exports=0
# First the driver's options; `-Wl,a,b` becomes the linker arguments a b (rustc
# passes `-Wl,-exported_symbols_list` and `-Wl,FILE` as two).
for a in "$@"; do
    if [ -n "$skip" ]; then
        case "$skip" in
            arch) arch="$a" ;;
            keep) flat+=("$a") ;;
        esac
        skip=""; continue
    fi
    case "$a" in
        -arch) skip=arch ;;
        -isysroot) skip=drop ;;                  # SDKROOT: the stubs come with -L below
        -o | -L) flat+=("$a"); skip=keep ;;
        --target=* | -target=*) arch="${a#*=}"; arch="${arch%%-*}" ;;
        -mmacosx-version-min=*) min="${a#-mmacosx-version-min=}" ;;
        -dynamiclib | -shared) flat+=(-dylib) ;;
        -lc | -lm) ;;                            # parts of libSystem on macOS
        -l*) flat+=("$a") ;;
        -nodefaultlibs | -nostartfiles | -m64 | -fPIC | -fuse-ld=* | -O* | -g*) ;;
        -Wl,*) IFS=, read -r -a parts <<<"${a#-Wl,}"; flat+=("${parts[@]}") ;;
        -*) echo "darwin-link.sh: unexpected driver option '$a'" >&2; exit 2 ;;
        *) flat+=("$a") ;;
    esac
done
# The FMI version whose functions the library exports: the FMI 3.0 library
# (crate fmi3/, libstick_slip_manipulator_fmi3.dylib) links the FMI 2.0
# crate as an rlib, whose fmi2 functions rustc would list too.
version=fmi2 keep="_fmi2|_stickslip_inverse_dynamics|_stickslip_joint_torque_regressor|_stickslip_run_experiment|_stickslip_write_model"
for ((i = 0; i + 1 < ${#flat[@]}; i++)); do
    if [ "${flat[$i]}" = -o ]; then
        case "$(basename "${flat[$((i + 1))]}")" in *fmi3*) version=fmi3 keep=_fmi3 ;; esac
    fi
done
i=0
while [ "$i" -lt "${#flat[@]}" ]; do
    p="${flat[$i]}"
    case "$p" in
        --exclude-libs) i=$((i + 1)) ;;          # and its value (ALL)
        --exclude-libs=*) ;;
        -exported_symbols_list)
            i=$((i + 1)); list="${flat[$i]}"
            cut="$list.$version"
            grep -E "^[[:space:]]*($keep)" "$list" >"$cut" || true
            args+=(-exported_symbols_list "$cut"); exports=1 ;;
        *) args+=("$p") ;;
    esac
    i=$((i + 1))
done
# Each architecture's own minimum macOS (DARWIN64_MIN_MACOS_ARM64, _X86_64 of
# scripts/darwin64.sh): both targets build in one cargo run, under one
# MACOSX_DEPLOYMENT_TARGET (x86_64's).
case "$arch" in
    arm64 | aarch64) arch=arm64; sign=(-adhoc_codesign); min="${DARWIN64_MIN_MACOS_ARM64:-$min}" ;;
    x86_64) sign=(); min="${DARWIN64_MIN_MACOS_X86_64:-$min}" ;;
    *) echo "darwin-link.sh: unknown or missing architecture '$arch' (args: $*)" >&2; exit 2 ;;
esac
# A dylib without the export list would export every Rust symbol.
if printf '%s\n' "${args[@]}" | grep -qx -- -dylib && [ "$exports" = 0 ]; then
    echo "darwin-link.sh: a dylib without -exported_symbols_list" >&2; exit 2
fi
[ -n "$min" ] || { echo "darwin-link.sh: no minimum macOS (MACOSX_DEPLOYMENT_TARGET)" >&2; exit 2; }
sdk_version=$(sed -n 's/.*"Version"[[:space:]]*:[[:space:]]*"\([0-9.]*\)".*/\1/p' "$DARWIN64_SDK/SDKSettings.json" | head -n1)
exec $DARWIN64_LLD -arch "$arch" -platform_version macos "$min" "${sdk_version:-$min}" \
    -L "$DARWIN64_SDK" -install_name "$DARWIN64_INSTALL_NAME" -headerpad_max_install_names \
    -dead_strip -S -x ${sign[@]+"${sign[@]}"} "${args[@]}"
