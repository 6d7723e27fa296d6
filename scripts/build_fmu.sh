#!/usr/bin/env bash
# scripts/build_fmu.sh -- builds the FMI 2.0 co-simulation FMU and, beside it,
# the FMI 3.0 one (<name>-fmi3.fmu, docs/fmi3.md) of the same model.
#
#   bash scripts/build_fmu.sh [--platforms linux64,win64,darwin64] [package_fmu args...]
#
#   --platforms LIST  the FMU binaries to build, comma-separated, of linux64,
#                     win64, darwin64, or `all` (the three); default
#                     $STICKSLIP_PLATFORMS, else `linux64`: the machine it runs
#                     on. The cross-builds cost their toolchains on a fresh
#                     machine (win64: Debian's rustc-web, mingw-w64 and wine,
#                     about 350 MB through apt; darwin64: LLVM and the PyPI
#                     package ziglang) and about 3 minutes each of compiling
#                     (docs/platforms.md). scripts/test.sh builds all three;
#                     STICKSLIP_DARWIN64=0 takes darwin64 out of any list (a
#                     developer's opt-out; CI builds it).
#
#   1. linux64: cargo build --release -p stick_slip_manipulator
#      -p stick_slip_manipulator_fmi3 --lib --bin package_fmu (the FMI 3.0
#      cdylib of the crate fmi3/ and the packager; build.rs also writes
#      modelDescription/modelDescription.xml), then the FMI 2.0 cdylib without
#      the FMI 3.0 layer: cargo build --profile fmi2 -p stick_slip_manipulator
#      --lib --no-default-features (the profile `fmi2` of Cargo.toml: release
#      in target/fmi2/, so that the engine crate's two builds, with and
#      without its feature `fmi3`, keep their files apart; docs/platforms.md).
#      Each step below does the same for both libraries.
#   2. win64: the same library cross-built for x86_64-pc-windows-gnu with
#      Debian's rustc and mingw-w64 (scripts/win64.sh), target dir
#      $STICKSLIP_CACHE_DIR/cross (outside the clone, shared by every clone)
#   2b. darwin64 (unless left out): the same library cross-built for
#      x86_64-apple-darwin and aarch64-apple-darwin (scripts/darwin64.sh),
#      the same target dir, merged by llvm-lipo into one universal dylib
#   3. copies stripped of debug info and symbol table (strip --strip-all, into
#      target/fmu/stripped/): the FMU ships those; target/release and
#      target/fmu/stripped/unstripped.dll keep the debug info for local profiling (the
#      darwin64 dylib is linked stripped: stripping afterwards would break
#      the arm64 slice's code signature)
#   4. checks every shipped binary's interface: exactly the 34 FMI 2.0
#      functions, stickslip_inverse_dynamics, stickslip_joint_torque_regressor
#      and stickslip_write_model (the engine's inverse dynamics and its
#      joint-torque regressor for the fit, the identified model written as a
#      model file, src/fmi/exports.rs) exported (the 75 FMI 3.0 functions
#      only for the FMI 3.0 library); the DLL imports Windows system DLLs only; each
#      darwin64 slice imports libSystem only, has the install name
#      @rpath/StickSlipManipulator.dylib, the minimum macOS 10.13 (x86_64) or
#      11.0 (arm64), no local or debug symbols, and arm64 a code signature
#   5. package_fmu: target/fmu/StickSlipManipulator.fmu (or --out FILE) from the
#      reference model (or --model FILE), and package_fmu --fmi3:
#      target/fmu/StickSlipManipulator-fmi3.fmu (or FILE without .fmu + -fmi3.fmu)
#   6. fmpy.validation of both FMUs, when the venv has fmpy
#
# Called by scripts/test.sh and scripts/main.sh.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

platforms="${STICKSLIP_PLATFORMS:-linux64}"
pass=()
while [ $# -gt 0 ]; do
    case "$1" in
        --platforms) [ $# -ge 2 ] || { echo "build_fmu.sh: --platforms needs a value" >&2; exit 2; }
                     platforms="$2"; shift 2 ;;
        --platforms=*) platforms="${1#--platforms=}"; shift ;;
        *) pass+=("$1"); shift ;;
    esac
done
[ "$platforms" = all ] && platforms="linux64,win64,darwin64"
if [ "${STICKSLIP_DARWIN64:-1}" = 0 ]; then platforms=$(printf '%s' "$platforms" | sed 's/,darwin64//; s/darwin64,//'); fi
linux64=0 win64=0 darwin64=0
IFS=, read -r -a wanted <<<"$platforms"
for p in "${wanted[@]}"; do
    case "$p" in
        linux64) linux64=1 ;;
        win64) win64=1 ;;
        darwin64) darwin64=1 ;;
        *) echo "build_fmu.sh: unknown platform '$p' (linux64, win64, darwin64)" >&2; exit 2 ;;
    esac
done
if [ "$linux64" -eq 0 ]; then
    # package_fmu and build.rs's modelDescription come from the Linux build.
    echo "build_fmu.sh: --platforms must include linux64" >&2
    exit 2
fi
# env.sh installs each cross toolchain only when its platform is built.
if [ "$darwin64" -eq 1 ]; then export STICKSLIP_DARWIN64=1; else export STICKSLIP_DARWIN64=0; fi
[ "$win64" -eq 1 ] && export STICKSLIP_WIN64=1
env_start=$SECONDS
# shellcheck source=scripts/env.sh
source scripts/env.sh
# (with darwin64 in a clean clone: the ziglang download and venv)
[ $((SECONDS - env_start)) -lt 2 ] || echo "build_fmu.sh: scripts/env.sh $((SECONDS - env_start)) s"

TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
# One build at a time per target dir: the stripped libraries and the darwin64
# dylibs have fixed paths there (parallel tests build their own model's FMUs).
mkdir -p "$TARGET_DIR"
# The compiler cache's server starts now if it is not running: one that a cargo below
# started would inherit the lock's descriptor 7 (and win64's 9) and hold the lock until it
# exits at its idle timeout, 10 minutes, blocking every other build_fmu.sh meanwhile (seen
# with parallel builds). "Address in use" means it runs already.
if [ "${RUSTC_WRAPPER:-}" = sccache ]; then sccache --start-server </dev/null >/dev/null 2>&1 || true; fi
exec 7>"$TARGET_DIR/.build_fmu.lock"
flock 7
LIB="$TARGET_DIR/fmi2/libstick_slip_manipulator.so"
LIB3="$TARGET_DIR/release/libstick_slip_manipulator_fmi3.so"
STRIPPED="$TARGET_DIR/fmu/stripped"
mkdir -p "$STRIPPED"

# The interface of a binary is the FMU's: the 34 fmi2 functions of FMI 2.0
# and the four functions beyond FMI, stickslip_inverse_dynamics,
# stickslip_joint_torque_regressor, stickslip_run_experiment and
# stickslip_write_model, or the 75 fmi3
# functions of FMI 3.0,
# nothing else.
# check_exports FILE [fmi3] < exported names
check_exports() {
    local symbols count extra version="${2:-fmi2}" want=34
    local beyond="stickslip_inverse_dynamics stickslip_joint_torque_regressor stickslip_run_experiment stickslip_write_model"
    [ "$version" = fmi3 ] && want=75 beyond=""
    symbols=$(sort)
    count=$(printf '%s\n' "$symbols" | grep -c "^$version" || true)
    extra=$(printf '%s\n' "$symbols" | grep -v "^$version" | grep . || true)
    if [ "$count" -ne "$want" ] || [ "$(echo $extra)" != "$beyond" ]; then
        echo "build_fmu.sh: $1 exports $count $version symbols and '$(echo $extra)' besides, expected the $want $version functions${beyond:+ and $beyond} only:" >&2
        printf '%s\n' "$symbols" >&2
        exit 1
    fi
}

size() { stat -c %s "$1"; }

# STICKSLIP_FMU_ALL_TARGETS=1 (scripts/test.sh, after `cargo test --all-targets`): built
# with every target, so that cargo resolves the dependencies' features as for the tests
# (the dev-dependencies add some) and reuses that build of the engine; a plain build of
# the libraries would compile it again with other features, and the engine's cdylib,
# one file for both, would make each build invalidate the other.
linux_targets=(--lib --bin package_fmu)
[ "${STICKSLIP_FMU_ALL_TARGETS:-0}" = 1 ] && linux_targets=(--all-targets)
cargo build --release -p stick_slip_manipulator -p stick_slip_manipulator_fmi3 "${linux_targets[@]}"
# The FMI 2.0 library holds no FMI 3.0 code (the feature `fmi3` off).
cargo build --profile fmi2 -p stick_slip_manipulator --lib --no-default-features
SO="$STRIPPED/libstick_slip_manipulator.so"
SO3="$STRIPPED/libstick_slip_manipulator_fmi3.so"
strip --strip-all -o "$SO" "$LIB"
strip --strip-all -o "$SO3" "$LIB3"
nm -D --defined-only "$SO" | awk '$2 ~ /^[TtWwDdBbRrVviu]$/ {print $3}' | check_exports "$SO"
nm -D --defined-only "$SO3" | awk '$2 ~ /^[TtWwDdBbRrVviu]$/ {print $3}' | check_exports "$SO3" fmi3
echo "build_fmu.sh: linux64 $(size "$LIB") bytes, $(size "$SO") stripped; FMI 3.0 $(size "$SO3") stripped"
package_args=(--lib "$SO")
package3_args=(--lib "$SO3")

if [ "$win64" -eq 1 ]; then
    # shellcheck source=scripts/win64.sh
    source scripts/win64.sh
    win64_start=$SECONDS
    DLL="$STRIPPED/StickSlipManipulator.dll"
    DLL3="$STRIPPED/StickSlipManipulator-fmi3.dll"
    # Build and strip under the shared cache's lock (scripts/win64.sh): another
    # clone's build cannot replace the DLLs in between.
    mkdir -p "$WIN64_TARGET_DIR"
    (
        flock 9
        win64_cargo build --release -p stick_slip_manipulator_fmi3 --lib &&
            win64_cargo build --profile fmi2 -p stick_slip_manipulator --lib --no-default-features &&
            cp "$WIN64_FMI2/stick_slip_manipulator.dll" "$STRIPPED/unstripped.dll" &&
            cp "$WIN64_RELEASE/stick_slip_manipulator_fmi3.dll" "$STRIPPED/unstripped-fmi3.dll"
    ) 9>"$WIN64_LOCK"
    x86_64-w64-mingw32-strip --strip-all -o "$DLL" "$STRIPPED/unstripped.dll"
    x86_64-w64-mingw32-strip --strip-all -o "$DLL3" "$STRIPPED/unstripped-fmi3.dll"
    for dll in "$DLL" "$DLL3"; do
        version=fmi2
        [ "$dll" = "$DLL3" ] && version=fmi3
        exports=$(x86_64-w64-mingw32-objdump -p "$dll" | sed -n '/\[Ordinal\/Name Pointer\] Table/,/^$/p' | awk 'NR > 1 && /^[[:space:]]*\[/ {print $NF}')
        printf '%s\n' "$exports" | check_exports "$dll" "$version"
        # Imports: Windows system DLLs only (no libgcc_s, libwinpthread, libstdc++).
        imports=$(x86_64-w64-mingw32-objdump -p "$dll" | awk '/DLL Name:/ {print tolower($3)}' | sort -u)
        foreign=$(printf '%s\n' "$imports" | grep -Evx "$WIN64_SYSTEM_DLLS" || true)
        if [ -n "$foreign" ]; then
            echo "build_fmu.sh: $dll imports DLLs that are not part of Windows:" >&2
            printf '  %s\n' $foreign >&2
            exit 1
        fi
    done
    echo "build_fmu.sh: win64 $(size "$STRIPPED/unstripped.dll") bytes, $(size "$DLL") stripped; FMI 3.0 $(size "$DLL3") stripped; imports: $(echo $imports); cargo $((SECONDS - win64_start)) s"
    package_args+=(--win64-lib "$DLL")
    package3_args+=(--win64-lib "$DLL3")
fi

if [ "$darwin64" -eq 1 ]; then
    # shellcheck source=scripts/darwin64.sh
    source scripts/darwin64.sh
    darwin64_start=$SECONDS
    darwin64_build
    darwin64_seconds=$((SECONDS - darwin64_start))
    objdump=$(_darwin64_llvm llvm-objdump) nm=$(_darwin64_llvm llvm-nm) lipo=$(_darwin64_llvm llvm-lipo)
    for DYLIB in "$DARWIN64_DYLIB" "$DARWIN64_DYLIB3"; do
        version=fmi2
        [ "$DYLIB" = "$DARWIN64_DYLIB3" ] && version=fmi3
        arch="universal"
        darwin_fail() { echo "build_fmu.sh: $DYLIB ($arch): $*" >&2; exit 1; }
        archs=$(echo $("$lipo" -archs "$DYLIB"))
        [ "$archs" = "x86_64 arm64" ] || darwin_fail "slices '$archs', expected 'x86_64 arm64'"
        summary=()
        for arch in x86_64 arm64; do
            headers=$("$objdump" --macho --private-headers --arch="$arch" "$DYLIB")
            # Exports: the export trie, `_fmi2…` / `_fmi3…` (Mach-O names carry a leading underscore).
            exports=$("$objdump" --macho --exports-trie --arch="$arch" "$DYLIB" | awk '/^0x/ {print $2}')
            nonunderscore=$(printf '%s\n' "$exports" | grep -v '^_' || true)
            [ -z "$nonunderscore" ] || darwin_fail "exports names without the leading underscore: $nonunderscore"
            printf '%s\n' "$exports" | sed 's/^_//' | check_exports "$DYLIB ($arch)" "$version"
            # Load commands: the dylibs loaded (any kind), the install name, the minimum macOS.
            loads=$(printf '%s\n' "$headers" | awk '$1 == "cmd" {cmd = $2} $1 == "name" && cmd != "LC_ID_DYLIB" && cmd ~ /DYLIB/ {print cmd, $2}')
            [ "$loads" = "LC_LOAD_DYLIB $DARWIN64_SYSTEM_LIBS" ] || darwin_fail "loads '$loads', expected only $DARWIN64_SYSTEM_LIBS"
            ! printf '%s\n' "$headers" | grep -q 'cmd LC_RPATH' || darwin_fail "has an LC_RPATH"
            id=$(printf '%s\n' "$headers" | awk '$1 == "cmd" {cmd = $2} $1 == "name" && cmd == "LC_ID_DYLIB" {print $2}')
            [ "$id" = "$DARWIN64_INSTALL_NAME" ] || darwin_fail "install name '$id', expected $DARWIN64_INSTALL_NAME"
            minos=$(printf '%s\n' "$headers" | awk '$1 == "cmd" {cmd = $2} (cmd == "LC_BUILD_VERSION" && $1 == "minos") || (cmd == "LC_VERSION_MIN_MACOSX" && $1 == "version") {print $2}')
            want=$([ "$arch" = arm64 ] && echo 11.0 || echo 10.13)
            [ -n "$minos" ] && [ "$(printf '%s\n%s\n' "$minos" "$want" | sort -V | tail -n1)" = "$want" ] ||
                darwin_fail "minimum macOS '$minos', at most $want wanted"
            # Stripped: only the exports and the undefined imports in the symbol table.
            local_syms=$("$nm" -a --arch="$arch" "$DYLIB" | awk '$(NF-1) != "T" && $(NF-1) != "U"' | head -n5)
            [ -z "$local_syms" ] || darwin_fail "symbols other than exports and imports (not stripped): $local_syms"
            sig=""
            if printf '%s\n' "$headers" | grep -q 'cmd LC_CODE_SIGNATURE'; then sig=", signed"; fi
            [ "$arch" = x86_64 ] || [ -n "$sig" ] || darwin_fail "no LC_CODE_SIGNATURE (Apple silicon loads no unsigned code)"
            summary+=("$arch: macOS $minos$sig")
        done
        echo "build_fmu.sh: darwin64 $(size "$DYLIB") bytes, stripped, universal ($(printf '%s; ' "${summary[@]}" | sed 's/; $//')); imports: $DARWIN64_SYSTEM_LIBS; install name $DARWIN64_INSTALL_NAME; cargo ${darwin64_seconds} s"
    done
    package_args+=(--darwin64-lib "$DARWIN64_DYLIB")
    package3_args+=(--darwin64-lib "$DARWIN64_DYLIB3")
fi

"$TARGET_DIR/release/package_fmu" "${package_args[@]}" ${pass[@]+"${pass[@]}"}

# The FMI 3.0 FMU of the same model beside it: <name>-fmi3.fmu.
FMU="$TARGET_DIR/fmu/StickSlipManipulator.fmu"
pass3=()
for ((i = 0; i < ${#pass[@]}; i++)); do
    if [ "${pass[$i]}" = "--out" ]; then
        FMU="${pass[$((i + 1))]}"
        i=$((i + 1))
    else
        pass3+=("${pass[$i]}")
    fi
done
FMU3="${FMU%.fmu}-fmi3.fmu"
"$TARGET_DIR/release/package_fmu" --fmi3 "${package3_args[@]}" ${pass3[@]+"${pass3[@]}"} --out "$FMU3"

if python -c "import fmpy" 2>/dev/null; then
    python - "$FMU" "$FMU3" <<'PY'
import sys
from fmpy.validation import validate_fmu
failed = False
for fmu in sys.argv[1:]:
    problems = validate_fmu(fmu)
    if problems:
        print("build_fmu.sh: fmpy.validation found problems in", fmu, file=sys.stderr)
        for p in problems:
            print("  " + p, file=sys.stderr)
        failed = True
    else:
        print("build_fmu.sh: fmpy.validation: no problems in", fmu)
sys.exit(1 if failed else 0)
PY
else
    echo "build_fmu.sh: fmpy not importable; validation skipped" >&2
fi
