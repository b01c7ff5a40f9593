#!/usr/bin/env bash
# deploy/run-main.sh - the main job behind `make run`: starts seamtexd on 127.0.0.1 (a free
# port, a temp data dir, the built-in "default" set), waits until it answers, then shows the
# service working end to end with the CLI and the load tester, and stops the daemon with
# SIGTERM, checking that it exits 0. Exits non-zero on any failure (and prints the daemon's
# log tail). B names the build dir (make passes B=build).
#
# Everything talks to loopback only; every step is bounded in time.
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"

DAEMON=$B/seamtexd
CLI=$B/seamtex
BENCH=$B/seamtex-bench
for exe in "$DAEMON" "$CLI" "$BENCH" "$B/seamtex-render"; do
    [ -x "$exe" ] || { echo "run-main: $exe is missing (run make first)" >&2; exit 1; }
done

TMP=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-run.XXXXXX")
PID=""
cleanup() {
    if [ -n "$PID" ] && kill -0 "$PID" 2>/dev/null; then
        kill -KILL "$PID" 2>/dev/null
        wait "$PID" 2>/dev/null
    fi
    rm -rf "$TMP"
}
trap cleanup EXIT

fail() {
    echo "run-main: FAILED: $*" >&2
    if [ -s "$TMP/daemon.log" ]; then
        echo "---- last lines of the daemon's log ----" >&2
        tail -n 20 "$TMP/daemon.log" >&2
    fi
    exit 1
}

step() { printf '\n$ %s\n' "$*"; }

echo "run-main: machine $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%FT%TZ)"

# ---- start the daemon ----------------------------------------------------------------------
mkdir -p "$TMP/data"
"$DAEMON" --listen 127.0.0.1:0 --data-dir "$TMP/data" --port-file "$TMP/port" \
    2>"$TMP/daemon.log" &
PID=$!
PORT=""
READY=""
START=$SECONDS
while [ $((SECONDS - START)) -lt 30 ]; do       # up to 30 s
    kill -0 "$PID" 2>/dev/null || fail "seamtexd exited during start"
    if [ -s "$TMP/port" ]; then
        PORT=$(tr -dc '0-9' <"$TMP/port")
        if [ -n "$PORT" ] && "$CLI" -p "$PORT" --timeout 2000 ping >/dev/null 2>&1; then
            READY=1
            break
        fi
    fi
    sleep 0.1
done
[ -n "$PORT" ] || fail "seamtexd did not write its port within 30 s"
[ -n "$READY" ] || fail "seamtexd did not answer PING within 30 s"
echo "run-main: seamtexd pid $PID listening on 127.0.0.1:$PORT, data dir $TMP/data"

run() {
    step "seamtex $*"
    timeout 60 "$CLI" -p "$PORT" "$@" || fail "seamtex $* (exit $?)"
}

run ping
run ls
run info default

# ---- a real query in each mode -----------------------------------------------------------
# face u v [dudx dvdx dudy dvdy]: a face centre, points near an edge and a corner with
# footprints that reach across it (where the modes differ), and a wide footprint.
cat >"$TMP/queries.txt" <<'EOF'
0 0.5 0.5
7 0.98 0.5 0.05 0 0 0.05
100 0.5 0.01 0.05 0 0 0.05
200 0.01 0.99 0.08 0 0 0.08
383 0.3 0.7 0.25 0 0 0.25
EOF
for mode in traverse discard clamp; do
    step "seamtex sample default --queries queries.txt --mode $mode --filter bilinear"
    out=$(timeout 60 "$CLI" -p "$PORT" sample default --queries "$TMP/queries.txt" \
          --mode "$mode" --filter bilinear) || fail "sample in $mode mode"
    echo "$out"
    nok=$(grep -c ' OK$' <<<"$out")
    [ "$nok" -eq 5 ] || fail "sample in $mode mode: $nok of 5 queries OK"
done
step "seamtex sample default 12 0.25 0.75 --mode traverse --filter trilinear --dudx 0.1 --dvdy 0.1"
timeout 60 "$CLI" -p "$PORT" sample default 12 0.25 0.75 --mode traverse --filter trilinear \
    --dudx 0.1 --dvdy 0.1 || fail "single sample"

# ---- a short load test -----------------------------------------------------------------------
step "seamtex-bench --rate 20000 --conns 16 --duration 3 --warmup 1   (open loop, PING)"
timeout 60 "$BENCH" -p "$PORT" --rate 20000 --conns 16 --threads 1 --duration 3 --warmup 1 \
    || fail "seamtex-bench open loop"
step "seamtex-bench --op sample --batch 4096 --conns 2 --pipeline 2 --duration 2 --warmup 0.5"
timeout 60 "$BENCH" -p "$PORT" --op sample --batch 4096 --conns 2 --pipeline 2 --duration 2 \
    --warmup 0.5 || fail "seamtex-bench sample"

# ---- real assets ------------------------------------------------------------------------------
# From the shared data folder (skipped when it is not there): a Ptex file
# sampled with a Ptex filter, a textured mesh (atlas) sampled by UV, the atlas re-encoded
# to seam-aware BC1 on the server, sampled from its blocks and exported as DDS.
DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
TEAPOT=$DATA/ptx/wdas-ptex-samples/teapot/teapot.ptx
DUCK=$DATA/meshes/duck
if [ -f "$TEAPOT" ] && [ -f "$DUCK/Duck.obj" ] && [ -f "$DUCK/DuckCM.png" ]; then
    run upload "$TEAPOT" teapot
    run sample teapot 12 0.5 0.5 --filter ptex-gaussian --dudx 0.2 --dvdy 0.2
    run upload "$DUCK/DuckCM.png" duck-tex
    run upload "$DUCK/Duck.obj" duck --texture duck-tex
    run info duck
    run sample duck 0 0.31 0.62 --filter trilinear --dudx 0.004 --dvdy 0.004
    run compress duck duck-bc1
    run sample duck-bc1 0 0.31 0.62 --filter trilinear --dudx 0.004 --dvdy 0.004
    run fetch duck-bc1 "$TMP/duck-bc1.dds" --format dds
    [ -s "$TMP/duck-bc1.dds" ] || fail "the fetched DDS is empty"
    head -c 4 "$TMP/duck-bc1.dds" | grep -q '^DDS ' || fail "the fetched file is not a DDS"
    echo "fetched $(stat -c %s "$TMP/duck-bc1.dds") bytes of DDS (BC1 with mips)"
    run ls
    # the renderer: one teapot frame in each mode, sampled through this daemon
    RENDER_OUT=$ROOT/$B/render-run
    step "seamtex-render teapot.obj --size 640x360 --msaa 4 --mode all --out $RENDER_OUT"
    timeout 120 "$B/seamtex-render" --port "$PORT" --size 640x360 --msaa 4 --mode all \
        --out "$RENDER_OUT" "$DATA/ptx/wdas-ptex-samples/teapot/teapot.obj" \
        || fail "seamtex-render"
    echo "the frames (Discard, Traverse, Clamp) are in $RENDER_OUT/"
else
    echo
    echo "run-main: $DATA has no teapot.ptx / duck mesh: skipping the real-asset steps"
fi

step "seamtex stats   (a few of the counters)"
stats=$(timeout 60 "$CLI" -p "$PORT" stats) || fail "seamtex stats"
grep -E '^(uptime_ms|conns_accepted|requests|replies_error|queries|bytes_in|bytes_out|sets|set_memory) ' \
    <<<"$stats"

# ---- stop ----------------------------------------------------------------------------------
step "kill -TERM $PID"
kill -TERM "$PID"
# bash reaps the child when it exits, so kill -0 fails from then on; wait gives its status
for _ in $(seq 1 200); do                      # up to 20 s
    kill -0 "$PID" 2>/dev/null || break
    sleep 0.1
done
kill -0 "$PID" 2>/dev/null && fail "seamtexd did not exit within 20 s of SIGTERM"
wait "$PID"
rc=$?
PID=""
[ "$rc" -eq 0 ] || fail "seamtexd exited with status $rc after SIGTERM"
echo "seamtexd exited 0"
echo
echo "run-main: OK"
