#!/usr/bin/env bash
# tests/bench/net_ping.sh OUT.json - PING over loopback against seamtexd, beside the anchors
# measured on this machine for memcached and Redis (issue text):
#   ping-pong, 1 connection (closed loop, pipeline 1)
#   open loop, 50 connections, 10k / 50k / 100k req/s uniform arrivals: corrected p50 / p99
#   closed loop, 50 connections x pipeline 16: throughput
# Each figure is the median of NET_REPS runs (default 3) of NET_SECS seconds (default 2) after
# a 0.5 s warm-up. Prints a table, writes OUT.json.
set -u
OUT=${1:?usage: net_ping.sh OUT.json}
source "$(dirname "$0")/net_common.inc"
net_need
REPS=${NET_REPS:-3}
SECS=${NET_SECS:-2}
THREADS=${NET_THREADS:-1}

load0=$(net_load)
net_start
runs=()
# run NAME ARGS...: one seamtex-bench run, JSON kept in $NET_TMP/NAME.N.json
run() {
    local name=$1; shift
    for r in $(seq 1 "$REPS"); do
        local f=$NET_TMP/$name.$r.json c0 c1
        c0=$(net_daemon_cpu)
        timeout 60 "$BENCH" -p "$NET_PORT" -d "$SECS" -w 0.5 -q -j "$f" "$@" >/dev/null \
            || { echo "net_ping: run $name failed" >&2; }
        c1=$(net_daemon_cpu)
        [ -s "$f" ] || continue
        runs+=("$f")
        # daemon CPU microseconds per request (warm-up included): independent of the load
        awk -v a="$c0" -v b="$c1" -v n="$(net_json "$f" completed)" \
            'BEGIN{printf "%.2f\n", (n > 0 ? (b - a) * 1e6 / n : 0)}' >"$NET_TMP/$name.$r.cpu"
    done
}
# med NAME KEY [SUB]: median over the repetitions
med() {
    local name=$1 vals=()
    for f in "$NET_TMP/$name".*.json; do
        [ -s "$f" ] || continue
        vals+=("$(net_json "$f" "$2" "${3:-}")")
    done
    [ ${#vals[@]} -gt 0 ] && net_median "${vals[@]}" || echo 0
}

run pingpong -c 1 -P 1
for rate in 10000 50000 100000; do
    run open$rate -c 50 -T "$THREADS" --rate "$rate"
done
run closed -c 50 -T "$THREADS" -P 16
net_stop || echo "net_ping: seamtexd did not exit 0" >&2
load1=$(net_load)

pp_rate=$(med pingpong achieved_rate)
pp_p50=$(med pingpong corrected_us p50)
pp_p99=$(med pingpong corrected_us p99)
cl_rate=$(med closed achieved_rate)
cpu_of() {      # cpu_of NAME: median daemon CPU us per request
    local vals=()
    for c in "$NET_TMP/$1".*.cpu; do [ -s "$c" ] && vals+=("$(cat "$c")"); done
    [ ${#vals[@]} -gt 0 ] && net_median "${vals[@]}" || echo 0
}
cl_p99=$(med closed corrected_us p99)
printf '\nnet_ping: PING over loopback, %s cores, load %s -> %s, median of %s x %s s\n' \
    "$(nproc)" "$load0" "$load1" "$REPS" "$SECS"
printf '%-36s %-40s %-5s %s\n' "test" "seamtexd" "load" "anchors (this machine)"
printf '%-36s %-40s %-5s %s\n' "ping-pong, 1 conn" \
    "$(printf '%.1fk req/s, p50 %.0f / p99 %.0f us' "$(awk -v x="$pp_rate" 'BEGIN{print x/1000}')" "$pp_p50" "$pp_p99")" \
    "$(med pingpong loadavg_before)" "memcached 22.8k req/s, p50 39 / p99 127 us"
printf 'daemon CPU per request: ping-pong %s us, closed loop 50x16 %s us, open 10k/50k/100k %s / %s / %s us\n' \
    "$(cpu_of pingpong)" "$(cpu_of closed)" "$(cpu_of open10000)" "$(cpu_of open50000)" "$(cpu_of open100000)"
declare -A ANCH=([10000]="memcached 97 / 737, Redis 97 / 458 us"
                 [50000]="memcached 161 / 2406, Redis 55 / 645 us"
                 [100000]="memcached 834 / 5104, Redis 67 / 3926 us")
json_open=""
for rate in 10000 50000 100000; do
    p50=$(med open$rate corrected_us p50); p99=$(med open$rate corrected_us p99)
    s50=$(med open$rate service_us p50); s99=$(med open$rate service_us p99)
    ach=$(med open$rate achieved_rate); to=$(med open$rate timeouts); er=$(med open$rate errors)
    printf '%-36s %-40s %-5s %s\n' "open loop $((rate / 1000))k/s, 50 conns" \
        "$(printf 'p50 %.0f / p99 %.0f us (got %.0f/s)' "$p50" "$p99" "$ach")" \
        "$(med open$rate loadavg_before)" "${ANCH[$rate]}"
    json_open+="    \"open_${rate}\": {\"loadavg\": $(med open$rate loadavg_before), \"target_rate\": $rate, \"achieved_rate\": $ach, \"corrected_p50_us\": $p50, \"corrected_p99_us\": $p99, \"service_p50_us\": $s50, \"service_p99_us\": $s99, \"errors\": $er, \"timeouts\": $to},"$'\n'
done
printf '%-36s %-40s %-5s %s\n' "closed loop, 50 conns x pipeline 16" \
    "$(printf '%.0fk req/s (p99 %.0f us)' "$(awk -v x="$cl_rate" 'BEGIN{print x/1000}')" "$cl_p99")" \
    "$(med closed loadavg_before)" "memcached 600-770k, Redis 570-690k req/s"

{
    echo "{"
    echo "  \"benchmark\": \"net_ping\","
    echo "  \"machine\": {\"cores\": $(nproc), \"loadavg_before\": $load0, \"loadavg_after\": $load1},"
    echo "  \"reps\": $REPS, \"seconds\": $SECS, \"client_threads\": $THREADS,"
    echo "  \"results\": {"
    echo "    \"pingpong\": {\"loadavg\": $(med pingpong loadavg_before), \"rate\": $pp_rate, \"p50_us\": $pp_p50, \"p99_us\": $pp_p99},"
    printf '%s' "$json_open"
    echo "    \"daemon_cpu_us_per_request\": {\"pingpong\": $(cpu_of pingpong), \"closed_50x16\": $(cpu_of closed), \"open_10000\": $(cpu_of open10000), \"open_50000\": $(cpu_of open50000), \"open_100000\": $(cpu_of open100000)},"
    echo "    \"closed_50x16\": {\"loadavg\": $(med closed loadavg_before), \"rate\": $cl_rate, \"p99_us\": $cl_p99}"
    echo "  },"
    echo "  \"anchors\": {\"pingpong_memcached\": {\"rate\": 22800, \"p50_us\": 39, \"p99_us\": 127},"
    echo "    \"open_10000\": {\"memcached\": [97, 737], \"redis\": [97, 458]},"
    echo "    \"open_50000\": {\"memcached\": [161, 2406], \"redis\": [55, 645]},"
    echo "    \"open_100000\": {\"memcached\": [834, 5104], \"redis\": [67, 3926]},"
    echo "    \"closed_50x16\": {\"memcached\": [600000, 770000], \"redis\": [570000, 690000]}},"
    echo "  \"runs\": ["
    sep=""
    for f in "${runs[@]}"; do printf '%s' "$sep"; sed 's/^/    /' "$f"; sep=","; done
    echo "  ]"
    echo "}"
} >"$OUT"
echo "net_ping: wrote $OUT"
