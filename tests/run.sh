#!/usr/bin/env bash
# tests/run.sh - runs every test binary and every fuzz target (bounded), then prints one
# closing line "N passed, N failed". Called by `make test`; B names the build dir.
#
# Each cmocka binary reports in TAP; a binary that dies (signal, timeout) without reporting
# every test counts as one more failure. Fuzz targets run FUZZ_SECONDS each on a fresh corpus
# seeded from tests/fuzz/seeds/<target>/ when that folder exists.
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
export SEAMTEX_DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
export SEAMTEX_BUILD=$ROOT/$B
export CMOCKA_MESSAGE_OUTPUT=TAP
FUZZ_SECONDS=${FUZZ_SECONDS:-20}
TEST_TIMEOUT=${TEST_TIMEOUT:-900}
ONLY=${ONLY:-}

[ -d "$SEAMTEX_DATA" ] || echo "note: SEAMTEX_DATA=$SEAMTEX_DATA is missing: tests on shared data will be skipped" >&2

pass=0 fail=0 skip=0
failed_names=()
log_dir=$B/test-logs
mkdir -p "$log_dir"

for t in $(ls "$B"/tests/unit/test_* "$B"/tests/integration/test_* 2>/dev/null | grep -v '\.[od]$'); do
    name=$(basename "$t")
    [ -n "$ONLY" ] && [[ "$name" != *$ONLY* ]] && continue
    log=$log_dir/$name.log
    start=$(date +%s.%N)
    timeout -k 10 "$TEST_TIMEOUT" "$t" >"$log" 2>&1
    rc=$?
    secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
    p=$(grep -cE '^ok [0-9]+' "$log")
    s_ok=$(grep -cE '^ok [0-9]+ .*# SKIP' "$log")
    # cmocka 1.1 reports a skip() as "not ok N # SKIP": a skip, not a failure
    s=$(grep -cE '^(not )?ok [0-9]+ .*# SKIP' "$log")
    f=$(grep -E '^not ok [0-9]+' "$log" | grep -vc '# SKIP')
    p=$((p - s_ok))
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi
    planned=$(grep -oE '^1\.\.[0-9]+' "$log" | head -1 | cut -d. -f3)
    if [ -n "$planned" ] && [ $((p + s + f)) -lt "$planned" ] && [ "$f" -eq 0 ]; then f=1; fi
    pass=$((pass + p)); fail=$((fail + f)); skip=$((skip + s))
    printf '%-40s %4d passed %3d failed %3d skipped  %6ss\n' "$name" "$p" "$f" "$s" "$secs"
    if [ "$f" -ne 0 ]; then
        failed_names+=("$name")
        grep -E '^not ok|ERROR|error:|Assert|FAIL|rc=' "$log" | head -20 | sed 's/^/    /'
        [ "$rc" -ne 0 ] && echo "    (exit status $rc; full log in $log)"
    fi
done

if [ -z "$ONLY" ] || [[ "fuzz" == *$ONLY* ]]; then
for f in $(ls "$B"/fuzz/fuzz_* 2>/dev/null | grep -v '\.[oad]$'); do
    name=$(basename "$f")
    corpus=$(mktemp -d)
    [ -d "tests/fuzz/seeds/$name" ] && cp -r "tests/fuzz/seeds/$name/." "$corpus/"
    log=$log_dir/$name.log
    timeout -k 10 $((FUZZ_SECONDS + 60)) "$f" -max_total_time="$FUZZ_SECONDS" -rss_limit_mb=2048 \
        -artifact_prefix="$log_dir/$name-" "$corpus" >"$log" 2>&1
    rc=$?
    runs=$(grep -oE 'Done [0-9]+ runs' "$log" | grep -oE '[0-9]+' | tail -1)
    rm -rf "$corpus"
    if [ "$rc" -eq 0 ]; then
        pass=$((pass + 1)); printf '%-40s fuzzed %ss, %s runs, no crash\n' "$name" "$FUZZ_SECONDS" "${runs:-?}"
    else
        fail=$((fail + 1)); failed_names+=("$name")
        printf '%-40s FAILED (exit %d), see %s\n' "$name" "$rc" "$log"
        grep -E 'ERROR|SUMMARY' "$log" | head -5 | sed 's/^/    /'
    fi
done
fi

[ ${#failed_names[@]} -gt 0 ] && echo "failed: ${failed_names[*]}"
if [ "$skip" -gt 0 ]; then
    echo "$pass passed, $fail failed, $skip skipped"
else
    echo "$pass passed, $fail failed"
fi
[ "$fail" -eq 0 ]
