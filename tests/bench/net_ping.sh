#!/usr/bin/env bash
# tests/bench/net_ping.sh OUT.json - the cheapest request over loopback, seamtexd beside
# memcached and Redis measured in the same run with the same load generator (seamtex-bench
# --proto: seamtexd PING, memcached "version", Redis PING in RESP; see client/bench_wire.c for
# why not memcached's "mn"):
#   ping-pong, 1 connection (closed loop, pipeline 1)
#   open loop, 50 connections, 10k / 50k / 100k req/s uniform arrivals: corrected p50 / p99
#   closed loop, 50 connections x pipeline 16: throughput (capacity)
# The servers run side by side (idle when not loaded) and take turns: for each test point,
# each repetition runs seamtexd, memcached, Redis in that order (A B C A B C ...), so a change
# of the machine's load touches all three alike. Each figure is the median of NET_REPS
# repetitions (default 3) of NET_SECS seconds (default 2) after a 0.5 s warm-up.
# A peer that is not installed or does not start gets no figure, and the reason is printed
# (NET_PEERS="memcached redis" by default; empty = seamtexd alone). Prints a table, writes
# OUT.json, where every server says whether it was measured in this run.
set -u
OUT=${1:?usage: net_ping.sh OUT.json}
source "$(dirname "$0")/net_common.inc"
net_need
REPS=${NET_REPS:-3}
SECS=${NET_SECS:-2}
THREADS=${NET_THREADS:-1}
PEERS=${NET_PEERS-memcached redis}

load0=$(net_load)
date0=$(date -u +%FT%TZ)
net_start
declare -A PID=([seamtex]=$NET_PID) PORT=([seamtex]=$NET_PORT)
servers=(seamtex)
for p in $PEERS; do
    if net_peer_start "$p"; then
        PID[$p]=${PEER_PID[$p]}
        PORT[$p]=${PEER_PORT[$p]}
        servers+=("$p")
    else
        echo "net_ping: $p not measured: ${PEER_WHY[$p]}" >&2
    fi
done

runs=()
# run SERVER NAME REP ARGS...: one seamtex-bench run, JSON kept in $NET_TMP/SERVER.NAME.REP.json
# and the server's CPU microseconds per request (warm-up included) in .cpu beside it
run() {
    local s=$1 name=$2 r=$3; shift 3
    local f=$NET_TMP/$s.$name.$r.json c0 c1
    c0=$(net_pid_cpu "${PID[$s]}")
    timeout 60 "$BENCH" --proto "$s" -p "${PORT[$s]}" -d "$SECS" -w 0.5 -q -j "$f" "$@" \
        >/dev/null || echo "net_ping: $s run $name failed" >&2
    c1=$(net_pid_cpu "${PID[$s]}")
    [ -s "$f" ] || return 0
    runs+=("$f")
    awk -v a="$c0" -v b="$c1" -v n="$(net_json "$f" completed)" \
        'BEGIN{printf "%.2f\n", (n > 0 ? (b - a) * 1e6 / n : 0)}' >"$NET_TMP/$s.$name.$r.cpu"
}
RATES=(10000 50000 100000)
points=(pingpong)
declare -A ARGS=([pingpong]="-c 1 -P 1" [closed]="-c 50 -T $THREADS -P 16")
for rate in "${RATES[@]}"; do
    points+=("open$rate")
    ARGS[open$rate]="-c 50 -T $THREADS --rate $rate"
done
points+=(closed)
for pt in "${points[@]}"; do
    for r in $(seq 1 "$REPS"); do
        for s in "${servers[@]}"; do
            # shellcheck disable=SC2086
            run "$s" "$pt" "$r" ${ARGS[$pt]}
        done
    done
done

net_stop || echo "net_ping: seamtexd did not exit 0" >&2
for p in $PEERS; do net_peer_stop "$p"; done
load1=$(net_load)

# Medians over the repetitions, computed once: M["SERVER POINT KEY"] for every number of the
# runs' JSON (nested ones as KEY.SUB, e.g. corrected_us.p99) and "cpu" from the .cpu files.
declare -A M=()
while read -r key val; do M[$key]=$val; done < <(
    for f in "$NET_TMP"/*.*.*.json "$NET_TMP"/*.*.*.cpu; do [ -s "$f" ] && echo "$f"; done |
    xargs -r awk '
        { n = split(FILENAME, p, "/"); split(p[n], id, "."); pre = id[1] " " id[2] " " }
        FILENAME ~ /\.cpu$/ { print pre "cpu", $1; next }
        /^ *"[a-z_0-9]+": [-0-9.e+]+,?$/ {
            k = $1; gsub(/[":]/, "", k); v = $2; sub(/,$/, "", v); print pre k, v }
        /^ *"[a-z_0-9]+": \{/ {
            k = $1; gsub(/[":]/, "", k); line = $0; sub(/^[^{]*\{/, "", line)
            m = split(line, kv, ", ")
            for (i = 1; i <= m; i++) {
                split(kv[i], e, ": "); sk = e[1]; gsub(/[" {}]/, "", sk); sv = e[2]; gsub(/[ },]/, "", sv)
                print pre k "." sk, sv
            }
        }' |
    sort -k1,1 -k2,2 -k3,3 -k4,4g |
    awk '{ g = $1 " " $2 " " $3 }
         g != last && NR > 1 { out() }
         { v[++n] = $4; last = g }
         END { if (n) out() }
         function out() { printf "%s\t%s\n", last, (n % 2) ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2; n = 0 }' |
    sed 's/ /_/; s/ /_/; s/\t/ /')
# med SERVER POINT KEY [SUB]: median over the repetitions (0 when there was no run)
med() { local key="$1_$2_$3${4:+.$4}"; echo "${M[$key]:-0}"; }
# cpu SERVER POINT: median server CPU us per request
cpu() { med "$1" "$2" cpu; }

k() { awk -v x="$1" 'BEGIN{printf "%.1fk", x / 1000}'; }
title() {
    case $1 in
        seamtex) echo "seamtexd PING" ;;
        memcached) echo "memcached ${PEER_VERSION[memcached]} version" ;;
        redis) echo "Redis ${PEER_VERSION[redis]} PING" ;;
    esac
}
cell() {        # cell SERVER POINT: the table entry
    local s=$1 pt=$2
    case $pt in
        pingpong) printf '%s/s, p50 %.0f / p99 %.0f us' "$(k "$(med "$s" pingpong achieved_rate)")" \
                      "$(med "$s" pingpong corrected_us p50)" "$(med "$s" pingpong corrected_us p99)" ;;
        open*) printf 'p50 %.0f / p99 %.0f us (%s/s)' "$(med "$s" "$pt" corrected_us p50)" \
                   "$(med "$s" "$pt" corrected_us p99)" "$(k "$(med "$s" "$pt" achieved_rate)")" ;;
        closed) printf '%s/s (p99 %.0f us)' "$(k "$(med "$s" closed achieved_rate)")" \
                    "$(med "$s" closed corrected_us p99)" ;;
    esac
}
label() {
    case $1 in
        pingpong) echo "ping-pong, 1 conn" ;;
        open*) echo "open loop $((${1#open} / 1000))k/s, 50 conns" ;;
        closed) echo "closed loop, 50 conns x pipeline 16" ;;
    esac
}

printf '\nnet_ping: no-op request over loopback, same load generator, %s cores, load %s -> %s, %s,\n' \
    "$(nproc)" "$load0" "$load1" "$date0"
printf 'median of %s x %s s, servers alternated (A B C A B C) at every point; latency corrected for coordinated omission\n' \
    "$REPS" "$SECS"
printf '%-36s' "test"
for s in "${servers[@]}"; do printf ' %-34s' "$(title "$s")"; done
printf '\n'
for pt in "${points[@]}"; do
    printf '%-36s' "$(label "$pt")"
    for s in "${servers[@]}"; do printf ' %-34s' "$(cell "$s" "$pt")"; done
    printf '\n'
done
for pt in pingpong closed; do
    printf '%-36s' "server CPU per request, $pt"
    for s in "${servers[@]}"; do printf ' %-34s' "$(cpu "$s" "$pt") us"; done
    printf '\n'
done
for p in $PEERS; do
    [ -n "${PEER_WHY[$p]:-}" ] && printf '%s: not measured (%s)\n' "$p" "${PEER_WHY[$p]}"
done

# json_server SERVER: that server's figures from this run
json_server() {
    local s=$1 pt sep=""
    printf '{"measured_in_this_run": true, "request": "%s",' \
        "$(case $s in seamtex) echo PING;; memcached) echo version;; redis) echo 'PING (RESP)';; esac)"
    if [ "$s" = seamtex ]; then
        printf ' "command": "seamtexd (defaults)",'
    else
        printf ' "version": "%s", "command": "%s",' "${PEER_VERSION[$s]}" \
            "$(echo "${PEER_CMD[$s]% }" | sed "s|$NET_TMP|TMP|g; s|[\\\"]|\\\\&|g")"
    fi
    printf '\n      "pingpong": {"rate": %s, "p50_us": %s, "p99_us": %s, "cpu_us_per_request": %s},\n' \
        "$(med "$s" pingpong achieved_rate)" "$(med "$s" pingpong corrected_us p50)" \
        "$(med "$s" pingpong corrected_us p99)" "$(cpu "$s" pingpong)"
    for rate in "${RATES[@]}"; do
        pt=open$rate
        printf '      "open_%s": {"loadavg": %s, "target_rate": %s, "achieved_rate": %s, "corrected_p50_us": %s, "corrected_p99_us": %s, "service_p50_us": %s, "service_p99_us": %s, "errors": %s, "timeouts": %s, "cpu_us_per_request": %s},\n' \
            "$rate" "$(med "$s" "$pt" loadavg_before)" "$rate" "$(med "$s" "$pt" achieved_rate)" \
            "$(med "$s" "$pt" corrected_us p50)" "$(med "$s" "$pt" corrected_us p99)" \
            "$(med "$s" "$pt" service_us p50)" "$(med "$s" "$pt" service_us p99)" \
            "$(med "$s" "$pt" errors)" "$(med "$s" "$pt" timeouts)" "$(cpu "$s" "$pt")"
    done
    printf '      "closed_50x16": {"loadavg": %s, "rate": %s, "p99_us": %s, "cpu_us_per_request": %s}}' \
        "$(med "$s" closed loadavg_before)" "$(med "$s" closed achieved_rate)" \
        "$(med "$s" closed corrected_us p99)" "$(cpu "$s" closed)"
}

{
    echo "{"
    echo "  \"benchmark\": \"net_ping\","
    echo "  \"date\": \"$date0\","
    echo "  \"machine\": {\"cores\": $(nproc), \"loadavg_before\": $load0, \"loadavg_after\": $load1},"
    echo "  \"reps\": $REPS, \"seconds\": $SECS, \"client_threads\": $THREADS,"
    echo "  \"order\": \"servers alternated at every test point, figures are medians of the repetitions\","
    echo "  \"servers\": {"
    printf '    "seamtexd": '; json_server seamtex
    for p in $PEERS; do
        printf ',\n    "%s": ' "$p"
        if [ -n "${PORT[$p]:-}" ]; then
            json_server "$p"
        else
            printf '{"measured_in_this_run": false, "why": "%s"}' \
                "$(echo "${PEER_WHY[$p]}" | sed 's/["\\]/ /g')"
        fi
    done
    echo
    echo "  },"
    echo "  \"runs\": ["
    sep=""
    for f in "${runs[@]}"; do printf '%s' "$sep"; sed 's/^/    /' "$f"; sep=","; done
    echo "  ]"
    echo "}"
} >"$OUT"
echo "net_ping: wrote $OUT"
