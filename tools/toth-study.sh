#!/usr/bin/env bash
# tools/toth-study.sh - Toth 2013's Table 1 and Figure 5 reproduced with seamtexd: starts a
# seamtexd on a Unix socket in a temp dir (TOTH_LISTEN=tcp: on TCP loopback, a free port) with a
# temp data dir, runs `seamtex-render --toth OUT` against it (on the Unix socket its queries and
# replies go through a shared-memory region, `--shm auto`) on the given meshes (default: the teapot and the holey cube of $SEAMTEX_DATA), then draws
# Figure 5 from the CSVs with gnuplot (OUT/fig5_<mesh>.png: left Traverse vs Discard, right each
# vs the reference) and stops the daemon with SIGTERM.
#
#   tools/toth-study.sh OUT [seamtex-render options] [MESH.obj ...]
#   e.g. nice tools/toth-study.sh build/toth --frames 120 --size 320x240
#
# B names the build dir (default build); TOTH_LISTEN=unix (default) or tcp. Exits non-zero when
# any step fails.
set -u
B=${B:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
if [ $# -lt 1 ]; then
    echo "usage: tools/toth-study.sh OUT [seamtex-render options] [MESH.obj ...]" >&2
    exit 2
fi
OUT=$1
shift
DATA=${SEAMTEX_DATA:-$ROOT/../shared/data}
RENDER=$ROOT/$B/seamtex-render
DAEMON=$ROOT/$B/seamtexd
for exe in "$RENDER" "$DAEMON"; do
    [ -x "$exe" ] || { echo "toth-study: $exe is missing (run make first)" >&2; exit 1; }
done
if ! command -v gnuplot >/dev/null; then
    echo "toth-study: gnuplot is missing (deploy/install-deps.sh installs gnuplot-nox)" >&2
    exit 1
fi
args=()
meshes=()
while [ $# -gt 0 ]; do
    case "$1" in
        *.obj) meshes+=("$1") ;;
        --*)                        # a flag, with its value unless it takes none
            args+=("$1")
            case "$1" in
                --inproc|--no-upload|--quiet|--all-frames|--breakdown) ;;
                *) shift; args+=("${1:-}") ;;
            esac ;;
        *) echo "toth-study: unexpected argument '$1'" >&2; exit 2 ;;
    esac
    shift
done
if [ ${#meshes[@]} -eq 0 ]; then
    meshes=("$DATA/ptx/wdas-ptex-samples/teapot/teapot.obj"
            "$DATA/ptx/wdas-ptex-samples/holeycube/holeycube.obj")
fi
for m in "${meshes[@]}"; do
    [ -f "$m" ] || { echo "toth-study: $m is missing (SEAMTEX_DATA=$DATA)" >&2; exit 1; }
done

TMP=$(mktemp -d "${TMPDIR:-/tmp}/seamtex-toth.XXXXXX")
PID=""
cleanup() {
    if [ -n "$PID" ] && kill -0 "$PID" 2>/dev/null; then
        kill -TERM "$PID" 2>/dev/null
        for _ in $(seq 1 100); do kill -0 "$PID" 2>/dev/null || break; sleep 0.1; done
        kill -KILL "$PID" 2>/dev/null
        wait "$PID" 2>/dev/null
    fi
    rm -rf "$TMP"
}
trap cleanup EXIT
mkdir -p "$TMP/data" "$OUT"
case "${TOTH_LISTEN:-unix}" in
    unix) LISTEN="unix:$TMP/s.sock" ;;
    tcp) LISTEN=127.0.0.1:0 ;;
    *) echo "toth-study: TOTH_LISTEN must be unix or tcp" >&2; exit 2 ;;
esac
"$DAEMON" --listen "$LISTEN" --data-dir "$TMP/data" --port-file "$TMP/port" 2>"$TMP/daemon.log" &
PID=$!
for _ in $(seq 1 600); do                     # up to 60 s on a loaded machine
    [ -s "$TMP/port" ] && break
    if ! kill -0 "$PID" 2>/dev/null; then
        echo "toth-study: seamtexd exited at start:" >&2
        tail -5 "$TMP/daemon.log" >&2
        exit 1
    fi
    sleep 0.1
done
[ -s "$TMP/port" ] || { echo "toth-study: seamtexd did not start within 60 s" >&2; exit 1; }
if [ "$LISTEN" = 127.0.0.1:0 ]; then
    WHERE="127.0.0.1:$(cat "$TMP/port")"
    CONNECT=(--port "$(cat "$TMP/port")")
else
    WHERE=$LISTEN
    CONNECT=(--host "$LISTEN")
fi
echo "toth-study: seamtexd on $WHERE; load $(cut -d' ' -f1-3 /proc/loadavg); $(date -u +%FT%TZ)"
if ! "$RENDER" --toth "$OUT" "${CONNECT[@]}" "${args[@]}" "${meshes[@]}"; then
    echo "toth-study: seamtex-render failed" >&2
    tail -5 "$TMP/daemon.log" >&2
    exit 1
fi
echo "toth-study: load after the run $(cut -d' ' -f1-3 /proc/loadavg)"

# Figure 5: columns of fig5_<name>.csv are x, then traverse_vs_discard_{1,2,4,8}x,
# traverse_vs_ref_{1,2,4,8}x, discard_vs_ref_{1,2,4,8}x (fraction of pixels deviating >= x)
for csv in "$OUT"/fig5_*.csv; do
    name=$(basename "$csv" .csv)
    gnuplot <<GP || { echo "toth-study: gnuplot failed on $csv" >&2; exit 1; }
set terminal png size 1200,480 font ",10" noenhanced
set output "$OUT/$name.png"
set datafile separator ","
set key top right
set logscale y
set yrange [1e-5:1]
set xrange [0:0.3]
set xlabel "x: 2-norm deviation, linear RGB"
set ylabel "fraction of pixels deviating >= x"
set multiplot layout 1,2 title "$name (seamtex-render, Toth 2013 Figure 5)"
set title "Traverse vs Discard"
plot for [i=0:3] "$csv" every ::1 using 1:(column(2+i)) with lines lw 2 title sprintf("%dx", 2**i)
set title "vs the reference: solid Traverse, dashed Discard"
plot for [i=0:3] "$csv" every ::1 using 1:(column(6+i)) with lines lw 2 lc i+1 title sprintf("Traverse %dx", 2**i), \
     for [i=0:3] "$csv" every ::1 using 1:(column(10+i)) with lines lw 2 lc i+1 dt 2 title sprintf("Discard %dx", 2**i)
unset multiplot
GP
    echo "toth-study: $OUT/$name.png"
done
echo "toth-study: OK, results in $OUT"
