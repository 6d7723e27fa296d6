#!/usr/bin/env bash
# scripts/mingw-link.sh -- the linker of the x86_64-pc-windows-gnu builds
# (CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER, set by scripts/win64.sh):
# x86_64-w64-mingw32-gcc, except that the export list rustc writes for a
# cdylib (`list.def`) is cut to the fmi2 functions and the four beyond FMI,
# stickslip_inverse_dynamics, stickslip_joint_torque_regressor,
# stickslip_run_experiment and
# stickslip_write_model (the fmi3 functions only for the FMI 3.0 library, an
# output named *fmi3*).
#
# Why: rustc exports every `#[no_mangle]` function of every crate it links, so
# fmi-sys's `callback_log` lands in the DLL's export table. On Linux build.rs
# hides it with `-Wl,--exclude-libs,ALL`; GNU ld for PE applies that (and
# --exclude-symbols) only to automatic exports, never to a .def file's.
set -euo pipefail
# The FMI version whose functions the DLL exports: the FMI 3.0 library
# (crate fmi3/, stick_slip_manipulator_fmi3.dll) links the FMI 2.0 crate as
# an rlib, whose fmi2 functions would be listed too.
version=fmi2 keep="fmi2|stickslip_inverse_dynamics|stickslip_joint_torque_regressor|stickslip_run_experiment|stickslip_write_model"
prev=""
for a in "$@"; do
    if [ "$prev" = -o ]; then
        case "$(basename "$a")" in *fmi3*) version=fmi3 keep=fmi3 ;; esac
    fi
    prev="$a"
done
args=()
for a in "$@"; do
    case "$a" in
        *.def) # passed as `-Wl,<dir>/list.def`
            def="${a#-Wl,}"
            cut="${def%.def}.$version.def"
            { echo EXPORTS; grep -E "^[[:space:]]*\"?($keep)" "$def" || true; } >"$cut"
            args+=("${a%"$def"}$cut")
            ;;
        *) args+=("$a") ;;
    esac
done
exec x86_64-w64-mingw32-gcc "${args[@]}"
