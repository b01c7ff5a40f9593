#!/usr/bin/env bash
# tests/check-deb.sh - the Debian package, end to end, without touching this system (make
# check-deb, run by make test):
#   1. deploy/build-deb.sh builds it into a scratch dir;
#   2. `dpkg-deb --contents` lists every expected file (programs, library, header, pkg-config
#      file, the five man pages, unit, config as a conffile, copyright) and the control file
#      has Depends, conffiles, postinst and postrm;
#   3. lintian: no error or warning left (the tags kept are overridden with reasons in
#      deploy/lintian-overrides);
#   4. `dpkg --root=<tmp> --force-not-root --force-depends --unpack` (the maintainer scripts
#      are not run: run chrootless they would add a user to this system; they are checked
#      with sh -n above), else `dpkg-deb -x`, into a scratch root; the unpacked
#      seamtex, seamtexd and seamtex-bench run --help, and a program compiled with the
#      extracted seamtex.pc against the extracted header and libseamtex.a links.
# Bounded: lintian gets LINTIAN_TIMEOUT seconds (default 600). Exit 0 or 1 with reasons.
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
B=${B:-build}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-checkdeb-XXXXXX")
trap 'rm -rf "$tmp"' EXIT
bad=0
fail() { echo "check-deb: $*"; bad=1; }

deb=$(B=$B DEB_OUT=$tmp bash deploy/build-deb.sh | tail -1)
[ -f "$deb" ] || { echo "check-deb: deploy/build-deb.sh made no package"; exit 1; }
echo "check-deb: built $(basename "$deb") ($(stat -c %s "$deb") bytes)"

# ---- 2. contents and control
multi=$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch)
list=$(dpkg-deb --contents "$deb" | awk '{print $NF}' | sed 's|^\./|/|')
for f in /usr/bin/seamtexd /usr/bin/seamtex /usr/bin/seamtex-bench /usr/bin/seamtex-render \
         "/usr/lib/$multi/libseamtex.a" "/usr/lib/$multi/pkgconfig/seamtex.pc" \
         /usr/include/seamtex/seamtex.h /usr/include/seamtex/seamtex_cluster.h \
         "/usr/lib/$multi/libseamtex_etcd.a" "/usr/lib/$multi/pkgconfig/seamtex-etcd.pc" \
         /usr/include/seamtex/seamtex_etcd.h \
         /usr/share/man/man1/seamtex.1.gz /usr/share/man/man1/seamtex-bench.1.gz \
         /usr/share/man/man1/seamtex-render.1.gz \
         /usr/share/man/man3/libseamtex.3.gz /usr/share/man/man3/seamtex-python.3.gz \
         /usr/share/man/man8/seamtexd.8.gz \
         /lib/systemd/system/seamtexd.service /etc/seamtex/seamtexd.conf \
         /usr/share/doc/seamtex/copyright /usr/share/doc/seamtex/changelog.gz \
         /usr/share/doc/seamtex/examples/seamtexd.conf.example; do
    grep -qxF "$f" <<<"$list" || fail "the package lacks $f"
done
ctl=$tmp/control
dpkg-deb -e "$deb" "$ctl"
grep -q '^Depends: .*libc6' "$ctl/control" || fail "Depends does not name libc6: $(grep ^Depends "$ctl/control")"
grep -qxF /etc/seamtex/seamtexd.conf "$ctl/conffiles" || fail "the config is not a conffile"
for s in postinst postrm; do
    [ -x "$ctl/$s" ] || fail "no executable $s"
    sh -n "$ctl/$s" || fail "$s does not parse"
done

# ---- 3. lintian
if command -v lintian >/dev/null; then
    lint=$(timeout "${LINTIAN_TIMEOUT:-600}" lintian --show-overrides --tag-display-limit 0 "$deb" 2>&1)
    rc=$?
    [ $rc -eq 124 ] && fail "lintian did not finish in ${LINTIAN_TIMEOUT:-600} s"
    tags=$(grep -E '^[EW]: ' <<<"$lint")
    if [ -n "$tags" ]; then
        fail "lintian reports (fix, or override with a reason in deploy/lintian-overrides):"
        echo "$tags" | sed 's/^/    /'
    else
        echo "check-deb: lintian: no error or warning ($(grep -c '^O: ' <<<"$lint") tags overridden, see deploy/lintian-overrides)"
    fi
else
    fail "lintian is not installed (deploy/install-deps.sh installs it)"
fi

# ---- 4. into a scratch root
sroot=$tmp/root
mkdir -p "$sroot/var/lib/dpkg/updates" "$sroot/var/lib/dpkg/info"
touch "$sroot/var/lib/dpkg/status"
how="dpkg --root --unpack"
if ! dpkg --root="$sroot" --force-not-root --force-depends --no-triggers --unpack "$deb" \
        >"$tmp/dpkg.log" 2>&1; then
    how="dpkg-deb -x (dpkg --root --unpack failed: $(tail -1 "$tmp/dpkg.log"))"
    rm -rf "$sroot" && mkdir -p "$sroot"
    dpkg-deb -x "$deb" "$sroot"
else
    dpkg --root="$sroot" -L seamtex >/dev/null 2>&1 || fail "dpkg --root does not list the unpacked package"
fi
for p in seamtexd seamtex seamtex-bench; do
    out=$("$sroot/usr/bin/$p" --help 2>&1) || fail "the unpacked $p --help exits $?"
    grep -q "usage: $p" <<<"$out" || grep -q "^$p - " <<<"$out" || fail "the unpacked $p --help printed no usage"
done
cat > "$tmp/hello.c" <<'C'
#include <seamtex.h>
#include <stdio.h>
int main(void) { printf("%s\n", stc_strerror(STC_ENOTFOUND)); return 0; }
C
pc=$sroot/usr/lib/$multi/pkgconfig
flags=$(PKG_CONFIG_PATH=$pc PKG_CONFIG_SYSROOT_DIR=$sroot pkg-config --cflags --libs seamtex 2>&1) \
    || fail "pkg-config seamtex: $flags"
if cc -o "$tmp/hello" "$tmp/hello.c" $flags -lpthread >"$tmp/cc.log" 2>&1; then
    [ "$("$tmp/hello")" = NOT_FOUND ] || fail "a program linked with the packaged libseamtex printed '$("$tmp/hello")'"
else
    fail "a program does not build with the packaged header, seamtex.pc and libseamtex.a:"; sed 's/^/    /' "$tmp/cc.log"
fi
[ $bad -eq 0 ] && echo "check-deb: contents, control, lintian and the unpacked programs ($how) are right"
exit $bad
