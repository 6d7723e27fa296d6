# shellcheck shell=bash
# scripts/env.sh -- project environment. SOURCE it (the other scripts do):
#
#     source scripts/env.sh
#
# What it guarantees afterwards (idempotent; the warm path does no installs):
#   * libclang (needed by bindgen, which the `fmi-sys` crate runs at build time)
#     is installed: Debian package `libclang-dev` via apt-get when missing;
#     LIBCLANG_PATH is exported pointing at the directory holding libclang.so.
#   * a Python venv at $STICKSLIP_VENV (default: <repo>/.venv) exists and has
#     requirements.txt installed; it is re-installed only when requirements.txt
#     changes (sha256 stamp kept in the venv). uv (pinned in
#     scripts/uv-requirements.txt, in a venv of its own in the cache) makes it
#     from the wheels in its cache, $STICKSLIP_CACHE_DIR/uv. Its bin/ is first on PATH, so
#     `python` and `pytest` are the venv's.
#   * the package `stickslip` of pyproject.toml (python/stickslip, command
#     `stickslip`) is installed into the venv in editable mode; re-installed
#     only when pyproject.toml changes (stamp kept in the venv).
#   * only with STICKSLIP_WIN64=1 (scripts/build_fmu.sh sets it when it builds
#     win64; scripts/test.sh's full run sets it): the Debian packages of the
#     win64 cross-build and its wine tests (apt-get when missing): rustc-web,
#     cargo-web, rust-web-src, gcc-mingw-w64-x86-64, wine64, wine (see
#     _stickslip_ensure_win64_packages; about 350 MB to download).
#   * only with STICKSLIP_DARWIN64=1 (scripts/build_fmu.sh sets it when it
#     builds darwin64, which it does by default): Debian's llvm-14 and the PyPI
#     package `ziglang` in a venv of its own (see _stickslip_ensure_darwin64).
#   * the host builds compile through sccache (Debian package; RUSTC_WRAPPER,
#     cache in $STICKSLIP_CACHE_DIR/sccache; see _stickslip_ensure_sccache).
#   * MPLBACKEND=Agg (headless plotting), STICKSLIP_ROOT=<repo root>,
#     STICKSLIP_CACHE_DIR (default ~/.cache/stickslip): the caches outside the clone.
#
# Safe for `set -euo pipefail` callers, CI=true and no stdin. On failure it
# prints the reason and returns non-zero (so a `set -e` caller stops).
# Running it as `bash scripts/env.sh` performs the installs (exports are lost).
#
# Knobs: STICKSLIP_VENV (venv dir), PYTHON (base interpreter, default python3),
#        STICKSLIP_SKIP_APT=1 (never call apt-get; just warn if packages are missing).

_stickslip_log() { printf 'env.sh: %s\n' "$*" >&2; }

_stickslip_find_libclang_dir() {
    # Prints a directory containing an unversioned libclang.so / libclang-N.so
    # (what clang-sys/bindgen looks for). libclang-cpp.so is NOT libclang.
    local d f
    if [ -n "${LIBCLANG_PATH:-}" ]; then
        for f in "$LIBCLANG_PATH"/libclang.so "$LIBCLANG_PATH"/libclang-*.so; do
            case "$f" in *libclang-cpp*) continue ;; esac
            if [ -e "$f" ]; then printf '%s\n' "$LIBCLANG_PATH"; return 0; fi
        done
    fi
    # Debian: /usr/lib/llvm-N/lib/libclang.so (from libclang-N-dev); newest first.
    for d in $(ls -d /usr/lib/llvm-*/lib 2>/dev/null | sort -t- -k2 -V -r); do
        if [ -e "$d/libclang.so" ]; then printf '%s\n' "$d"; return 0; fi
    done
    for d in /usr/lib/x86_64-linux-gnu /usr/lib/aarch64-linux-gnu /usr/lib64 /usr/lib /usr/local/lib; do
        for f in "$d"/libclang.so "$d"/libclang-[0-9]*.so; do
            if [ -e "$f" ]; then printf '%s\n' "$d"; return 0; fi
        done
    done
    return 1
}

_stickslip_apt_install() {
    # apt-get install of the Debian packages given (as root, or through sudo -n).
    local sudo=""
    if ! command -v apt-get >/dev/null 2>&1; then
        _stickslip_log "ERROR: apt-get unavailable; install the Debian packages $* by other means"
        return 1
    fi
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null 2>&1; then
            sudo="sudo -n"
        else
            _stickslip_log "ERROR: not root and no sudo: run 'apt-get install $*' as root"
            return 1
        fi
    fi
    _stickslip_log "installing Debian packages $* (apt-get)..."
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -q </dev/null >&2 || {
        _stickslip_log "ERROR: apt-get update failed"; return 1; }
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "$@" </dev/null >&2 || {
        _stickslip_log "ERROR: apt-get install $* failed"; return 1; }
}

_stickslip_ensure_win64_packages() {
    # The win64 cross-build and its tests (scripts/win64.sh, docs/platforms.md):
    #   rustc-web, cargo-web   Debian's Rust (/usr/bin/rustc, /usr/bin/cargo),
    #                          which may build std itself (-Zbuild-std)
    #   rust-web-src           the sources of that std
    #   gcc-mingw-w64-x86-64   the Windows linker and C runtime (mingw-w64)
    #   wine64, wine           runs the Windows test programs (scripts/test.sh)
    local pkgs="rustc-web cargo-web rust-web-src gcc-mingw-w64-x86-64 wine64 wine" missing
    [ "${STICKSLIP_WIN64:-0}" = 1 ] || return 0
    missing=$(dpkg-query -W -f='${Status} ${Package}\n' $pkgs 2>/dev/null |
        awk '$3 == "installed" {ok[$4] = 1} END {n = split("'"$pkgs"'", p, " "); for (i = 1; i <= n; i++) if (!ok[p[i]]) printf "%s ", p[i]}')
    [ -z "$missing" ] && return 0
    if [ "${STICKSLIP_SKIP_APT:-0}" = 1 ]; then
        _stickslip_log "WARNING: missing $missing and STICKSLIP_SKIP_APT=1; the win64 build and tests will fail"
        return 0
    fi
    # shellcheck disable=SC2086
    _stickslip_apt_install $missing || return 1
}

_stickslip_ensure_sccache() {
    # The compiler cache of the host builds (Debian's package sccache): every
    # clone's `cargo` compiles through it (RUSTC_WRAPPER), so a fresh clone
    # takes its dependencies' compiled crates from $STICKSLIP_CACHE_DIR/sccache
    # instead of compiling them again. Its key is the content (the compiler's
    # binary, the arguments, the environment cargo sets, every source file the
    # crate reads), so it cannot hand out a stale build; crates it cannot cache
    # (the project's own cdylib, binaries, test harnesses) are simply compiled.
    # STICKSLIP_SCCACHE=0, or a RUSTC_WRAPPER of your own, leaves it out.
    [ "${STICKSLIP_SCCACHE:-1}" = 1 ] && [ -z "${RUSTC_WRAPPER:-}" ] || return 0
    if ! command -v sccache >/dev/null 2>&1; then
        if [ "${STICKSLIP_SKIP_APT:-0}" = 1 ]; then
            _stickslip_log "WARNING: sccache missing and STICKSLIP_SKIP_APT=1; compiling without the cache"
            return 0
        fi
        _stickslip_apt_install sccache || return 1
    fi
    export RUSTC_WRAPPER=sccache SCCACHE_DIR="${SCCACHE_DIR:-$STICKSLIP_CACHE_DIR/sccache}"
    export SCCACHE_CACHE_SIZE="${SCCACHE_CACHE_SIZE:-10G}"
}

_stickslip_ensure_darwin64() {
    # Only when the darwin64 binary is to be built (STICKSLIP_DARWIN64=1, set by
    # scripts/build_fmu.sh when darwin64 is among its platforms, the default);
    # sourced without it (scripts/test.sh's first stages, STICKSLIP_DARWIN64=0)
    # it installs nothing of it. See scripts/darwin64.sh:
    #   llvm-14                Debian's LLVM tools: llvm-lipo (the universal
    #                          file), llvm-objdump, llvm-nm (the checks)
    #   lld-19                 ld64.lld, only if the rustup toolchain has no rust-lld
    #   ziglang (PyPI)         zig cc and the macOS libSystem stubs, pinned in
    #                          scripts/darwin64-requirements.txt, in a venv of
    #                          its own: $STICKSLIP_ZIG_VENV, default
    #                          <target>/darwin64/zig-venv (re-installed when
    #                          that file changes)
    local root="$1" venv req want have="" py
    [ "${STICKSLIP_DARWIN64:-0}" = 1 ] || return 0
    if ! command -v llvm-lipo-14 >/dev/null 2>&1 && ! command -v llvm-lipo >/dev/null 2>&1; then
        if [ "${STICKSLIP_SKIP_APT:-0}" = 1 ]; then
            _stickslip_log "WARNING: llvm-lipo missing and STICKSLIP_SKIP_APT=1; the darwin64 build will fail"
        else
            _stickslip_apt_install llvm-14 || return 1
        fi
    fi
    # The Mach-O linker: rustup's rust-lld (rustc's own component), else Debian's lld-19.
    if ! { command -v rustc >/dev/null 2>&1 && [ -x "$(rustc --print sysroot 2>/dev/null)/lib/rustlib/$(rustc -vV 2>/dev/null | sed -n 's/^host: //p')/bin/rust-lld" ]; } &&
        ! command -v ld64.lld >/dev/null 2>&1 && ! command -v ld64.lld-19 >/dev/null 2>&1; then
        if [ "${STICKSLIP_SKIP_APT:-0}" = 1 ]; then
            _stickslip_log "WARNING: no ld64.lld and STICKSLIP_SKIP_APT=1; the darwin64 build will fail"
        else
            _stickslip_apt_install lld-19 || return 1
        fi
    fi
    venv="${STICKSLIP_ZIG_VENV:-$STICKSLIP_CACHE_DIR/darwin64/zig-venv}"
    req="$root/scripts/darwin64-requirements.txt"
    py="${PYTHON:-python3}"
    want=$(sha256sum "$req" | cut -d' ' -f1) || return 1
    [ -f "$venv/.requirements.sha256" ] && have=$(cat "$venv/.requirements.sha256")
    [ "$want" = "$have" ] && [ -x "$venv/bin/python" ] && return 0
    _stickslip_log "installing the darwin64 toolchain ($(grep -v '^#' "$req" | tr '\n' ' ')) into $venv..."
    if [ ! -x "$venv/bin/python" ]; then
        rm -rf "$venv"
        "$py" -m venv "$venv" </dev/null >&2 || { _stickslip_log "ERROR: '$py -m venv $venv' failed"; return 1; }
    fi
    PIP_DISABLE_PIP_VERSION_CHECK=1 "$venv/bin/python" -m pip install -q --no-input -r "$req" </dev/null >&2 || {
        _stickslip_log "ERROR: pip install -r $req failed"; return 1; }
    printf '%s\n' "$want" >"$venv/.requirements.sha256"
}

_stickslip_ensure_libclang() {
    local dir
    if dir=$(_stickslip_find_libclang_dir); then
        export LIBCLANG_PATH="$dir"
        return 0
    fi
    if [ "${STICKSLIP_SKIP_APT:-0}" = 1 ]; then
        _stickslip_log "WARNING: libclang not found and STICKSLIP_SKIP_APT=1; bindgen (fmi-sys) will fail"
        return 0
    fi
    _stickslip_log "libclang not found"
    _stickslip_apt_install libclang-dev || return 1
    if dir=$(_stickslip_find_libclang_dir); then
        export LIBCLANG_PATH="$dir"
        _stickslip_log "libclang installed; LIBCLANG_PATH=$dir"
        return 0
    fi
    _stickslip_log "ERROR: libclang-dev installed but no libclang.so found"
    return 1
}

_stickslip_ensure_uv() {
    # uv (PyPI, pinned in scripts/uv-requirements.txt) installs the venvs: it
    # keeps each wheel once, unpacked, in its cache ($STICKSLIP_CACHE_DIR/uv,
    # keyed by the wheel's name, version and hash) and links or copies it into
    # a new venv, so a fresh clone's .venv takes 2 s instead of pip's 90 s of
    # unpacking. uv itself lives in a venv of its own in the cache, made again
    # when that file changes. Prints the uv binary.
    local root="$1" boot req want have="" py
    py="${PYTHON:-python3}"
    req="$root/scripts/uv-requirements.txt"
    want=$(cat "$req" | sha256sum | cut -c1-16) || return 1
    boot="$STICKSLIP_CACHE_DIR/uv-$want"
    [ -f "$boot/.ready" ] && [ -x "$boot/bin/uv" ] && { printf '%s\n' "$boot/bin/uv"; return 0; }
    _stickslip_log "installing uv ($(grep -v '^#' "$req" | tr '\n' ' ')) into $boot..."
    rm -rf "$boot"
    "$py" -m venv "$boot" </dev/null >&2 || { _stickslip_log "ERROR: '$py -m venv $boot' failed"; return 1; }
    PIP_DISABLE_PIP_VERSION_CHECK=1 "$boot/bin/python" -m pip install -q --no-input -r "$req" </dev/null >&2 || {
        _stickslip_log "ERROR: pip install -r $req failed"; return 1; }
    touch "$boot/.ready"
    printf '%s\n' "$boot/bin/uv"
}

_stickslip_ensure_venv() {
    local root="$1" venv="$2" req="$1/requirements.txt" py want have="" uv
    py="${PYTHON:-python3}"
    uv=$(_stickslip_ensure_uv "$root") || return 1
    export UV_CACHE_DIR="${UV_CACHE_DIR:-$STICKSLIP_CACHE_DIR/uv}"
    # -x follows the symlink: a venv whose base interpreter vanished is rebuilt.
    if [ ! -x "$venv/bin/python" ]; then
        if ! command -v "$py" >/dev/null 2>&1; then
            _stickslip_log "ERROR: base interpreter '$py' not found (set PYTHON=...)"; return 1
        fi
        _stickslip_log "creating Python venv at $venv (with $("$py" --version 2>&1))..."
        rm -rf "$venv"
        "$uv" venv -q --python "$(command -v "$py")" "$venv" </dev/null >&2 || {
            _stickslip_log "ERROR: 'uv venv $venv' failed"; return 1; }
    fi
    [ -f "$req" ] || return 0
    want=$(sha256sum "$req" | cut -d' ' -f1) || return 1
    [ -f "$venv/.requirements.sha256" ] && have=$(cat "$venv/.requirements.sha256")
    if [ "$want" != "$have" ]; then
        _stickslip_log "installing requirements.txt into $venv (changed since last install)..."
        VIRTUAL_ENV="$venv" "$uv" pip install -q -r "$req" </dev/null >&2 || {
            _stickslip_log "ERROR: uv pip install -r requirements.txt failed"; return 1; }
        printf '%s\n' "$want" >"$venv/.requirements.sha256"
    fi
    [ -f "$root/pyproject.toml" ] || return 0
    want="$(sha256sum "$root/pyproject.toml" | cut -d' ' -f1) $root"
    have=""
    [ -f "$venv/.package.sha256" ] && have=$(cat "$venv/.package.sha256")
    if [ "$want" != "$have" ] || [ ! -x "$venv/bin/stickslip" ]; then
        _stickslip_log "installing the stickslip package (editable) into $venv..."
        VIRTUAL_ENV="$venv" "$uv" pip install -q --no-build-isolation --no-deps -e "$root" </dev/null >&2 || {
            _stickslip_log "ERROR: uv pip install -e $root failed"; return 1; }
        printf '%s\n' "$want" >"$venv/.package.sha256"
    fi
    return 0
}

_stickslip_env_main() {
    local root venv
    root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd) || return 1
    export STICKSLIP_ROOT="$root"
    # The machine's build caches, outside every clone and shared by them
    # (docs/verification.md, "Caches"): the cross builds' cargo target dir,
    # the wine prefix, the darwin64 toolchain. Each is invalidated by content
    # (scripts/win64.sh, scripts/darwin64.sh say how); deleting the directory
    # is always safe.
    export STICKSLIP_CACHE_DIR="${STICKSLIP_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/stickslip}"
    mkdir -p "$STICKSLIP_CACHE_DIR" || return 1
    venv="${STICKSLIP_VENV:-$root/.venv}"

    # cargo from rustup when the caller's PATH lacks it (e.g. a bare CI shell).
    if ! command -v cargo >/dev/null 2>&1 && [ -x "$HOME/.cargo/bin/cargo" ]; then
        export PATH="$HOME/.cargo/bin:$PATH"
    fi

    # NB: functions called in a `||` list run with `set -e` disabled, hence the
    # explicit `|| return 1` on every step inside them.
    _stickslip_ensure_libclang || return 1
    _stickslip_ensure_sccache || return 1
    _stickslip_ensure_win64_packages || return 1
    _stickslip_ensure_venv "$root" "$venv" || return 1
    _stickslip_ensure_darwin64 "$root" || return 1

    export VIRTUAL_ENV="$venv"
    case ":$PATH:" in
        *":$venv/bin:"*) ;;
        *) export PATH="$venv/bin:$PATH" ;;
    esac
    export MPLBACKEND="${MPLBACKEND:-Agg}"
    # Compiled bytecode, kept in the venv: every Python process of the tests and the main
    # job (the stickslip commands, pytest's workers, Dask's scheduler and workers) imports
    # dask, pandas, scipy and matplotlib, which takes 7.5 s from source and 2.4 s from
    # bytecode (measured). A machine that sets PYTHONDONTWRITEBYTECODE (this one does)
    # would otherwise compile them again in each process. The .pyc files go under
    # $venv/pycache, never beside the clone's sources, and Python checks each against its
    # source's mtime and size, so that an edited module is compiled again.
    unset PYTHONDONTWRITEBYTECODE
    export PYTHONPYCACHEPREFIX="$venv/pycache"
    return 0
}

if _stickslip_env_main; then
    _stickslip_env_rc=0
else
    _stickslip_env_rc=1
    _stickslip_log "environment setup FAILED"
fi
unset -f _stickslip_env_main _stickslip_ensure_uv _stickslip_ensure_sccache _stickslip_ensure_darwin64 _stickslip_ensure_venv _stickslip_ensure_libclang _stickslip_ensure_win64_packages _stickslip_apt_install _stickslip_find_libclang_dir _stickslip_log
# `return` when sourced, `exit` when run as a script.
if [ "$_stickslip_env_rc" -eq 0 ]; then
    unset _stickslip_env_rc
    return 0 2>/dev/null || exit 0
else
    unset _stickslip_env_rc
    return 1 2>/dev/null || exit 1
fi
