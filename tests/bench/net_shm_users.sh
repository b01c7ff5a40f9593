#!/usr/bin/env bash
# tests/bench/net_shm_users.sh [OUT.json] - what shared-memory sampling (PROTOCOL.md 4.12)
# buys the tools that use it, against a seamtexd on a Unix socket (temp dir, stopped at the
# end):
#   render  seamtex-render, the teapot of $SEAMTEX_DATA at SIZE (1280x720) 4x Traverse FILTER
#           (aniso, 16 probes; bilinear shows the transport's share better),
#           --repeat REPEAT (5) per run: in-process (--inproc, one sampling thread), over the
#           Unix socket (--shm off) and through the region (--shm on); ROUNDS (5) rounds, the
#           order rotating each round (A B C, B C A, C A B, ...); medians of the runs' median
#           frame and sampling times, and of the daemon's CPU time per frame (utime + stime
#           from /proc over the run's REPEAT frames: steadier than wall times under load)
#   python  Client.sample of PYN (10^6) random bilinear Traverse queries on the default set,
#           a socket Client and a shm=True Client in one process, PYROUNDS (9) pairs
#           alternating which goes first; medians of the wall times
# and the medians of the per-round ratios (the runs of one round are adjacent in time).
# Prints a table and the load average before and after; writes JSON. Env: SIZE, FILTER,
# REPEAT, ROUNDS (0: no render part), PYN, PYROUNDS (0: no Python part). Without the teapot
# the render part is skipped and says so.
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT"
OUT=${1:-$B/bench/net_shm_users.json}
SIZE=${SIZE:-1280x720}
FILTER=${FILTER:-aniso}
REPEAT=${REPEAT:-5}
ROUNDS=${ROUNDS:-5}
PYN=${PYN:-1000000}
PYROUNDS=${PYROUNDS:-9}
DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
TEAPOT=$DATA/ptx/wdas-ptex-samples/teapot/teapot.obj
PY=${PYTHON3:-/usr/bin/python3}
for exe in "$B/seamtexd" "$B/seamtex-render"; do
    [ -x "$exe" ] || { echo "$(basename "$0"): $exe is missing (make first)" >&2; exit 1; }
done
TMP=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-shmusers.XXXXXX")
PID=""
cleanup() {
    if [ -n "$PID" ] && kill -0 "$PID" 2>/dev/null; then
        kill -TERM "$PID"
        wait "$PID" 2>/dev/null
    fi
    rm -rf "$TMP"
}
trap cleanup EXIT
ADDR=unix:$TMP/s.sock
"$B/seamtexd" --listen "$ADDR" --port-file "$TMP/port" --log-level warn 2>>"$TMP/daemon.log" &
PID=$!
for _ in $(seq 1 300); do [ -s "$TMP/port" ] && break; sleep 0.1; done
[ -s "$TMP/port" ] || { echo "seamtexd did not start:" >&2; cat "$TMP/daemon.log" >&2; exit 1; }

median() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "null"; else if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
LOAD0=$(cut -d' ' -f1-3 /proc/loadavg)
echo "net_shm_users: load before $LOAD0"

# ---- render ------------------------------------------------------------------------------
declare -A FR=() SA=() DC=()
daemon_cpu_ms() {   # utime + stime of the daemon in ms (fields 14, 15 of /proc/PID/stat)
    awk -v hz="$(getconf CLK_TCK)" '{ sub(/.*\) /, ""); print ($12 + $13) * 1000 / hz }' \
        "/proc/$PID/stat"
}
RENDER_JSON="null"
if [ "$ROUNDS" -gt 0 ] && [ -r "$TEAPOT" ]; then
    # the first run uploads the texture; every timed run then uses --no-upload
    "$B/seamtex-render" --host "$ADDR" --shm off --size 64x48 --mode traverse --quiet \
        --out "$TMP" "$TEAPOT" >/dev/null || { echo "render warm-up failed" >&2; exit 1; }
    variants=(inproc socket shm)
    for r in $(seq 0 $((ROUNDS - 1))); do
        for k in 0 1 2; do
            v=${variants[$(((r + k) % 3))]}
            case $v in
            inproc) how=(--inproc) ;;
            socket) how=(--host "$ADDR" --no-upload --shm off) ;;
            shm)    how=(--host "$ADDR" --no-upload --shm on) ;;
            esac
            c0=$(daemon_cpu_ms)
            line=$("$B/seamtex-render" "${how[@]}" --size "$SIZE" --msaa 4 --mode traverse \
                   --filter "$FILTER" \
                   --repeat "$REPEAT" --out "$TMP" "$TEAPOT" | grep ' frame 0: ')
            [ -n "$line" ] || { echo "render $v failed" >&2; exit 1; }
            DC[$v]+="$(awk -v a="$c0" -v b="$(daemon_cpu_ms)" -v n="$REPEAT" \
                       'BEGIN { print (b - a) / n }') "
            # "... frame 0: T ms (raster R, sampling[ over ...] S, resolve X) median; ..."
            FR[$v]+="$(sed -E 's/.* frame 0: ([0-9.]+) ms.*/\1/' <<<"$line") "
            SA[$v]+="$(sed -E 's/.*sampling[a-z ]* ([0-9.]+), resolve.*/\1/' <<<"$line") "
        done
    done
    printf '\nseamtex-render teapot %s 4x traverse %s, --repeat %s, %s rounds (medians, ms; ratios:\n' \
        "$SIZE" "$FILTER" "$REPEAT" "$ROUNDS"
    printf 'medians of the per-round ratios of the sampling times)\n'
    printf '%-10s %10s %10s %14s %14s %18s\n' variant frame sampling "vs inproc" "vs socket" \
        "daemon CPU/frame"
    declare -A MF=() MS=() MD=()
    for v in inproc socket shm; do
        MF[$v]=$(tr ' ' '\n' <<<"${FR[$v]}" | grep . | median)
        MS[$v]=$(tr ' ' '\n' <<<"${SA[$v]}" | grep . | median)
        MD[$v]=$(tr ' ' '\n' <<<"${DC[$v]}" | grep . | median)
    done
    ratio() {   # median over rounds of run(a) / run(b)
        paste -d' ' <(tr ' ' '\n' <<<"${SA[$1]}" | grep .) <(tr ' ' '\n' <<<"${SA[$2]}" | grep .) |
            awk '{ print $1 / $2 }' | median
    }
    for v in inproc socket shm; do
        printf '%-10s %10s %10s %14.2f %14.2f %18s\n' "$v" "${MF[$v]}" "${MS[$v]}" \
            "$(ratio "$v" inproc)" "$(ratio "$v" socket)" "${MD[$v]}"
    done
    RENDER_JSON=$(printf '{"size": "%s", "filter": "%s", "repeat": %s, "rounds": %s, "shm_vs_socket": %s, "socket_vs_inproc": %s, "shm_vs_inproc": %s, ' \
        "$SIZE" "$FILTER" "$REPEAT" "$ROUNDS" "$(ratio shm socket)" "$(ratio socket inproc)" \
        "$(ratio shm inproc)")
    for v in inproc socket shm; do
        RENDER_JSON+=$(printf '"%s": {"frame_ms": %s, "sampling_ms": %s, "daemon_cpu_ms_per_frame": %s, "frame_runs": [%s], "sampling_runs": [%s], "daemon_cpu_runs": [%s]}, ' \
            "$v" "${MF[$v]}" "${MS[$v]}" "${MD[$v]}" \
            "$(tr ' ' '\n' <<<"${FR[$v]}" | grep . | paste -sd,)" \
            "$(tr ' ' '\n' <<<"${SA[$v]}" | grep . | paste -sd,)" \
            "$(tr ' ' '\n' <<<"${DC[$v]}" | grep . | paste -sd,)")
    done
    RENDER_JSON="${RENDER_JSON%, }}"
else
    [ "$ROUNDS" -gt 0 ] && echo "render: skipped: $TEAPOT is missing (SEAMTEX_DATA)"
fi

# ---- python ------------------------------------------------------------------------------
PY_JSON="null"
if [ "$PYROUNDS" -gt 0 ] && [ -f "$B/python/seamtex/__init__.py" ]; then
    PY_JSON=$(SEAMTEX_BUILD=$ROOT/$B "$PY" - "$ADDR" "$PYN" "$PYROUNDS" <<'EOF'
import json, os, statistics, sys, time
sys.path.insert(0, os.path.join(os.environ["SEAMTEX_BUILD"], "python"))
import numpy as np
import seamtex
addr, n, rounds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
rng = np.random.default_rng(5)
face = rng.integers(0, 384, n, dtype=np.uint32)
u = rng.random(n, dtype=np.float32)
v = rng.random(n, dtype=np.float32)
t = {"socket": [], "shm": []}
with seamtex.Client(addr, timeout=120, shm=False) as s, \
        seamtex.Client(addr, timeout=120, shm=True) as m:
    cl = {"socket": s, "shm": m}
    out = {}
    for k in cl:                       # warm-up, and the results must agree
        for _ in range(2):
            out[k] = cl[k].sample("default", face, u, v)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(out["socket"], out["shm"]))
    for r in range(rounds):
        for k in (("socket", "shm") if r % 2 == 0 else ("shm", "socket")):
            t0 = time.perf_counter()
            cl[k].sample("default", face, u, v)
            t[k].append(time.perf_counter() - t0)
    assert m.shm_status["via_shm"] >= rounds + 2 and m.shm_status["via_socket"] == 0
print(json.dumps({"n": n, "rounds": rounds,
                  "socket_s": statistics.median(t["socket"]), "shm_s": statistics.median(t["shm"]),
                  "shm_vs_socket": statistics.median(a / b for a, b in zip(t["shm"], t["socket"])),
                  "socket_runs": t["socket"], "shm_runs": t["shm"]}))
EOF
) || { echo "python part failed" >&2; exit 1; }
    "$PY" - "$PY_JSON" <<'EOF'
import json, sys
j = json.loads(sys.argv[1])
print("\nPython Client.sample of %d bilinear Traverse queries, %d alternated pairs (medians)"
      % (j["n"], j["rounds"]))
for k in ("socket", "shm"):
    s = j[k + "_s"]
    print("%-8s %8.3f s  %6.2f M queries/s" % (k, s, j["n"] / s / 1e6))
print("shm / socket time, median of the pairs' ratios: %.2f" % j["shm_vs_socket"])
EOF
elif [ "$PYROUNDS" -gt 0 ]; then
    echo "python: skipped: $B/python/seamtex is not built"
fi

LOAD1=$(cut -d' ' -f1-3 /proc/loadavg)
echo "net_shm_users: load after $LOAD1"
mkdir -p "$(dirname "$OUT")"
printf '{"bench": "net_shm_users", "load_before": "%s", "load_after": "%s", "render": %s, "python": %s}\n' \
    "$LOAD0" "$LOAD1" "$RENDER_JSON" "$PY_JSON" >"$OUT"
echo "wrote $OUT"
