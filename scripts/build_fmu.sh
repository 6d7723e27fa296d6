#!/usr/bin/env bash
# scripts/build_fmu.sh -- builds the FMI 2.0 co-simulation FMU.
#
#   bash scripts/build_fmu.sh [package_fmu args...]
#
#   1. cargo build --release --lib --bin package_fmu   (the cdylib; build.rs also
#      writes modelDescription/modelDescription.xml for the reference model)
#   2. checks that the library exports exactly the 34 FMI 2.0 functions
#   3. package_fmu: target/fmu/StickSlipManipulator.fmu (or --out FILE) from the
#      reference model (or --model FILE)
#   4. fmpy.validation of the FMU, when the venv has fmpy
#
# Called by scripts/test.sh and scripts/main.sh.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
# shellcheck source=scripts/env.sh
source scripts/env.sh

TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
LIB="$TARGET_DIR/release/libstick_slip_manipulator.so"

cargo build --release --lib --bin package_fmu

# The symbol table is the FMU's interface: the 34 fmi2 functions, nothing else.
symbols=$(nm -D --defined-only "$LIB" | awk '$2 ~ /^[TtWwDdBbRrVviu]$/ {print $3}' | sort)
count=$(printf '%s\n' "$symbols" | grep -c . || true)
extra=$(printf '%s\n' "$symbols" | grep -v '^fmi2' || true)
if [ "$count" -ne 34 ] || [ -n "$extra" ]; then
    echo "build_fmu.sh: $LIB exports $count symbols, expected the 34 fmi2 functions only:" >&2
    printf '%s\n' "$symbols" >&2
    exit 1
fi

"$TARGET_DIR/release/package_fmu" --lib "$LIB" "$@"

FMU="$TARGET_DIR/fmu/StickSlipManipulator.fmu"
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
    [ "${args[$i]}" = "--out" ] && FMU="${args[$((i + 1))]}"
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
