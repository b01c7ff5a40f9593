#!/usr/bin/env bash
# tests/bench/net_idle.sh OUT.json - what idle connections cost seamtexd: the daemon's RSS
# before and while NET_IDLE (default 10000) connections are open, each having done HELLO,
# then a PING round trip on a fresh connection to show the server still answers. The soft
# open-file limit is raised as far as the hard limit allows (both processes need one fd per
# connection). Writes OUT.json.
set -u
OUT=${1:?usage: net_idle.sh OUT.json}
source "$(dirname "$0")/net_common.inc"
net_need
N=${NET_IDLE:-10000}
hard=$(ulimit -Hn)
if [ "$hard" != unlimited ] && [ "$hard" -lt $((N + 100)) ]; then
    N=$((hard - 100))
    echo "net_idle: hard open-file limit $hard: using $N connections"
fi
ulimit -Sn $((N + 100)) 2>/dev/null || ulimit -Sn "$hard"

load0=$(net_load)
net_start --max-conns $((N + 50)) --idle-timeout 0
rss() { awk '/VmRSS/ {print $2}' /proc/"$NET_PID"/status; }
rss0=$(rss)
hold=8
timeout 120 "$BENCH" -p "$NET_PORT" --idle "$N" --hold "$hold" >"$NET_TMP/idle.out" 2>&1 &
bpid=$!
opened=""
for _ in $(seq 1 600); do          # wait until every connection is open (up to 60 s)
    grep -q '^idle:' "$NET_TMP/idle.out" && { opened=$(sed -n 's/^idle: \([0-9]*\).*/\1/p' "$NET_TMP/idle.out"); break; }
    kill -0 "$bpid" 2>/dev/null || break
    sleep 0.1
done
sleep 1
rss1=$(rss)
# a PING on one more connection while they are held
t0=$(date +%s%N)
"$BENCH" -p "$NET_PORT" -n 20 -d 2 -w 0 -q -j "$NET_TMP/ping.json" >/dev/null 2>&1
ping_ok=$?
ping_p50=$(net_json "$NET_TMP/ping.json" corrected_us p50 2>/dev/null)
wait "$bpid"
brc=$?
sleep 1
rss2=$(rss)
net_stop || echo "net_idle: seamtexd did not exit 0" >&2
load1=$(net_load)
opened=${opened:-0}
per=$(awk -v a="$rss0" -v b="$rss1" -v n="$opened" 'BEGIN{printf "%.2f", (n > 0 ? (b - a) / n : 0)}')

printf '\nnet_idle: %s idle connections, %s cores, load %s -> %s\n' "$opened" "$(nproc)" "$load0" "$load1"
printf '%-44s %10s kB\n' "daemon RSS before" "$rss0"
printf '%-44s %10s kB\n' "daemon RSS with the connections open" "$rss1"
printf '%-44s %10s kB\n' "daemon RSS after they closed" "$rss2"
printf '%-44s %10s kB\n' "per idle connection" "$per"
printf '%-44s %10s\n' "PING while held (p50 us)" "${ping_p50:-failed}"
[ "$brc" -eq 0 ] || echo "net_idle: the idle client failed: $(tail -2 "$NET_TMP/idle.out")"

cat >"$OUT" <<JSON
{
  "benchmark": "net_idle",
  "machine": {"cores": $(nproc), "loadavg_before": $load0, "loadavg_after": $load1},
  "connections_requested": $N,
  "connections_open": $opened,
  "rss_before_kb": ${rss0:-0},
  "rss_open_kb": ${rss1:-0},
  "rss_after_kb": ${rss2:-0},
  "kb_per_connection": $per,
  "ping_while_held_ok": $([ "$ping_ok" -eq 0 ] && echo true || echo false),
  "ping_while_held_p50_us": ${ping_p50:-0}
}
JSON
echo "net_idle: wrote $OUT"
[ "$brc" -eq 0 ] && [ "$opened" -eq "$N" ]
