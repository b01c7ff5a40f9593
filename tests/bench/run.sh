#!/usr/bin/env bash
# tests/bench/run.sh - runs every benchmark binary (build/bench/bench_*) and every
# tests/bench/net_*.sh script; each prints its table and writes build/bench/<name>.json.
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT"
export SEAMTEX_DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
export SEAMTEX_BUILD=$ROOT/$B
export BENCH_OUT=$ROOT/$B/bench
mkdir -p "$BENCH_OUT"
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%FT%TZ)"
rc=0
for b in $(ls "$B"/bench/bench_* 2>/dev/null | grep -v '\.[od]$\|\.json$'); do
    name=$(basename "$b")
    [ -n "${ONLY:-}" ] && [[ "$name" != *$ONLY* ]] && continue
    echo "== $name"
    "$b" --json "$BENCH_OUT/$name.json" || { echo "$name failed"; rc=1; }
done
for s in tests/bench/net_*.sh; do
    [ -f "$s" ] || continue
    name=$(basename "$s" .sh)
    [ -n "${ONLY:-}" ] && [[ "$name" != *$ONLY* ]] && continue
    echo "== $name"
    bash "$s" "$BENCH_OUT/$name.json" || { echo "$name failed"; rc=1; }
done
exit $rc
