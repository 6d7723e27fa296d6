#!/usr/bin/env bash
# scripts/darwin-cc.sh -- the C compiler of the darwin64 builds
# (CC_x86_64_apple_darwin, CC_aarch64_apple_darwin, set by scripts/darwin64.sh):
# `zig cc`, which carries the macOS headers, for the architecture and minimum
# macOS the cc crate asks for in clang's terms (`--target=arm64-apple-macosx`,
# `-arch arm64`, `-mmacosx-version-min=11.0`), given to zig as its own
# `-target aarch64-macos.11.0` (the minimum: DARWIN64_MIN_MACOS_ARM64 or
# _X86_64 when set, see the end). Only fmi-sys's logger.c is compiled with it.
set -euo pipefail
arch="" min="${MACOSX_DEPLOYMENT_TARGET:-}" args=() skip=0
for a in "$@"; do
    if [ "$skip" = arch ]; then arch="$a"; skip=0; continue; fi
    if [ "$skip" = drop ]; then skip=0; continue; fi
    case "$a" in
        -arch) skip=arch ;;
        -isysroot) skip=drop ;;      # SDKROOT (for rustc): zig has its own headers
        --target=*) arch="${a#--target=}"; arch="${arch%%-*}" ;;
        -mmacosx-version-min=*) min="${a#-mmacosx-version-min=}" ;;
        *) args+=("$a") ;;
    esac
done
case "$arch" in
    arm64 | aarch64 | arm64-*) arch=aarch64 ;;
    x86_64 | x86_64-*) arch=x86_64 ;;
    "") # a probe without a target (the cc crate's `--version`): any will do
        arch=x86_64 ;;
    *) echo "darwin-cc.sh: unknown architecture '$arch'" >&2; exit 2 ;;
esac
# The architecture's own minimum macOS (scripts/darwin64.sh): both targets
# build in one cargo run under one MACOSX_DEPLOYMENT_TARGET, x86_64's 10.13.
case "$arch" in
    aarch64) min="${DARWIN64_MIN_MACOS_ARM64:-$min}" ;;
    x86_64) min="${DARWIN64_MIN_MACOS_X86_64:-$min}" ;;
esac
exec "${DARWIN64_ZIG:?scripts/darwin64.sh sets DARWIN64_ZIG}" cc -target "$arch-macos${min:+.$min}" ${args[@]+"${args[@]}"}
