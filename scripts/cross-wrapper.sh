# shellcheck shell=bash
# scripts/cross-wrapper.sh -- SOURCED by scripts/win64.sh and scripts/darwin64.sh.
#
#   cross_wrapper NAME   prints the path of scripts/NAME's copy in the cache,
#                        $STICKSLIP_CACHE_DIR/wrappers/<sha256 of NAME, 16 hex>/NAME
#
# The cross builds name their C compiler and linker wrappers (mingw-link.sh,
# darwin-cc.sh, darwin-link.sh) in environment variables, and cargo keeps the
# linker's path in the fingerprint of every unit of the target (std and the
# dependencies included) and the C compiler's in fmi-sys's build script: a
# path inside the clone would make each fresh clone, at another path, build
# all of them again. The copy is named by the script's content, so the path
# is the same in every clone and changes exactly when the script does.
cross_wrapper() {
    local src="$STICKSLIP_ROOT/scripts/$1" dir
    dir="${STICKSLIP_CACHE_DIR:?scripts/env.sh sets STICKSLIP_CACHE_DIR}/wrappers/$(sha256sum "$src" | cut -c1-16)"
    if [ ! -x "$dir/$1" ]; then
        mkdir -p "$dir" && cp "$src" "$dir/$1.tmp$$" && chmod +x "$dir/$1.tmp$$" && mv "$dir/$1.tmp$$" "$dir/$1" || return 1
    fi
    printf '%s\n' "$dir/$1"
}
