#!/usr/bin/env bash
# scripts/build_fmu.sh -- builds the FMI 2.0 co-simulation FMU.
#
#   bash scripts/build_fmu.sh [--platforms linux64,win64] [package_fmu args...]
#
#   --platforms LIST  the FMU binaries to build, comma-separated; default
#                     `linux64,win64` (both). `--platforms linux64` skips the
#                     Windows cross-build while iterating.
#
#   1. linux64: cargo build --release --lib --bin package_fmu   (the cdylib;
#      build.rs also writes modelDescription/modelDescription.xml)
#   2. win64: the same library cross-built for x86_64-pc-windows-gnu with
#      Debian's rustc and mingw-w64 (scripts/win64.sh), target dir target/win64
#   3. copies stripped of debug info and symbol table (strip --strip-all, into
#      target/fmu/stripped/): the FMU ships those; target/release and
#      target/win64/…/release keep the debug info for local profiling
#   4. checks every shipped binary's interface: exactly the 34 FMI 2.0
#      functions exported; the DLL imports Windows system DLLs only
#   5. package_fmu: target/fmu/StickSlipManipulator.fmu (or --out FILE) from the
#      reference model (or --model FILE)
#   6. fmpy.validation of the FMU, when the venv has fmpy
#
# Called by scripts/test.sh and scripts/main.sh.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
# shellcheck source=scripts/env.sh
source scripts/env.sh

platforms="linux64,win64"
pass=()
while [ $# -gt 0 ]; do
    case "$1" in
        --platforms) [ $# -ge 2 ] || { echo "build_fmu.sh: --platforms needs a value" >&2; exit 2; }
                     platforms="$2"; shift 2 ;;
        --platforms=*) platforms="${1#--platforms=}"; shift ;;
        *) pass+=("$1"); shift ;;
    esac
done
linux64=0 win64=0
IFS=, read -r -a wanted <<<"$platforms"
for p in "${wanted[@]}"; do
    case "$p" in
        linux64) linux64=1 ;;
        win64) win64=1 ;;
        *) echo "build_fmu.sh: unknown platform '$p' (linux64, win64; darwin64 cannot be built here)" >&2; exit 2 ;;
    esac
done
if [ "$linux64" -eq 0 ]; then
    # package_fmu and build.rs's modelDescription come from the Linux build.
    echo "build_fmu.sh: --platforms must include linux64" >&2
    exit 2
fi

TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
LIB="$TARGET_DIR/release/libstick_slip_manipulator.so"
STRIPPED="$TARGET_DIR/fmu/stripped"
mkdir -p "$STRIPPED"

# The interface of a binary is the FMU's: the 34 fmi2 functions, nothing else.
# check_exports FILE < exported names
check_exports() {
    local symbols count extra
    symbols=$(sort)
    count=$(printf '%s\n' "$symbols" | grep -c . || true)
    extra=$(printf '%s\n' "$symbols" | grep -v '^fmi2' || true)
    if [ "$count" -ne 34 ] || [ -n "$extra" ]; then
        echo "build_fmu.sh: $1 exports $count symbols, expected the 34 fmi2 functions only:" >&2
        printf '%s\n' "$symbols" >&2
        exit 1
    fi
}

size() { stat -c %s "$1"; }

cargo build --release --lib --bin package_fmu
SO="$STRIPPED/libstick_slip_manipulator.so"
strip --strip-all -o "$SO" "$LIB"
nm -D --defined-only "$SO" | awk '$2 ~ /^[TtWwDdBbRrVviu]$/ {print $3}' | check_exports "$SO"
echo "build_fmu.sh: linux64 $(size "$LIB") bytes, $(size "$SO") stripped"
package_args=(--lib "$SO")

if [ "$win64" -eq 1 ]; then
    # shellcheck source=scripts/win64.sh
    source scripts/win64.sh
    win64_cargo build --release --lib
    DLL="$STRIPPED/StickSlipManipulator.dll"
    x86_64-w64-mingw32-strip --strip-all -o "$DLL" "$WIN64_RELEASE/stick_slip_manipulator.dll"
    exports=$(x86_64-w64-mingw32-objdump -p "$DLL" | sed -n '/\[Ordinal\/Name Pointer\] Table/,/^$/p' | awk 'NR > 1 && /^[[:space:]]*\[/ {print $NF}')
    printf '%s\n' "$exports" | check_exports "$DLL"
    # Imports: Windows system DLLs only (no libgcc_s, libwinpthread, libstdc++).
    imports=$(x86_64-w64-mingw32-objdump -p "$DLL" | awk '/DLL Name:/ {print tolower($3)}' | sort -u)
    foreign=$(printf '%s\n' "$imports" | grep -Evx "$WIN64_SYSTEM_DLLS" || true)
    if [ -n "$foreign" ]; then
        echo "build_fmu.sh: $DLL imports DLLs that are not part of Windows:" >&2
        printf '  %s\n' $foreign >&2
        exit 1
    fi
    echo "build_fmu.sh: win64 $(size "$WIN64_RELEASE/stick_slip_manipulator.dll") bytes, $(size "$DLL") stripped; imports: $(echo $imports)"
    package_args+=(--win64-lib "$DLL")
fi

"$TARGET_DIR/release/package_fmu" "${package_args[@]}" ${pass[@]+"${pass[@]}"}

FMU="$TARGET_DIR/fmu/StickSlipManipulator.fmu"
for ((i = 0; i < ${#pass[@]}; i++)); do
    [ "${pass[$i]}" = "--out" ] && FMU="${pass[$((i + 1))]}"
done
if python -c "import fmpy" 2>/dev/null; then
    python - "$FMU" <<'PY'
import sys
from fmpy.validation import validate_fmu
problems = validate_fmu(sys.argv[1])
if problems:
    print("build_fmu.sh: fmpy.validation found problems in", sys.argv[1], file=sys.stderr)
    for p in problems:
        print("  " + p, file=sys.stderr)
    sys.exit(1)
print("build_fmu.sh: fmpy.validation: no problems in", sys.argv[1])
PY
else
    echo "build_fmu.sh: fmpy not importable; validation skipped" >&2
fi
