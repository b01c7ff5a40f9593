#!/usr/bin/env bash
# tests/run.sh - runs every test binary and every fuzz target (a bounded slice) in parallel,
# then prints one line per binary and the closing line "N passed, N failed" (", N skipped"
# follows when tests were skipped). Called by `make test` (and by `make fuzz` / `make soak`
# with MODE=fuzz / MODE=soak); B names the build dir.
#
# Jobs: every $B/tests/unit/test_* and $B/tests/integration/test_* binary (new files are picked
# up by themselves) plus every $B/fuzz/fuzz_* target, run by a pool of TEST_JOBS workers
# (default nproc + 2: the integration tests mostly wait on sockets and daemons). Longest jobs
# start first: the order comes from the durations of the last run ($B/test-logs/durations),
# with fixed guesses for jobs never run. Each job writes its own log in $B/test-logs/; the
# summary is printed in a fixed order (integration, unit, fuzz) once all are done. Ports are 0
# and every daemon and scratch dir is a fresh mkdtemp, so jobs do not collide.
#
# Each cmocka binary reports in TAP; a binary that dies (signal, timeout) without reporting
# every test counts as one more failure.
#
# The Python module's tests (python/tests, pytest under Debian's /usr/bin/python3, importing
# the module from $B/python) are one more job, "pytest_python", when `make python` built it:
# its "N passed" / "N failed" / "N error" / "N skipped" counts go into the totals, and an exit
# status other than 0 with no failure counted (no tests collected = 5, interrupted, crashed)
# counts as one failure. PYTHON3 overrides the interpreter.
#
# Fuzz targets run FUZZ_SECONDS each (default 8 in make test) on a corpus seeded from
# tests/fuzz/seeds/<target>/: a fresh temp copy, thrown away after, except with
# FUZZ_CORPUS_DIR set (make fuzz: $B/fuzz-corpus/<target>/, kept from one campaign to the next).
# tests/fuzz/<target>.flags, when present, holds extra libFuzzer flags for that target (one
# line, e.g. "-max_len=4096" for the slow OpenImageIO target).
#
# Environment: ONLY=substr (run only the jobs whose name contains it; "fuzz" matches every fuzz
# target), TEST_TIMEOUT (seconds per binary, default 900), TEST_JOBS, FUZZ_SECONDS,
# FUZZ_CORPUS_DIR, MODE=test|fuzz|soak|tsan (fuzz: fuzz targets only; soak: test_durability and
# test_cluster_soak only, with SEAMTEX_SOAK_ROUNDS / SEAMTEX_SOAK_SECONDS passed through (make
# test runs a short slice of both); tsan: the integration tests, TSAN_OPTIONS set to
# tests/tsan.supp and per-process report files, any report fails).
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
export SEAMTEX_DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
export SEAMTEX_BUILD=$ROOT/$B
export CMOCKA_MESSAGE_OUTPUT=TAP
MODE=${MODE:-test}
FUZZ_SECONDS=${FUZZ_SECONDS:-8}
TEST_TIMEOUT=${TEST_TIMEOUT:-900}
ONLY=${ONLY:-}
NPROC=$(nproc 2>/dev/null || echo 2)
TEST_JOBS=${TEST_JOBS:-$((NPROC + 2))}
FUZZ_CORPUS_DIR=${FUZZ_CORPUS_DIR:-}

[ -d "$SEAMTEX_DATA" ] || echo "note: SEAMTEX_DATA=$SEAMTEX_DATA is missing: tests on shared data will be skipped" >&2

log_dir=$B/test-logs
mkdir -p "$log_dir"
durations=$log_dir/durations

# ---- the job list --------------------------------------------------------------------------
jobs=()      # "kind path" in summary order
if [ "$MODE" != fuzz ]; then
    for t in $(ls "$B"/tests/integration/test_* "$B"/tests/unit/test_* 2>/dev/null | grep -v '\.[od]$'); do
        name=$(basename "$t")
        # a binary whose source is gone (renamed or split) is a leftover of an old build
        src=tests/$(basename "$(dirname "$t")")/$name.c
        [ -f "$src" ] || { echo "note: $t has no $src: not run (stale build)" >&2; continue; }
        [ "$MODE" = soak ] && [ "$name" != test_durability ] && [ "$name" != test_cluster_soak ] && continue
        # the cluster soak: 20 rounds in make soak, a bounded slice of 3 in make test
        # (SEAMTEX_SOAK_ROUNDS overrides both); tsan leaves it out (test_cluster covers it)
        [ "$MODE" = tsan ] && [ "$name" = test_cluster_soak ] && continue
        [ "$MODE" = tsan ] && [ "$(basename "$(dirname "$t")")" != integration ] && continue
        # the fault-injection daemon tests interpose libc through LD_PRELOAD, which does not
        # mix with ThreadSanitizer's own interceptors: they run in make test and make asan
        [ "$MODE" = tsan ] && [[ "$name" == test_faults_* ]] && continue
        [ -n "$ONLY" ] && [[ "$name" != *$ONLY* ]] && continue
        jobs+=("test $t")
    done
fi
PYTHON3=${PYTHON3:-/usr/bin/python3}
if [ "$MODE" = test ] && { [ -z "$ONLY" ] || [[ pytest_python == *$ONLY* ]]; }; then
    if [ -f "$B/python/seamtex/__init__.py" ]; then
        jobs+=("pytest python/tests")
    else
        echo "note: $B/python/seamtex is not built (no python3-dev?): the Python tests are not run" >&2
    fi
fi
if [ "$MODE" != soak ] && [ "$MODE" != tsan ]; then
    for f in $(ls "$B"/fuzz/fuzz_* 2>/dev/null | grep -v '\.[oad]$'); do
        name=$(basename "$f")
        [ -n "$ONLY" ] && [[ "$name" != *$ONLY* ]] && [[ "fuzz" != *$ONLY* ]] && continue
        jobs+=("fuzz $f")
    done
fi

# the name of a job (its log is $log_dir/<name>.log)
job_name() { if [ "$1" = pytest ]; then echo pytest_python; else basename "$2"; fi; }

# expected seconds of a job: the last run's, else a guess
guess() {
    local kind=$1 name=$2 secs=""
    [ -f "$durations" ] && secs=$(awk -v n="$name" '$1 == n {s = $2} END {print s}' "$durations")
    if [ -z "$secs" ]; then
        case "$kind/$name" in
            fuzz/*) secs=$FUZZ_SECONDS ;;
            test/test_server*|test/test_durability|test/test_client|test/test_cli|pytest/*) secs=30 ;;
            test/test_faults_daemon) secs=60 ;;
            test/test_cluster*) secs=40 ;;
            *) secs=5 ;;
        esac
    fi
    [ "$kind" = fuzz ] && secs=$FUZZ_SECONDS
    echo "$secs"
}

order=()     # the same jobs, longest first
while read -r _ kind path; do
    order+=("$kind $path")
done < <(for j in "${jobs[@]}"; do
             set -- $j
             printf '%s %s %s\n' "$(guess "$1" "$(job_name "$1" "$2")")" "$1" "$2"
         done | sort -k1,1gr -s)

# ---- one job -------------------------------------------------------------------------------
# Writes $log_dir/<name>.log (the binary's output) and $log_dir/<name>.result ("rc secs").
run_test() {
    local t=$1 name log start rc secs
    name=$(basename "$t")
    log=$log_dir/$name.log
    start=$(date +%s.%N)
    timeout -k 10 "$TEST_TIMEOUT" "$t" >"$log" 2>&1
    rc=$?
    secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
    echo "$rc $secs" >"$log_dir/$name.result"
}

run_pytest() {
    local name=pytest_python log start rc secs
    log=$log_dir/$name.log
    start=$(date +%s.%N)
    # no .pytest_cache or __pycache__ written into the tree
    PYTHONDONTWRITEBYTECODE=1 timeout -k 10 "$TEST_TIMEOUT" "$PYTHON3" -m pytest -q \
        -p no:cacheprovider "$1" >"$log" 2>&1
    rc=$?
    secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
    echo "$rc $secs" >"$log_dir/$name.result"
}

run_fuzz() {
    local f=$1 name log corpus rc start secs
    name=$(basename "$f")
    log=$log_dir/$name.log
    if [ -n "$FUZZ_CORPUS_DIR" ]; then
        corpus=$FUZZ_CORPUS_DIR/$name
        mkdir -p "$corpus"
    else
        corpus=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-fuzz-$name-XXXXXX")
    fi
    [ -d "tests/fuzz/seeds/$name" ] && cp -r "tests/fuzz/seeds/$name/." "$corpus/"
    # tests/fuzz/<target>.flags: extra libFuzzer flags of one target (e.g. -max_len)
    local extra=()
    [ -f "tests/fuzz/$name.flags" ] && read -r -a extra <"tests/fuzz/$name.flags"
    start=$(date +%s.%N)
    timeout -k 10 $((FUZZ_SECONDS + 60)) "$f" -max_total_time="$FUZZ_SECONDS" -rss_limit_mb=2048 \
        "${extra[@]}" -artifact_prefix="$log_dir/$name-" "$corpus" >"$log" 2>&1
    rc=$?
    secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')
    [ -z "$FUZZ_CORPUS_DIR" ] && rm -rf "$corpus"
    echo "$rc $secs" >"$log_dir/$name.result"
}

# ---- ThreadSanitizer (make tsan): every process (tests, seamtexd, the CLI) writes its reports
# to $log_dir/tsan.<pid>; any report is a failure, listed after the summary
if [ "$MODE" = tsan ]; then
    rm -f "$log_dir"/tsan.*
    export TSAN_OPTIONS="suppressions=$ROOT/tests/tsan.supp halt_on_error=0 second_deadlock_stack=1 log_path=$ROOT/$log_dir/tsan ${TSAN_OPTIONS:-}"
fi

# ---- the pool --------------------------------------------------------------------------------
t_all=$(date +%s.%N)
running=0
for j in "${order[@]}"; do
    set -- $j
    rm -f "$log_dir/$(job_name "$1" "$2").result"
    if [ "$running" -ge "$TEST_JOBS" ]; then
        wait -n
        running=$((running - 1))
    fi
    case $1 in
        fuzz) run_fuzz "$2" & ;;
        pytest) run_pytest "$2" & ;;
        *) run_test "$2" & ;;
    esac
    running=$((running + 1))
done
wait

# ---- the summary, in a fixed order -----------------------------------------------------------
pass=0 fail=0 skip=0
failed_names=()
new_durations=$(mktemp)
[ -f "$durations" ] && cp "$durations" "$new_durations"
for j in "${jobs[@]}"; do
    set -- $j
    kind=$1 name=$(job_name "$1" "$2")
    log=$log_dir/$name.log
    rc=1 secs=0
    [ -f "$log_dir/$name.result" ] && read -r rc secs <"$log_dir/$name.result"
    { grep -v "^$name " "$new_durations"; echo "$name $secs"; } >"$new_durations.tmp"
    mv "$new_durations.tmp" "$new_durations"
    if [ "$kind" = fuzz ]; then
        runs=$(grep -oE 'Done [0-9]+ runs' "$log" 2>/dev/null | grep -oE '[0-9]+' | tail -1)
        if [ "$rc" -eq 0 ]; then
            pass=$((pass + 1)); printf '%-40s fuzzed %ss, %s runs, no crash\n' "$name" "$FUZZ_SECONDS" "${runs:-?}"
        else
            fail=$((fail + 1)); failed_names+=("$name")
            printf '%-40s FAILED (exit %d), see %s\n' "$name" "$rc" "$log"
            grep -E 'ERROR|SUMMARY' "$log" | head -5 | sed 's/^/    /'
        fi
        continue
    fi
    if [ "$kind" = pytest ]; then
        # pytest -q closes with e.g. "2 failed, 31 passed, 1 skipped, 1 error in 20.1s"
        last=$(grep -E '(passed|failed|error|skipped|no tests ran)' "$log" | tail -1)
        count() { echo "$last" | grep -oE "[0-9]+ $1" | grep -oE '^[0-9]+' | head -1; }
        p=$(count passed); f=$(count failed); e=$(count 'errors?'); s=$(count skipped)
        p=${p:-0} f=$(( ${f:-0} + ${e:-0} )) s=${s:-0}
        if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi
        pass=$((pass + p)); fail=$((fail + f)); skip=$((skip + s))
        printf '%-40s %4d passed %3d failed %3d skipped  %6ss\n' "$name" "$p" "$f" "$s" "$secs"
        if [ "$f" -ne 0 ]; then
            failed_names+=("$name")
            grep -E '^(FAILED|ERROR)|Error' "$log" | head -20 | sed 's/^/    /'
            echo "    (exit status $rc; full log in $log)"
        fi
        continue
    fi
    p=$(grep -cE '^ok [0-9]+' "$log")
    s_ok=$(grep -cE '^ok [0-9]+ .*# SKIP' "$log")
    # cmocka 1.1 reports a skip() as "not ok N # SKIP": a skip, not a failure
    s=$(grep -cE '^(not )?ok [0-9]+ .*# SKIP' "$log")
    f=$(grep -E '^not ok [0-9]+' "$log" | grep -vc '# SKIP')
    p=$((p - s_ok))
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi
    # a binary runs one or more groups: each prints its own plan "1..N"
    planned=$(grep -oE '^1\.\.[0-9]+' "$log" | cut -d. -f3 | awk '{n += $1} END {print n + 0}')
    if [ "$planned" -gt 0 ] && [ $((p + s + f)) -lt "$planned" ] && [ "$f" -eq 0 ]; then f=1; fi
    pass=$((pass + p)); fail=$((fail + f)); skip=$((skip + s))
    printf '%-40s %4d passed %3d failed %3d skipped  %6ss\n' "$name" "$p" "$f" "$s" "$secs"
    if [ "$f" -ne 0 ]; then
        failed_names+=("$name")
        grep -E '^not ok|ERROR|error:|Assert|FAIL|rc=' "$log" | head -20 | sed 's/^/    /'
        [ "$rc" -ne 0 ] && echo "    (exit status $rc; full log in $log)"
    fi
done
mv "$new_durations" "$durations"

if [ "$MODE" = tsan ]; then
    reports=$(cat "$log_dir"/tsan.* 2>/dev/null | grep -c '^WARNING: ThreadSanitizer')
    if [ "$reports" -gt 0 ]; then
        fail=$((fail + reports)); failed_names+=("tsan")
        echo "ThreadSanitizer: $reports report(s) in $log_dir/tsan.*:"
        grep -h -A3 '^WARNING: ThreadSanitizer' "$log_dir"/tsan.* | grep -E 'WARNING|#0' | head -40 | sed 's/^/    /'
    else
        echo "ThreadSanitizer: no reports (suppressions: tests/tsan.supp)"
    fi
fi

wall=$(awk -v a="$t_all" -v b="$(date +%s.%N)" 'BEGIN{printf "%.0f", b-a}')
echo "${#jobs[@]} jobs, $TEST_JOBS at a time, ${wall}s"
[ ${#failed_names[@]} -gt 0 ] && echo "failed: ${failed_names[*]}"
if [ "$skip" -gt 0 ]; then
    echo "$pass passed, $fail failed, $skip skipped"
else
    echo "$pass passed, $fail failed"
fi
[ "$fail" -eq 0 ]
