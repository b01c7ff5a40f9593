#!/usr/bin/env bash
# deploy/runtime-packages.sh - the Debian packages that hold the shared libraries the given
# ELF binaries need directly (their DT_NEEDED entries), one per line, sorted. apt pulls in what
# those libraries need in turn. Used by deploy/Containerfile to install a run-time image with
# no compiler and no -dev packages.
#
#   deploy/runtime-packages.sh /usr/local/bin/seamtexd /usr/local/bin/seamtex
#
# Each needed library is located with ldd and looked up with dpkg -S, under its path and under
# the same path with or without /usr (Debian's merged /usr: ldd may print /lib/... for a file
# dpkg knows as /usr/lib/..., or the other way round). A library no package owns fails the run.
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: $0 ELF..." >&2; exit 2; }
for bin in "$@"; do
    paths=$(ldd "$bin" | awk '/=> \//{print $1, $3}')
    for lib in $(readelf -d "$bin" | sed -n 's/.*Shared library: \[\(.*\)\].*/\1/p'); do
        path=$(awk -v n="$lib" '$1 == n {print $2}' <<<"$paths")
        [ -n "$path" ] || continue              # the dynamic loader itself, vdso
        pkg=""
        for p in "$path" "/usr$path" "${path#/usr}"; do
            pkg=$(dpkg -S "$p" 2>/dev/null | head -1 | cut -d: -f1) && [ -n "$pkg" ] && break
        done
        [ -n "$pkg" ] || { echo "$0: no package owns $path ($bin needs $lib)" >&2; exit 1; }
        echo "$pkg"
    done
done | sort -u
