# scripts/target-seed.sh -- the compiled dependencies of a fresh clone's target dir, from
# an earlier run (sourced by scripts/test.sh; needs STICKSLIP_CACHE_DIR from scripts/env.sh).
#
#   target_seed_restore TARGET_DIR   before the first cargo command: each profile directory
#                                    of TARGET_SEED_PROFILES that TARGET_DIR does not have
#                                    yet is copied from the seed
#   target_seed_save TARGET_DIR      at the end: TARGET_DIR's profile directories become the seed
#
# The profile directories: release/ (cargo test, clippy, the FMI 3.0 library, package_fmu)
# and fmi2/ (the FMI 2.0 library, built with the profile `fmi2` by scripts/build_fmu.sh).
#
# What CI caches of a Rust project's target dir (the dependencies' compiled crates, their
# build scripts' outputs, clippy's metadata), kept outside the clone: a fresh clone starts
# with them and compiles only the workspace's own crates. sccache (scripts/env.sh) serves the
# same crates one compiler call at a time; the seed saves those calls and the links.
#
# Invalidation:
#   * The seed's key is a hash of `rustc -vV`, `cargo -V` and both Cargo.lock files: another
#     compiler or another dependency version starts a new seed (the two newest are kept).
#   * Within a seed, cargo's own fingerprints decide what is fresh, as in any target dir: a
#     unit whose profile, features, flags or environment differ is compiled again.
#   * The workspace's own packages (the engine, fmi3/, tests/win64) are never taken from the
#     seed: their fingerprints are removed on saving and again on restoring, so that cargo
#     compiles them from the clone's sources. (Their fingerprints compare source mtimes with
#     the build's, and a seed saved after the clone was made could otherwise look newer.)
#
# STICKSLIP_TARGET_SEED=0 leaves the seed out. The cross builds (win64, darwin64) have their
# own target dir in the cache already (scripts/win64.sh, scripts/build_fmu.sh).

TARGET_SEED_PROFILES=(release fmi2)

_target_seed_dir() {
    local key
    key=$({
        rustc -vV
        cargo -V
        cat Cargo.lock tests/win64/Cargo.lock 2>/dev/null
    } | sha256sum | cut -c1-16)
    printf '%s/target-seed/%s\n' "${STICKSLIP_CACHE_DIR:?scripts/env.sh sets STICKSLIP_CACHE_DIR}" "$key"
}

# The workspace's own units in a profile dir: fingerprints removed, so cargo builds them.
_target_seed_forget_workspace() {
    find "$1/.fingerprint" -maxdepth 1 \( -name 'stick_slip_manipulator-*' \
        -o -name 'stick_slip_manipulator_fmi3-*' -o -name 'stickslip-win64-tests-*' \) \
        -exec rm -rf {} +
}

target_seed_restore() {
    local target="$1" seed start profile missing=()
    [ "${STICKSLIP_TARGET_SEED:-1}" = 1 ] || return 0
    for profile in "${TARGET_SEED_PROFILES[@]}"; do
        [ -e "$target/$profile" ] || missing+=("$profile")
    done
    [ ${#missing[@]} -gt 0 ] || return 0
    seed=$(_target_seed_dir)
    mkdir -p "$(dirname "$seed")" "$target"
    (
        flock 9
        for profile in "${missing[@]}"; do
            [ -d "$seed/$profile" ] || continue
            start=$SECONDS
            cp -a --reflink=auto "$seed/$profile" "$target/$profile.part"
            _target_seed_forget_workspace "$target/$profile.part"
            mv "$target/$profile.part" "$target/$profile"
            echo "target-seed: $target/$profile from $seed ($(du -sh "$target/$profile" | cut -f1), $((SECONDS - start)) s)"
        done
    ) 9>"$(dirname "$seed")/.lock"
}

target_seed_save() {
    local target="$1" seed start=$SECONDS profile
    [ "${STICKSLIP_TARGET_SEED:-1}" = 1 ] || return 0
    [ -d "$target/release" ] || return 0
    seed=$(_target_seed_dir)
    mkdir -p "$(dirname "$seed")"
    (
        flock 9
        rm -rf "$seed.part"
        mkdir -p "$seed.part"
        for profile in "${TARGET_SEED_PROFILES[@]}"; do
            [ -d "$target/$profile" ] || continue
            cp -a --reflink=auto "$target/$profile" "$seed.part/$profile"
            _target_seed_forget_workspace "$seed.part/$profile"
        done
        rm -rf "$seed" && mv "$seed.part" "$seed"
        # keep the two newest seeds
        find "$(dirname "$seed")" -mindepth 1 -maxdepth 1 -type d -printf '%T@ %p\n' |
            sort -rn | tail -n +3 | cut -d' ' -f2- | xargs -r rm -rf
        echo "target-seed: saved $(cd "$seed" && echo *) of $target as $seed ($((SECONDS - start)) s)"
    ) 9>"$(dirname "$seed")/.lock"
}
