#!/usr/bin/env bash
# scripts/main.sh -- the main job: build the FMUs, simulate the reference manipulator, plot
# it, and run the examples, the study and the calibrations into results/. No test runs here
# (scripts/test.sh runs every test).
#
#   1-2. scripts/build_fmu.sh (its cargo builds): the FMI 2.0 and FMI 3.0 FMUs for this machine (linux64);
#      STICKSLIP_PLATFORMS=all adds the win64 and darwin64 binaries (their toolchains,
#      about 350 MB of apt packages and a PyPI package, and about 3 minutes of compiling
#      each on a fresh machine: docs/platforms.md)
#   3. stickslip simulate --out results/reference.csv  (the FMU through fmpy)
#   4. python scripts/plot_reference.py results/reference.csv results/
#   4b. python scripts/figure_fmi3_events.py --out results/fmi3_events.png (docs/fmi3.md's
#       figure: the reference run through the FMI 3.0 FMU with early return, against FMI 2.0)
#   5. the URDF example arms (docs/urdf.md): per arm (KUKA iiwa, xArm 6) its FMU
#      (scripts/build_fmu.sh --model models/urdf/<arm>/<arm>.toml), a reference-like
#      motion file (examples/motions/<arm>.toml) from a static-equilibrium start
#      (scripts/urdf_static_start.py), CSV, plots and summary.json in results/<arm>/
#      (scripts/plot_urdf_arm.py); URDF_ARMS="kuka_iiwa" runs one, "" none
#   6. stickslip study --out results/study   (the source study's five cases, docs/study.md)
#   7. stickslip sweep examples/monte_carlo.toml --out results/monte_carlo  (its first 500 samples)
#   7b. stickslip fit examples/calibration/calibration.toml --out results/calibration
#       (docs/calibration.md: six parameters of the reference arm from two measured runs)
#   7c. stickslip fit examples/calibration_motor/calibration.toml --out results/calibration_motor
#       and its three held-out runs replayed (stickslip simulate --spec .../heldout.toml --fitted
#       ... --horizon 0.25 --out results/calibration_motor/heldout): the torque-logged motor arm
#   7d. stickslip identify examples/identification/identify.toml --out results/identification, and
#       the identified model's FMU (scripts/build_fmu.sh --model .../identified.toml): a real arm's
#       links and friction from its torque logs
#
# Each stage prints its wall time; the README's table gives them as measured on a fresh
# 2-core machine. Output directory: $RESULTS_DIR (default <repo>/results). Extra arguments
# are passed to `stickslip simulate` (e.g. --set mu_k[3]=0.1).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
# shellcheck source=scripts/env.sh
source scripts/env.sh

RESULTS_DIR="${RESULTS_DIR:-$ROOT/results}"
CSV="$RESULTS_DIR/reference.csv"
mkdir -p "$RESULTS_DIR"

STAGE_START=$SECONDS
STAGE_NAME=""
# banner NAME: ends the stage before (its wall time) and starts the next.
banner() {
    [ -n "$STAGE_NAME" ] && printf 'main.sh: %s: %d s\n' "$STAGE_NAME" $((SECONDS - STAGE_START))
    STAGE_NAME="$*" STAGE_START=$SECONDS
    printf '\n===== %s =====\n' "$*"
}

# The FMUs for this machine (STICKSLIP_PLATFORMS=all: every platform, see the header).
if [ -f scripts/build_fmu.sh ]; then
    banner "bash scripts/build_fmu.sh (platforms: ${STICKSLIP_PLATFORMS:-linux64})"
    bash scripts/build_fmu.sh
fi

banner "reference motion through the FMU (fmpy) -> $CSV"
stickslip simulate --out "$CSV" "$@"
[ -s "$CSV" ] || { echo "main.sh: the FMU run wrote no $CSV" >&2; exit 1; }

banner "plot_reference.py"
python scripts/plot_reference.py "$CSV" "$RESULTS_DIR"

# docs/fmi3.md's figure from the two FMUs just built (the copy in docs/figures is made by
# running the script without --out). Measured: 8 s on 2 busy cores.
banner "figure_fmi3_events.py: early returns of the FMI 3.0 FMU -> $RESULTS_DIR/fmi3_events.png"
python scripts/figure_fmi3_events.py --out "$RESULTS_DIR/fmi3_events.png"

# The URDF example arms (issue 19, docs/urdf.md). Each step is checked explicitly, so
# that a failed arm stops the main job with a message naming the arm and the step.
# Measured: 18 s for both arms on 2 busy cores (per arm: build_fmu.sh 4 s with the
# binaries of the reference FMU above, start values, a 2 s run in 0.3-0.5 s, plots).
urdf_failed() {
    echo "main.sh: URDF arm $1: $2 FAILED (exit $3); the output above says why" >&2
    exit 1
}
urdf_arm() {  # name: models/urdf/<name>/<name>.toml driven by examples/motions/<name>.toml
    local name=$1
    local model="models/urdf/$name/$name.toml" motion="examples/motions/$name.toml"
    local fmu="$ROOT/target/fmu/$name.fmu" out="$RESULTS_DIR/$name"
    local csv="$out/$name.csv"
    banner "URDF arm $name: FMU, $motion from static equilibrium -> $out"
    rm -rf "$out"
    mkdir -p "$out" || urdf_failed "$name" "mkdir $out" $?
    # The binaries are the ones just built: cargo and the cross-builds have nothing to do.
    bash scripts/build_fmu.sh --model "$model" --out "$fmu" || urdf_failed "$name" "building its FMU ($model)" $?
    local start
    start=$(python scripts/urdf_static_start.py --fmu "$fmu" --motion "$motion") \
        || urdf_failed "$name" "static start values (scripts/urdf_static_start.py)" $?
    local args=() a b
    while read -r a b; do [ -n "$a" ] && args+=("$a" "$b"); done <<<"$start"
    [ "${#args[@]}" -ge 2 ] || urdf_failed "$name" "static start values (none printed)" 1
    printf '%s\n' "stickslip simulate --fmu target/fmu/$name.fmu --motion $motion --out $name.csv ${args[*]}" \
        >"$out/command.txt"
    stickslip simulate --fmu "$fmu" --motion "$motion" --out "$csv" "${args[@]}" \
        || urdf_failed "$name" "stickslip simulate --motion $motion" $?
    [ -s "$csv" ] || urdf_failed "$name" "stickslip simulate (wrote no $csv)" 1
    python scripts/plot_urdf_arm.py "$csv" "$out" --fmu "$fmu" --name "$name" --loads 1,2 \
        --summary "$out/summary.json" || urdf_failed "$name" "plot_urdf_arm.py" $?
}
URDF_ARMS="${URDF_ARMS-kuka_iiwa xarm6}"
urdf_started=$SECONDS
for arm in $URDF_ARMS; do
    urdf_arm "$arm"
done
[ -z "$URDF_ARMS" ] || echo "main.sh: URDF arms ($URDF_ARMS): $((SECONDS - urdf_started)) s"

# The axis-control example (issue 20, docs/control.md): a cascaded position/velocity
# controller at 1 kHz in Python driving the motor arm's FMU (models/reference_rrpr_motor.toml)
# with motor torques: (a) the reference motion, (b) hunting with integral action, (c) motor
# against link encoder. PNGs, one CSV per run and summary.json in $RESULTS_DIR/axis_control
# (`--docs-figures docs/figures` regenerates docs/control.md's figures; not done here). A failure
# stops the main job with a message naming the step. Measured: about 30 s on 2 busy cores
# (build_fmu.sh re-packaging with the binaries above, the example's 23 closed-loop runs,
# figures).
axis_control_failed() {
    echo "main.sh: axis-control example: $1 FAILED (exit $2); the output above says why" >&2
    exit 1
}
banner "axis-control example (examples/axis_control.py, docs/control.md) -> $RESULTS_DIR/axis_control"
axis_fmu="$ROOT/target/fmu/reference_rrpr_motor.fmu"
bash scripts/build_fmu.sh --model models/reference_rrpr_motor.toml --out "$axis_fmu" \
    || axis_control_failed "building its FMU (models/reference_rrpr_motor.toml)" $?
rm -rf "$RESULTS_DIR/axis_control"
python examples/axis_control.py --fmu "$axis_fmu" --out "$RESULTS_DIR/axis_control" \
    || axis_control_failed "examples/axis_control.py" $?
[ -s "$RESULTS_DIR/axis_control/summary.json" ] \
    || axis_control_failed "examples/axis_control.py (wrote no summary.json)" 1

banner "stickslip study: the source study's five cases through the FMU -> $RESULTS_DIR/study"
stickslip study --out "$RESULTS_DIR/study"

# The Monte Carlo example has 1000 samples of the 2 s motion; its first MC_SAMPLES draws
# (default 200: the main job's ten minutes on a fresh 2-core machine leave about a minute for
# this stage; MC_SAMPLES=1000 runs them all) are run. A seeded tenth of them is run again with a
# tenfold tighter error tolerance (docs/convergence.md: about +25 % time), so that summary.md
# says where the numbers are not converged.
MC_SAMPLES="${MC_SAMPLES:-200}"
banner "stickslip sweep examples/monte_carlo.toml (first $MC_SAMPLES samples, 10 % checked for convergence) -> $RESULTS_DIR/monte_carlo"
rm -rf "$RESULTS_DIR/monte_carlo"
stickslip sweep examples/monte_carlo.toml --out "$RESULTS_DIR/monte_carlo" --samples "$MC_SAMPLES" \
    --check-convergence --convergence-fraction 0.1

# The calibration example (docs/calibration.md): measured by the FMU at values the SPEC
# does not know; about 4 minutes on 2 busy cores.
banner "stickslip fit examples/calibration/calibration.toml -> $RESULTS_DIR/calibration"
stickslip fit examples/calibration/calibration.toml --out "$RESULTS_DIR/calibration"

# The torque-logged motor arm (docs/calibration.md#torque-logged-arms): ten rotor and friction
# parameters from three runs' logged torques, and the three held-out runs predicted over 0.25 s
# with them (its FMU was built above for the axis controller).
banner "stickslip fit examples/calibration_motor/calibration.toml -> $RESULTS_DIR/calibration_motor"
stickslip fit examples/calibration_motor/calibration.toml --out "$RESULTS_DIR/calibration_motor"
stickslip simulate --spec examples/calibration_motor/heldout.toml \
    --fitted "$RESULTS_DIR/calibration_motor/fitted.toml" --horizon 0.25 --out "$RESULTS_DIR/calibration_motor/heldout"

# A real arm's model from its torque logs (docs/calibration.md#real-arms): the KUKA iiwa whose
# catalogue URDF has its links up to 30 % off; the identified model file and URDF, its FMU, and
# the held-out runs' torques predicted (examples/identification/make_data.py made the logs).
banner "stickslip identify examples/identification/identify.toml -> $RESULTS_DIR/identification"
bash scripts/build_fmu.sh --model examples/identification/catalogue.toml --out "$ROOT/target/fmu/iiwa_catalogue.fmu"
stickslip identify examples/identification/identify.toml --out "$RESULTS_DIR/identification"
bash scripts/build_fmu.sh --model "$RESULTS_DIR/identification/identified.toml" \
    --out "$RESULTS_DIR/identification/identified.fmu"

banner "done"
echo "main.sh: $SECONDS s in all (set-up by scripts/env.sh included)"
echo "results in $RESULTS_DIR:"
ls -l "$RESULTS_DIR"
