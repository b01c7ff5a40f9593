#!/usr/bin/env bash
# tests/bench/net_wire.sh OUT.json - SAMPLE over TCP and a Unix socket, f32 and compact, against
# the in-process sampler, with the daemon's CPU per query, and PING capacity / latency; see
# tests/bench/net_wire.py (the runs, the table, the JSON; NET_WIRE_BASE=older seamtexd and
# NET_WIRE_BASE_BENCH=its seamtex-bench for an A/B in the same window).
set -u
exec python3 "$(dirname "$0")/net_wire.py" "$@"
