#!/usr/bin/env bash
# deploy/build-deb.sh - builds the Debian package seamtex_<version>_<arch>.deb (make deb).
#
# Owns: the package's metadata and maintainer scripts. The files come from the Makefile's own
# `make install DESTDIR=<staging> PREFIX=/usr` (binaries, libseamtex.a, header, seamtex.pc,
# man pages, systemd unit, example config and /etc/seamtex/seamtexd.conf); this script only
# adds what Debian asks of a package: stripped binaries, gzipped man pages and changelog, a
# copyright file, DEBIAN/control with Depends computed by dpkg-shlibdeps (written out from
# the link libraries if dpkg-shlibdeps fails), conffiles, postinst (a system user `seamtex`,
# /var/lib/seamtex and /etc/seamtex/token, each only if missing) and postrm (purge removes
# the generated token; the data dir is left: it holds the users' sets), and the lintian
# overrides (deploy/lintian-overrides, each with its reason).
#
# Environment: B (build dir, default build), DEB_OUT (where the .deb goes, default $B),
# DEB_VERSION (default: the Version of client/seamtex.pc.in), DEB_MAINTAINER (the Maintainer
# field and changelog signature; the project has no mail address yet, so the default's host is
# localhost: see deploy/lintian-overrides). Prints the .deb's path last.
# Never installs anything on this system.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
B=${B:-build}
OUT=${DEB_OUT:-$ROOT/$B}
VERSION=${DEB_VERSION:-$(sed -n 's/^Version: *//p' client/seamtex.pc.in)}
ARCH=$(dpkg --print-architecture)
MULTIARCH=$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch)
MAINTAINER=${DEB_MAINTAINER:-seamtex developers <seamtex@localhost>}
PKG=seamtex

work=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-deb-XXXXXX")
trap 'rm -rf "$work"' EXIT
root=$work/debian/$PKG          # dpkg-shlibdeps expects the package tree under debian/
mkdir -p "$root"

make --no-print-directory -s install DESTDIR="$root" PREFIX=/usr LIBDIR=/usr/lib/$MULTIARCH >/dev/null

# ---- what Debian asks of the files ----------------------------------------------------------
strip --strip-unneeded --remove-section=.comment --remove-section=.note "$root"/usr/bin/*
strip --strip-debug --remove-section=.comment "$root"/usr/lib/"$MULTIARCH"/*.a
find "$root/usr/share/man" -type f -exec gzip -9n {} +
doc=$root/usr/share/doc/$PKG
gzip -9n "$doc/README.md"
cat > "$doc/copyright" <<COPY
Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: seamtex
Comment: Built from the seamtex source tree by deploy/build-deb.sh.

Files: *
Copyright: 2026 the seamtex authors
License: no-license-granted
 No license has been stated for seamtex yet; this package is for internal deployment.
COPY
date=$(date -R -u -d "@${SOURCE_DATE_EPOCH:-$(git log -1 --format=%ct 2>/dev/null || date +%s)}")
printf '%s (%s) unstable; urgency=medium\n\n  * Package built from the seamtex tree (make deb).\n\n -- %s  %s\n' \
    "$PKG" "$VERSION" "$MAINTAINER" "$date" | gzip -9n > "$doc/changelog.gz"
install -D -m 644 deploy/lintian-overrides "$root/usr/share/lintian/overrides/$PKG"

# ---- Depends --------------------------------------------------------------------------------
printf 'Source: %s\n\nPackage: %s\nArchitecture: any\n' "$PKG" "$PKG" > "$work/debian/control"
if deps=$(cd "$work" && dpkg-shlibdeps -O "debian/$PKG/usr/bin/seamtexd" \
              "debian/$PKG/usr/bin/seamtex" "debian/$PKG/usr/bin/seamtex-bench" 2>/dev/null \
          | sed -n 's/^shlibs:Depends=//p') && [ -n "$deps" ]; then
    :
else
    echo "build-deb: dpkg-shlibdeps failed; Depends written out from the link libraries" >&2
    deps="libc6, libstdc++6, libgcc-s1, zlib1g, libopenimageio2.4, libopenexr-3-1-30, libdraco7"
fi
rm "$work/debian/control"

# ---- DEBIAN/ ----------------------------------------------------------------------------------
mkdir -p "$root/DEBIAN"
size=$(du -sk --exclude=DEBIAN "$root" | cut -f1)
cat > "$root/DEBIAN/control" <<CTRL
Package: $PKG
Version: $VERSION
Architecture: $ARCH
Maintainer: $MAINTAINER
Installed-Size: $size
Depends: adduser, $deps
Section: graphics
Priority: optional
Description: texture service with seam-free sampling of Ptex, cube and atlas textures
 seamtex holds per-face (Ptex-style) textures, cube maps and atlas textures in
 memory and samples them without visible seams (Discard, Traverse, Clamp),
 re-encodes them to seam-masked BC1 and serves them from one daemon over a
 binary protocol.
 .
 This package contains the daemon seamtexd with its systemd unit, the
 command-line client seamtex, the load tester seamtex-bench, the client
 library libseamtex (static) with its header and pkg-config file,
 libseamtex_etcd (static: open a cluster from its etcd URL), and the
 manual pages.
CTRL
echo /etc/seamtex/seamtexd.conf > "$root/DEBIAN/conffiles"
cat > "$root/DEBIAN/postinst" <<'POSTINST'
#!/bin/sh
# seamtex postinst: the service's system user, its data dir and its token, each only if missing.
set -e
if [ "$1" = configure ]; then
    if ! getent passwd seamtex >/dev/null; then
        adduser --system --group --home /var/lib/seamtex --no-create-home \
            --gecos "seamtex texture daemon" seamtex
    fi
    if [ ! -d /var/lib/seamtex ]; then
        mkdir -p /var/lib/seamtex
        chown seamtex:seamtex /var/lib/seamtex
        chmod 0750 /var/lib/seamtex
    fi
    if [ ! -e /etc/seamtex/token ]; then
        (umask 077; head -c 32 /dev/urandom | base64 > /etc/seamtex/token)
    fi
fi
exit 0
POSTINST
cat > "$root/DEBIAN/postrm" <<'POSTRM'
#!/bin/sh
# seamtex postrm: purge removes the generated token; /var/lib/seamtex (the users' sets) and the
# system user stay.
set -e
if [ "$1" = purge ]; then
    rm -f /etc/seamtex/token
    rmdir --ignore-fail-on-non-empty /etc/seamtex 2>/dev/null || true
fi
exit 0
POSTRM
# md5sums of every file but the conffiles (dpkg keeps their sums itself)
(cd "$root" && find . -path ./DEBIAN -prune -o -type f -printf '%P\n' | sort \
    | grep -vxF -f <(sed 's|^/||' DEBIAN/conffiles) | tr '\n' '\0' | xargs -0 md5sum) \
    > "$root/DEBIAN/md5sums"
chmod 755 "$root/DEBIAN/postinst" "$root/DEBIAN/postrm"
chmod 644 "$root/DEBIAN/control" "$root/DEBIAN/conffiles" "$root/DEBIAN/md5sums"

mkdir -p "$OUT"
deb=$OUT/${PKG}_${VERSION}_${ARCH}.deb
dpkg-deb --root-owner-group -Zxz --build "$root" "$deb" >/dev/null
echo "$deb"
