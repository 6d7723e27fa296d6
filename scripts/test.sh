#!/usr/bin/env bash
# scripts/test.sh -- THE test command (CI runs it through .ci/run).
#
#   bash scripts/test.sh [--quick] [pytest args...]
#
#   0. formatters and linters, each a stage that fails the run:
#      cargo fmt --all --check, cargo clippy --workspace --all-targets -- -D warnings (the
#      workspace: the engine crate and fmi3/; and tests/win64), the same on the engine crate
#      as the FMI 2.0 library is built (--lib --no-default-features: without its feature
#      fmi3), ruff check, ruff format --check
#   1. cargo test --release --all-targets --no-fail-fast  (release: physics tests are heavy)
#   2. cargo test --release --doc           (doc tests; only if there is a lib target)
#   3. FMU packaging hook: scripts/build_fmu.sh --platforms all: linux64, win64
#      and darwin64 (STICKSLIP_DARWIN64=0 leaves darwin64 out, for developers
#      only: in CI, CI=true, tests/python/test_darwin64.py then fails; see
#      docs/platforms.md)
#   3b. cargo test --test engine fmi3_crate on the FMI 3.0 FMU of stage 3
#   4. win64 tests (tests/win64): the FMU's Windows DLL under wine against the
#      linux64 .so (scripts/win64.sh)
#   5. pytest tests/python --runslow        (if it holds test files; every test, the `slow`
#                                            ones included; --quick deselects `slow` and
#                                            `full`, see tests/python/conftest.py;
#                                            exit 5 "no tests collected" counts as ok)
#
# Before stage 0, a fresh clone's target dir gets the dependencies an earlier full run
# compiled, and after stage 5 the full run leaves its own for the next clone
# (scripts/target-seed.sh says how that cache is invalidated; STICKSLIP_TARGET_SEED=0
# leaves it out).
#
# Every stage runs even if an earlier one failed; the script exits non-zero if
# any stage failed. The last line is always
#     total: N passed, N failed, N skipped
# (a stage that failed without reporting a failed test, e.g. a compile error,
# adds 1 to "failed").
#
# Extra arguments are passed to pytest, e.g. `scripts/test.sh -k fit`.
#
# --quick: the inner loop of a change to the engine or the Python package
# (README, "Tests"): stages 0-2, the linux64 FMU only (no cross builds, no
# wine) and the Python tests that need neither the win64/darwin64 binaries
# nor a second master or a Dask cluster (pytest -m "not full"; the marker
# `full` is set in tests/python/conftest.py). The full run (no --quick) is
# what CI runs and what a change to the FMI layer, the build scripts, the
# platforms or the sweep must pass.
set -euo pipefail

QUICK=0
if [ "${1:-}" = "--quick" ]; then
    QUICK=1
    shift
    # The parameter-space sample (tests/engine/parameter_space.rs, 24 variants, about 50 s)
    # with its first 8 variants only.
    export STICKSLIP_VARIANTS="${STICKSLIP_VARIANTS:-8}"
    # No debug info in the inner loop's builds (the release profile's line tables, for
    # profiling the engine, cost about 12 s of every build of the engine; linux64 only, so
    # no cross build sees this profile). cargo keeps the two profiles' files apart: the
    # full run's builds and these do not rebuild each other's.
    export CARGO_PROFILE_RELEASE_DEBUG="${CARGO_PROFILE_RELEASE_DEBUG:-0}"
fi

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
if [ "$QUICK" -eq 0 ]; then
    # The full run builds and tests every platform (env.sh installs the win64 toolchain and
    # wine for it; build_fmu.sh the darwin64 one).
    export STICKSLIP_PLATFORMS=all STICKSLIP_WIN64=1
fi
# shellcheck source=scripts/env.sh
source scripts/env.sh

# A fresh clone's target dir starts with the dependencies an earlier run compiled
# (scripts/target-seed.sh: what is cached, and how it is invalidated).
# shellcheck source=scripts/target-seed.sh
source scripts/target-seed.sh
target_seed_restore "${CARGO_TARGET_DIR:-$ROOT/target}"

LOGDIR=$(mktemp -d "${TMPDIR:-/tmp}/stickslip-test.XXXXXX")
trap 'rm -rf "$LOGDIR"' EXIT

banner() { printf '\n===== %s =====\n' "$*"; }

FAILED_STAGES=()
SUMMARY=()
TOT_PASS=0 TOT_FAIL=0 TOT_SKIP=0

# Sum the libtest "test result:" lines of a cargo log -> "passed failed ignored".
cargo_counts() {
    awk '/^test result: /{
            for (i = 1; i <= NF; i++) {
                if ($(i+1) ~ /^passed/)  p += $i
                if ($(i+1) ~ /^failed/)  f += $i
                if ($(i+1) ~ /^ignored/) g += $i
            }
         } END { printf "%d %d %d\n", p, f, g }' "$1"
}

# run_cargo_stage NAME LOG -- cargo args...
run_cargo_stage() {
    run_libtest_stage "$1" "$2" -- cargo "${@:4}"
}

# run_libtest_stage NAME LOG -- COMMAND args...   (a command whose output has
# libtest's "test result:" lines, e.g. cargo test or win64_cargo test)
run_libtest_stage() {
    local name="$1" log="$2" rc p f g start=$SECONDS
    shift 3
    banner "$name: $*"
    set +e
    "$@" 2>&1 | tee "$log"
    rc=${PIPESTATUS[0]}
    set -e
    read -r p f g < <(cargo_counts "$log")
    SUMMARY+=("$name: $p passed, $f failed, $g ignored (exit $rc, $((SECONDS - start)) s)")
    TOT_PASS=$((TOT_PASS + p)); TOT_SKIP=$((TOT_SKIP + g)); TOT_FAIL=$((TOT_FAIL + f))
    if [ "$rc" -ne 0 ]; then
        FAILED_STAGES+=("$name")
        [ "$f" -eq 0 ] && TOT_FAIL=$((TOT_FAIL + 1))
    fi
    return 0
}

# run_check_stage NAME -- COMMAND args...   (a formatter or linter: its exit status decides)
run_check_stage() {
    local name="$1" rc start=$SECONDS
    shift 2
    banner "$name: $*"
    set +e
    "$@"
    rc=$?
    set -e
    if [ "$rc" -eq 0 ]; then
        SUMMARY+=("$name: ok ($((SECONDS - start)) s)")
        TOT_PASS=$((TOT_PASS + 1))
    else
        SUMMARY+=("$name: FAILED (exit $rc, $((SECONDS - start)) s)")
        FAILED_STAGES+=("$name")
        TOT_FAIL=$((TOT_FAIL + 1))
    fi
    return 0
}

# ---- 0. formatters and linters -------------------------------------------------
# rustfmt.toml and pyproject.toml's [tool.ruff] hold the choices; clippy's
# warnings are errors. tests/win64 is a package of its own (its own manifest).
run_check_stage "rustfmt" -- cargo fmt --all --check
run_check_stage "rustfmt-win64" -- cargo fmt --manifest-path tests/win64/Cargo.toml --check
run_check_stage "clippy" -- cargo clippy --release --workspace --all-targets --quiet -- -D warnings
# The FMI 2.0 library's build (scripts/build_fmu.sh): the engine crate without its feature fmi3.
run_check_stage "clippy-fmi2" -- cargo clippy --release -p stick_slip_manipulator --lib --no-default-features \
    --quiet -- -D warnings
if [ "$QUICK" -eq 0 ]; then
    run_check_stage "clippy-win64" -- cargo clippy --release --quiet --manifest-path tests/win64/Cargo.toml \
        --target-dir "${CARGO_TARGET_DIR:-$ROOT/target}" --all-targets -- -D warnings
fi
run_check_stage "ruff-check" -- ruff check --no-cache .
run_check_stage "ruff-format" -- ruff format --no-cache --check .

# ---- 1. Rust tests ----------------------------------------------------------
run_cargo_stage "cargo-test" "$LOGDIR/cargo-test.log" -- test --release --all-targets --no-fail-fast

# ---- 2. Rust doc tests (lib targets only) ---------------------------------------
if [ -f src/lib.rs ]; then
    run_cargo_stage "cargo-doctest" "$LOGDIR/cargo-doc.log" -- test --release --doc --no-fail-fast
fi

# ---- 3. FMU packaging hook ------------------------------------------------------
# >>> FMU HOOK: the FMU issue adds scripts/build_fmu.sh (builds the cdylib and zips
# >>> the .fmu). When present it runs here, before the Python tests that load it.
# build_fmu.sh's default platforms, darwin64 among them (docs/platforms.md):
# tests/python/test_darwin64.py (stage 5) checks the macOS dylib. A developer
# may leave it out with STICKSLIP_DARWIN64=0 (those tests then skip, or fail
# under CI=true).
build_fmu_args=()
[ "$QUICK" -eq 1 ] && build_fmu_args=(--platforms linux64)
# The FMUs' libraries (and the tests' own cargo builds) with every target, as stage 1
# built them: one build of the engine, not two (scripts/build_fmu.sh).
export STICKSLIP_FMU_ALL_TARGETS=1
if [ -f scripts/build_fmu.sh ]; then
    banner "build-fmu: bash scripts/build_fmu.sh ${build_fmu_args[*]} (STICKSLIP_DARWIN64=${STICKSLIP_DARWIN64:-1})"
    fmu_start=$SECONDS
    if bash scripts/build_fmu.sh ${build_fmu_args[@]+"${build_fmu_args[@]}"}; then
        SUMMARY+=("build-fmu: ok ($((SECONDS - fmu_start)) s)")
    else
        SUMMARY+=("build-fmu: FAILED")
        FAILED_STAGES+=("build-fmu")
        TOT_FAIL=$((TOT_FAIL + 1))
    fi
fi

# ---- 3b. the FMI 3.0 FMU through the Rust fmi crate -------------------------------
# tests/engine/fmi3_crate.rs reads the FMI 3.0 FMU stage 3 built (stage 1 ran before
# it existed, or against an older one, and skipped): run it again on it.
if [ -f tests/engine/fmi3_crate.rs ]; then
    export STICKSLIP_FMU3="${CARGO_TARGET_DIR:-$ROOT/target}/fmu/StickSlipManipulator-fmi3.fmu"
    run_cargo_stage "fmi3-crate" "$LOGDIR/fmi3-crate.log" -- test --release --test engine fmi3_crate
fi

# ---- 4. win64: the FMU's Windows binary under wine -------------------------------
# tests/win64 (its own package): the `fmi` crate as master runs the reference
# motion on Linux against binaries/linux64 (a), then, compiled for
# x86_64-pc-windows-gnu and run under wine, against binaries/win64 of the same
# .fmu (b), then restores on Linux the state win64 serialized (c); see
# tests/win64/Cargo.toml. The same for the FMI 3.0 FMU: its x86_64-linux binary
# runs the reference motion and an early-return run (fmi3-a), its
# x86_64-windows DLL under wine must return early at the same instants and
# agree (fmi3-b). Also the main crate's unit tests, compiled for Windows,
# under wine. Missing wine or a missing win64 binary fail the stage.
if [ -d tests/win64 ] && [ "$QUICK" -eq 0 ]; then
    # shellcheck source=scripts/win64.sh
    source scripts/win64.sh
    export STICKSLIP_FMU="${CARGO_TARGET_DIR:-$ROOT/target}/fmu/StickSlipManipulator.fmu"
    export STICKSLIP_FMU3="${CARGO_TARGET_DIR:-$ROOT/target}/fmu/StickSlipManipulator-fmi3.fmu"
    export STICKSLIP_XPLAT_DIR="$LOGDIR/xplat"
    win64_tests=(test --release --manifest-path tests/win64/Cargo.toml --no-fail-fast)
    linux_target=(--target-dir "${CARGO_TARGET_DIR:-$ROOT/target}")   # not tests/win64/target
    # The main crate's release profile (debug = 1): the Linux master then reuses
    # the `fmi` crate of stage 1 from the shared target dir, and the Windows
    # master the std that build_fmu.sh built for the DLL, instead of building
    # them again (a profile difference cargo keeps out of the file names would
    # make the two builds overwrite each other's artifacts each run).
    export CARGO_PROFILE_RELEASE_DEBUG=1
    run_libtest_stage "win64-a-linux64" "$LOGDIR/win64-a.log" -- cargo "${win64_tests[@]}" "${linux_target[@]}" --test linux64
    run_libtest_stage "win64-fmi3-a-linux64" "$LOGDIR/win64-fmi3-a.log" -- \
        cargo "${win64_tests[@]}" "${linux_target[@]}" --test linux64_fmi3
    banner "win64: the test-only wine prefix"
    if win64_wine_prefix; then
        run_libtest_stage "win64-b-wine" "$LOGDIR/win64-b.log" -- win64_cargo "${win64_tests[@]}" --test win64
        run_libtest_stage "win64-fmi3-b-wine" "$LOGDIR/win64-fmi3-b.log" -- win64_cargo "${win64_tests[@]}" --test win64_fmi3
        # The engine's own unit tests on Windows: the C boundary's catch_unwind
        # (a panic leaves the instance in the error state), the Windows resource
        # URI through the real Windows code path, the FMI layer's call checks.
        run_libtest_stage "win64-lib-wine" "$LOGDIR/win64-lib.log" -- win64_cargo test --release --lib --no-fail-fast
    else
        SUMMARY+=("win64-b-wine: FAILED (no wine prefix)" "win64-fmi3-b-wine: FAILED (no wine prefix)")
        FAILED_STAGES+=("win64-b-wine" "win64-fmi3-b-wine")
        TOT_FAIL=$((TOT_FAIL + 2))
    fi
    run_libtest_stage "win64-c-linux64" "$LOGDIR/win64-c.log" -- cargo "${win64_tests[@]}" "${linux_target[@]}" --test linux64_after_win64
    unset CARGO_PROFILE_RELEASE_DEBUG
fi

# ---- 5. Python tests ------------------------------------------------------------
if [ -d tests/python ] && [ -n "$(find tests/python \( -name 'test_*.py' -o -name '*_test.py' \) -print -quit)" ]; then
    banner "pytest tests/python $*"
    pytest_start=$SECONDS
    set +e
    # Two worker processes (pytest-xdist), a test module on one worker
    # (its module-scoped fixtures once); STICKSLIP_PYTEST_WORKERS=0 runs them
    # in this process.
    workers="${STICKSLIP_PYTEST_WORKERS:-2}"
    pytest_args=(-ra --durations=15)
    [ "$workers" != 0 ] && pytest_args+=(-n "$workers" --dist loadfile)
    # The full run includes the slow tests (the fit's statistical checks, the study at full
    # resolution, the examples' commands): a test no command runs rots. --quick leaves them out.
    if [ "$QUICK" -eq 1 ]; then pytest_args+=(-m "not full"); else pytest_args+=(--runslow); fi
    python -m pytest tests/python "${pytest_args[@]}" --junitxml="$LOGDIR/pytest.xml" "$@" 2>&1 | tee "$LOGDIR/pytest.log"
    rc=${PIPESTATUS[0]}
    set -e
    counts="0 0 0 0"
    if [ -f "$LOGDIR/pytest.xml" ]; then
        counts=$(python - "$LOGDIR/pytest.xml" <<'PY'
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
t = f = e = s = 0
for su in suites:
    t += int(su.get("tests", 0)); f += int(su.get("failures", 0))
    e += int(su.get("errors", 0)); s += int(su.get("skipped", 0))
print(t - f - e - s, f, e, s)
PY
)
    fi
    read -r p f e s <<<"$counts"
    desel=$(grep -Eo '[0-9]+ deselected' "$LOGDIR/pytest.log" | tail -n1 | cut -d' ' -f1 || true)
    SUMMARY+=("pytest: $p passed, $((f + e)) failed, $s skipped, ${desel:-0} deselected (exit $rc, $((SECONDS - pytest_start)) s)")
    TOT_PASS=$((TOT_PASS + p)); TOT_FAIL=$((TOT_FAIL + f + e)); TOT_SKIP=$((TOT_SKIP + s))
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 5 ]; then   # 5 = no tests collected: ok
        FAILED_STAGES+=("pytest")
        [ $((f + e)) -eq 0 ] && TOT_FAIL=$((TOT_FAIL + 1))
    fi
else
    SUMMARY+=("pytest: no test files in tests/python (skipped)")
fi

# ---- the target dir's dependencies for the next fresh clone ------------------------
[ "$QUICK" -eq 0 ] && target_seed_save "${CARGO_TARGET_DIR:-$ROOT/target}"

# ---- summary --------------------------------------------------------------------
banner "summary"
printf '%s\n' "${SUMMARY[@]}"
echo "wall time: $SECONDS s (set-up by scripts/env.sh included)"
if [ "${#FAILED_STAGES[@]}" -gt 0 ]; then
    echo "FAILED stages: ${FAILED_STAGES[*]}"
    echo "total: $TOT_PASS passed, $TOT_FAIL failed, $TOT_SKIP skipped"
    exit 1
fi
echo "all stages passed"
echo "total: $TOT_PASS passed, $TOT_FAIL failed, $TOT_SKIP skipped"
