#!/usr/bin/env bash
# scripts/mingw-link.sh -- the linker of the x86_64-pc-windows-gnu builds
# (CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER, set by scripts/win64.sh):
# x86_64-w64-mingw32-gcc, except that the export list rustc writes for a
# cdylib (`list.def`) is cut to the fmi2 functions.
#
# Why: rustc exports every `#[no_mangle]` function of every crate it links, so
# fmi-sys's `callback_log` lands in the DLL's export table. On Linux build.rs
# hides it with `-Wl,--exclude-libs,ALL`; GNU ld for PE applies that (and
# --exclude-symbols) only to automatic exports, never to a .def file's.
set -euo pipefail
args=()
for a in "$@"; do
    case "$a" in
        *.def) # passed as `-Wl,<dir>/list.def`
            def="${a#-Wl,}"
            cut="${def%.def}.fmi2.def"
            { echo EXPORTS; grep -E '^[[:space:]]*"?fmi2' "$def" || true; } >"$cut"
            args+=("${a%"$def"}$cut")
            ;;
        *) args+=("$a") ;;
    esac
done
exec x86_64-w64-mingw32-gcc "${args[@]}"
