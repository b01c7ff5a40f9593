#!/usr/bin/env bash
# deploy/install-deps.sh - installs the Debian packages seamtex builds, tests and runs with.
# Idempotent: asks dpkg first and calls apt-get only for what is missing. Needs root (or sudo)
# only when something is missing.
set -euo pipefail

# memcached and redis-server are for `make bench` only: tests/bench/net_ping.sh starts its own
# of each on a free loopback port (no persistence) to measure them beside seamtexd.
# python3-dev builds the Python module (make python), python3-setuptools installs it with pip;
# python3-pytest and python3-numpy are for its tests only (the module itself needs neither).
# libcurl4-openssl-dev and libjson-c-dev: the daemon's and client's etcd v3 JSON gateway client
# (cluster mode); etcd-server / etcd-client: the tests start their own etcd on loopback.
# prometheus gives promtool (tests check /metrics with it); mandoc lints the man pages;
# openimageio-tools gives maketx (the out-of-core benchmark's TextureSystem comparison);
# lintian checks the .deb that `make deb` builds. python3-yaml: make check-deploy parses the
# Kubernetes manifests in deploy/k8s/.
# gnuplot-nox draws the Toth study's Figure 5 from its CSVs (tools/toth-study.sh).
# libdeflate-dev: the .ptx reader's inflate (whole-buffer, about twice zlib's speed).
PKGS=(build-essential clang pkg-config zlib1g-dev libcmocka-dev
      memcached redis-server
      libopenimageio-dev libopenexr-dev libimath-dev libdraco-dev
      python3-dev python3-setuptools python3-pytest python3-numpy
      libcurl4-openssl-dev libjson-c-dev etcd-server etcd-client
      prometheus mandoc openimageio-tools lintian python3-yaml gnuplot-nox
      libdeflate-dev)

missing=()
for p in "${PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# clang's libFuzzer runtime ships in libclang-rt-<ver>-dev; the version follows clang's.
if command -v clang >/dev/null 2>&1; then
    cv=$(clang -dumpversion | cut -d. -f1)
    dpkg-query -W -f='${Status}' "libclang-rt-$cv-dev" 2>/dev/null | grep -q "install ok installed" \
        || missing+=("libclang-rt-$cv-dev")
fi

[ ${#missing[@]} -eq 0 ] && exit 0

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
# a fresh clang may have pulled a newer runtime version: check once more
if command -v clang >/dev/null 2>&1; then
    cv=$(clang -dumpversion | cut -d. -f1)
    dpkg-query -W -f='${Status}' "libclang-rt-$cv-dev" 2>/dev/null | grep -q "install ok installed" \
        || $SUDO apt-get install -y -qq --no-install-recommends "libclang-rt-$cv-dev" >/dev/null
fi
