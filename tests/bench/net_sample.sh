#!/usr/bin/env bash
# tests/bench/net_sample.sh OUT.json - SAMPLE throughput over loopback against the
# in-process sampler: batches of 4096 random bilinear Traverse queries on the default set,
# closed loop, versus st_sample_batch on the same set with the same queries in one process
# (seamtex-bench --inproc). Target: the network delivers at least 80 % of the in-process
# figure. Medians of NET_REPS runs (default 3) of NET_SECS s (default 2). Writes OUT.json.
set -u
OUT=${1:?usage: net_sample.sh OUT.json}
source "$(dirname "$0")/net_common.inc"
net_need
REPS=${NET_REPS:-3}
SECS=${NET_SECS:-2}
BATCH=${NET_BATCH:-4096}

load0=$(net_load)
med_of() {      # med_of PREFIX KEY [SUBKEY]: median of KEY over PREFIX.*.json
    local vals=()
    for f in "$NET_TMP/$1".*.json; do [ -s "$f" ] && vals+=("$(net_json "$f" "$2" "${3:-}")"); done
    [ ${#vals[@]} -gt 0 ] && net_median "${vals[@]}" || echo 0
}
runs=()
net_start
# a few shapes; the best median is the figure (the client shares the 2 cores with the server).
# The in-process and network runs alternate within each repetition, so that a change of the
# machine's load during the script touches both sides alike.
shapes=("-c 2 -P 2" "-c 4 -P 2 -T 2")
for r in $(seq 1 "$REPS"); do
    for t in 1 2; do
        f=$NET_TMP/inproc$t.$r.json
        timeout 60 "$BENCH" --inproc -T "$t" -b "$BATCH" -m traverse -f bilinear -d "$SECS" \
            -w 0.5 -q -j "$f" >/dev/null || echo "net_sample: in-process run failed" >&2
        [ -s "$f" ] && runs+=("$f")
    done
    i=0
    for shape in "${shapes[@]}"; do
        f=$NET_TMP/net$i.$r.json
        c0=$(net_daemon_cpu)
        # shellcheck disable=SC2086
        timeout 60 "$BENCH" -p "$NET_PORT" -o sample -b "$BATCH" -m traverse -f bilinear $shape \
            -d "$SECS" -w 0.5 -q -j "$f" >/dev/null || echo "net_sample: run '$shape' failed" >&2
        c1=$(net_daemon_cpu)
        if [ -s "$f" ]; then
            runs+=("$f")
            # queries the daemon answered per second of its own CPU time (warm-up included)
            awk -v c="$(awk -v a="$c0" -v b="$c1" 'BEGIN{print b - a}')" \
                -v n="$(net_json "$f" completed)" -v b="$BATCH" \
                'BEGIN{printf "%.1f\n", (c > 0 ? n * b / c : 0)}' >"$NET_TMP/cpu$i.$r"
        fi
        i=$((i + 1))
    done
done
rss=$(awk '/VmRSS/ {print $2}' /proc/"$NET_PID"/status)
net_stop || echo "net_sample: seamtexd did not exit 0" >&2
load1=$(net_load)

in1=$(med_of inproc1 queries_per_s)
in2=$(med_of inproc2 queries_per_s)
in1cpu=$(med_of inproc1 queries_per_cpu_s)
best=0 best_shape="" best_cpu=0
printf '\nnet_sample: SAMPLE %s bilinear traverse queries per request, default set, %s cores, load %s -> %s\n' \
    "$BATCH" "$(nproc)" "$load0" "$load1"
printf '%-40s %16s %12s %12s\n' "run" "queries/s" "req p50 us" "req p99 us"
printf '%-40s %16.0f   (%.0f per CPU-second)\n' "in-process st_sample_batch, 1 thread" "$in1" "$in1cpu"
printf '%-40s %16.0f\n' "in-process st_sample_batch, 2 threads" "$in2"
json_net=""
i=0
for shape in "${shapes[@]}"; do
    q=$(med_of net$i queries_per_s)
    p50=$(med_of net$i corrected_us p50)
    p99=$(med_of net$i corrected_us p99)
    vals=()
    for c in "$NET_TMP"/cpu$i.*; do [ -s "$c" ] && vals+=("$(cat "$c")"); done
    qcpu=$([ ${#vals[@]} -gt 0 ] && net_median "${vals[@]}" || echo 0)
    printf '%-40s %16.0f %12.0f %12.0f   (%.0f per daemon CPU-second)\n' \
        "seamtexd over loopback $shape" "$q" "$p50" "$p99" "$qcpu"
    json_net+="    {\"shape\": \"$shape\", \"queries_per_s\": $q, \"queries_per_daemon_cpu_s\": $qcpu, \"p50_us\": $p50, \"p99_us\": $p99},"$'\n'
    if awk -v a="$qcpu" -v b="$best_cpu" 'BEGIN{exit !(a > b)}'; then best_cpu=$qcpu; fi
    if awk -v a="$q" -v b="$best" 'BEGIN{exit !(a > b)}'; then best=$q; best_shape=$shape; fi
    i=$((i + 1))
done
r1=$(awk -v a="$best" -v b="$in1" 'BEGIN{printf "%.2f", (b > 0 ? a / b : 0)}')
r2=$(awk -v a="$best" -v b="$in2" 'BEGIN{printf "%.2f", (b > 0 ? a / b : 0)}')
rcpu=$(awk -v a="$best_cpu" -v b="$in1cpu" 'BEGIN{printf "%.2f", (b > 0 ? a / b : 0)}')
printf 'best network figure (%s): %.0f queries/s = %s x in-process 1 thread, %s x 2 threads (target >= 0.80)\n' \
    "$best_shape" "$best" "$r1" "$r2"
printf 'per CPU-second (independent of how much CPU the machine leaves us): daemon %.0f vs in-process %.0f queries = %s\n' \
    "$best_cpu" "$in1cpu" "$rcpu"
printf 'daemon RSS after the runs: %s kB\n' "$rss"

{
    echo "{"
    echo "  \"benchmark\": \"net_sample\","
    echo "  \"machine\": {\"cores\": $(nproc), \"loadavg_before\": $load0, \"loadavg_after\": $load1},"
    echo "  \"batch\": $BATCH, \"mode\": \"traverse\", \"filter\": \"bilinear\", \"reps\": $REPS, \"seconds\": $SECS,"
    echo "  \"inproc_1thread_queries_per_s\": $in1,"
    echo "  \"inproc_2threads_queries_per_s\": $in2,"
    echo "  \"network\": ["
    printf '%s' "${json_net%,$'\n'}"; echo
    echo "  ],"
    echo "  \"best_network_queries_per_s\": $best,"
    echo "  \"ratio_vs_inproc_1thread\": $r1,"
    echo "  \"ratio_vs_inproc_2threads\": $r2,"
    echo "  \"inproc_1thread_queries_per_cpu_s\": $in1cpu,"
    echo "  \"best_network_queries_per_daemon_cpu_s\": $best_cpu,"
    echo "  \"ratio_per_cpu_second\": $rcpu,"
    echo "  \"target_ratio\": 0.80,"
    echo "  \"daemon_rss_kb\": ${rss:-0},"
    echo "  \"runs\": ["
    sep=""
    for f in "${runs[@]}"; do printf '%s' "$sep"; sed 's/^/    /' "$f"; sep=","; done
    echo "  ]"
    echo "}"
} >"$OUT"
echo "net_sample: wrote $OUT"
