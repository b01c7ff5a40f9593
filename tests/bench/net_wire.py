#!/usr/bin/env python3
"""tests/bench/net_wire.py OUT.json - SAMPLE over the wire against the in-process sampler
(issue: "sampling over the wire at in-process speed"), run by net_wire.sh (make bench).

Per batch size (NET_BATCHES, default 256,1024,4096,16384) and encoding (f32: 28-byte queries
and f32 replies; compact: 14-byte UV16+FACE16 queries and f16 replies, PROTOCOL.md 4.4.1):
  - in-process st_sample_batch with 1 and 2 threads (seamtex-bench --inproc -T 1 / -T 2);
  - seamtexd over TCP loopback and over a Unix socket, with 1 and 2 connections (-P 2 each:
    NET_PIPELINE, below),
    and over the Unix socket with shared memory ("unix+shm": seamtex-bench --shm, PROTOCOL.md
    4.12: the queries and replies in a sealed memfd, small frames on the socket), run in the
    same daemon right after the plain Unix run of each batch, encoding and connection count
    (with NET_WIRE_BASE also "base-unix+shm" on the base daemon, and unix+shm's ratios to it;
    with NET_WIRE_SHM_COPY=1 also "unix+shmcp": seamtex-bench --shm-copy, the queries copied
    into the region per request);
  - ratios to the in-process figure at the same total thread count (1 connection vs 1 thread,
    2 connections vs 2 threads), and the daemon's CPU per query: utime + stime from
    /proc/<pid>/stat (sampled every 20 ms, read at the edges of the load tester's measured
    window) over the queries recorded in that window, against the in-process CPU per query;
  - the load tester's CPU per query (column "client": its user + system time over the same
    window, from its JSON, cpu_window_s / queries_measured) and "bound": the in-process CPU
    per query (same thread count) over daemon + client CPU per query, the ratio the run could
    reach if the two had the cores to themselves (both run on the same cores: the client's
    share and the daemon's extra CPU are what cap the ratio, whatever the machine's load);
    column "cl-run": the load tester's CPU over its whole process (start-up, connecting, its
    request pools, --shm's region, warm-up and drain) over every query answered, the figure
    this column gave before session 22 and the only one an older load tester allows (its rows
    fall back to whole-run figures everywhere); "cs/rq": the load tester's context switches
    per request in the window (each one a wake-up that preempts a daemon thread);
With NET_PIPELINE=2,8 (default 2) every wire run is made at each of those pipeline depths
(seamtex-bench -P: requests in flight per connection), one after the other on the same daemon,
and the table has a row per depth (column P); the in-process figures do not depend on it. A
deeper pipeline is how a client hides the round trip of small batches (256 queries: ~15 us of
sampling against a wakeup and a send each way); at 4096 and up -P 2 already keeps the daemon busy.
and PING: closed-loop capacity (8 connections x pipeline 16) and open-loop p50/p99 at 20k
req/s (8 connections).

A/B: with NET_WIRE_BASE=/path/to/an/older/seamtexd the same runs (TCP and Unix, both
encodings) are made against that binary too, driven by NET_WIRE_BASE_BENCH (an older
seamtex-bench; default: this one; NET_WIRE_BENCH_ARGS adds flags to this tree's load tester
only, e.g. "--lowat 0"), and with NET_WIRE_ALT_ARGS="--flag value ..." against this
daemon started with those flags; the variants alternate A B A B inside each repetition, so
before/after figures come from one window of the machine's load. Every figure is the median of NET_REPS repetitions (default 3) of NET_SECS seconds
(default 2) after a 0.5 s warm-up; the machine's load average is recorded before and after.
The client runs on the same cores as the daemon: throughput ratios on a loaded 2-core
machine say less than the CPU-per-query ratio, which does not depend on how much CPU the
machine leaves us.
"""
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
B = os.path.join(ROOT, os.environ.get('B', 'build'))
DAEMON = os.path.join(B, 'seamtexd')
BENCH = os.path.join(B, 'seamtex-bench')
BASE = os.environ.get('NET_WIRE_BASE', '')
BASE_BENCH = os.environ.get('NET_WIRE_BASE_BENCH', '')
ALT_ARGS = os.environ.get('NET_WIRE_ALT_ARGS', '').split()
# extra seamtex-bench flags for the SAMPLE runs of this tree's load tester (not the base's),
# e.g. NET_WIRE_BENCH_ARGS="--lowat 0" to measure the daemon change without the client's
BENCH_ARGS = os.environ.get('NET_WIRE_BENCH_ARGS', '').split()
REPS = int(os.environ.get('NET_REPS', '3'))
SECS = os.environ.get('NET_SECS', '2')
BATCHES = [int(x) for x in os.environ.get('NET_BATCHES', '256,1024,4096,16384').split(',')]
ENCODINGS = {'f32': [], 'compact': ['--compact', '--outfmt', 'f16']}
# NET_ENCODINGS=f32 / NET_VARIANTS=unix narrow a run (e.g. to A/B unix against unix+shm only)
ENCODINGS = {k: v for k, v in ENCODINGS.items()
             if k in os.environ.get('NET_ENCODINGS', 'f32,compact').split(',')}
VARIANTS = os.environ.get('NET_VARIANTS', 'tcp,unix').split(',')
SHM = os.environ.get('NET_WIRE_SHM', '1') != '0'    # the unix+shm column (0: leave it out)
# the unix+shmcp column (seamtex-bench --shm-copy: queries copied into the region per request)
SHM_COPY = os.environ.get('NET_WIRE_SHM_COPY', '0') != '0'
# NET_PIPELINE=2,8: the wire runs at each pipeline depth (-P), a table row per depth
PIPELINES = [int(x) for x in os.environ.get('NET_PIPELINE', '2').split(',')]
TCK = os.sysconf('SC_CLK_TCK')


def load():
    return float(open('/proc/loadavg').read().split()[0])


def cpu_s(pid):
    f = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
    return (int(f[11]) + int(f[12])) / TCK


class CpuTrace(threading.Thread):
    """The daemon's CPU (utime + stime, /proc/<pid>/stat) every 20 ms while a load tester runs,
    so that it can be read at the edges of the load tester's measured window (its JSON gives
    them as CLOCK_MONOTONIC ns, the clock of time.monotonic_ns), interpolated between the two
    samples around each edge."""

    def __init__(self, pid):
        super().__init__(daemon=True)
        self.pid, self.samples, self.stop_ev = pid, [], threading.Event()

    def run(self):
        while True:
            self.samples.append((time.monotonic_ns(), cpu_s(self.pid)))
            if self.stop_ev.wait(0.02):
                self.samples.append((time.monotonic_ns(), cpu_s(self.pid)))
                return

    def stop(self):
        self.stop_ev.set()
        self.join()

    def at(self, t):
        s = self.samples
        for (t0, c0), (t1, c1) in zip(s, s[1:]):
            if t0 <= t <= t1:
                return c0 + (c1 - c0) * (t - t0) / (t1 - t0) if t1 > t0 else c0
        return None


class Daemon:
    def __init__(self, exe, unix, args=(), bench_exe=BENCH):
        self.bench = bench_exe
        self.dir = tempfile.mkdtemp(prefix='seamtex-netwire.')
        listen = f'unix:{self.dir}/s.sock' if unix else '127.0.0.1:0'
        port = os.path.join(self.dir, 'port')
        self.p = subprocess.Popen([exe, '--listen', listen, '--data-dir', self.dir + '/data',
                                   '--port-file', port, '--log-level', 'warn'] + list(args),
                                  stderr=open(self.dir + '/log', 'w'))
        for _ in range(600):
            if self.p.poll() is not None:
                sys.exit(f'net_wire: {exe} died at start: ' + open(self.dir + '/log').read()[-500:])
            if os.path.exists(port) and os.path.getsize(port) > 0:
                break
            time.sleep(0.05)
        self.addr = ['-h', listen] if unix else ['-p', open(port).read().strip()]
        # readiness: one PING
        bench(self.addr + ['-n', '1', '-d', '1', '-w', '0'], self.bench)

    def stop(self):
        self.p.terminate()
        self.p.wait(timeout=30)
        subprocess.run(['rm', '-rf', self.dir])


def children_cpu_s():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def bench(args, exe=BENCH):
    with tempfile.NamedTemporaryFile(suffix='.json') as j:
        c0 = children_cpu_s()
        r = subprocess.run([exe] + args + ['-q', '-j', j.name], capture_output=True,
                           text=True, timeout=300)
        try:
            doc = json.load(open(j.name))
            # the load tester's own CPU (user + system, warm-up and connect included)
            doc['_client_cpu_s'] = children_cpu_s() - c0
            return doc
        except (ValueError, OSError):
            print('net_wire: run failed:', ' '.join(args), r.stderr[-300:], file=sys.stderr)
            return None


raw = {}


def add(key, val):
    raw.setdefault(key, []).append(val)


def sample_run(d, name, batch, enc, conns, pipe, extra=()):
    c0 = cpu_s(d.p.pid)
    trace = CpuTrace(d.p.pid)
    trace.start()
    j = bench(d.addr + ['-o', 'sample', '-b', str(batch), '-m', 'traverse', '-f', 'bilinear',
                        '-c', str(conns), '-T', str(conns), '-P', str(pipe), '-d', SECS,
                        '-w', '0.5']
              + ENCODINGS[enc] + list(extra) + (BENCH_ARGS if d.bench == BENCH else []),
              d.bench)
    trace.stop()
    c1 = cpu_s(d.p.pid)
    if not j:
        return
    served = j.get('completed', 0) * batch
    k = (batch, enc, name, conns, pipe)
    add((*k, 'qps'), j.get('queries_per_s', 0))
    if served:
        # whole run: every query answered against the CPU of the whole load-tester process
        # (start-up, connecting, the pools, --shm's region, warm-up and drain included)
        add((*k, 'ns_cpu_run'), (c1 - c0) * 1e9 / served)
        add((*k, 'ns_client_run'), j['_client_cpu_s'] * 1e9 / served)
    # the measured window (a load tester that reports it): both processes' CPU from the end of
    # the warm-up to the end of the run over the queries recorded in it - the steady state,
    # which is what the in-process figure is too (its set loaded before its clock starts)
    qw = j.get('queries_measured', 0)
    dw0 = trace.at(j.get('window_start_ns', -1))
    dw1 = trace.at(j.get('window_end_ns', -1))
    if qw and 'cpu_window_s' in j and dw0 is not None and dw1 is not None:
        add((*k, 'ns_cpu'), (dw1 - dw0) * 1e9 / qw)
        add((*k, 'ns_client'), j['cpu_window_s'] * 1e9 / qw)
        req = qw / batch
        add((*k, 'client_csw'), (j.get('vcsw_window', 0) + j.get('ivcsw_window', 0)) / req)
    elif served:
        add((*k, 'ns_cpu'), (c1 - c0) * 1e9 / served)
        add((*k, 'ns_client'), j['_client_cpu_s'] * 1e9 / served)
    if j.get('errors'):
        print(f'net_wire: {name} {enc} batch {batch}: {j["errors"]} error replies',
              file=sys.stderr)


def ping_runs(d, name):
    j = bench(d.addr + ['-o', 'ping', '-c', '8', '-T', '1', '-P', '16', '-d', SECS, '-w', '0.5'],
              d.bench)
    if j:
        add(('ping', name, 'capacity'), j.get('achieved_rate', 0))
    j = bench(d.addr + ['-o', 'ping', '-c', '8', '-T', '1', '-r', '20000', '-d', SECS, '-w', '0.5'],
              d.bench)
    if j:
        c = j.get('corrected_us', {})
        add(('ping', name, 'p50_us'), c.get('p50', 0))
        add(('ping', name, 'p99_us'), c.get('p99', 0))


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(B, 'bench', 'net_wire.json')
    for exe in (DAEMON, BENCH):
        if not os.access(exe, os.X_OK):
            sys.exit(f'net_wire: {exe} is missing (make first)')
    load0 = load()
    # (name, daemon, unix socket, daemon flags, load tester)
    variants = [v for v in [('tcp', DAEMON, False, [], BENCH), ('unix', DAEMON, True, [], BENCH)]
                if v[0] in VARIANTS]
    if BASE:
        bb = BASE_BENCH or BENCH
        variants[:0] = [('base-tcp', BASE, False, [], bb), ('base-unix', BASE, True, [], bb)]
    if ALT_ARGS:
        variants += [('alt-tcp', DAEMON, False, ALT_ARGS, BENCH),
                     ('alt-unix', DAEMON, True, ALT_ARGS, BENCH)]
    for rep in range(REPS):
        for batch in BATCHES:
            for t in (1, 2):
                j = bench(['--inproc', '-T', str(t), '-b', str(batch), '-m', 'traverse', '-f',
                           'bilinear', '-d', SECS, '-w', '0.5'])
                if j:
                    add((batch, 'inproc', t, 'qps'), j.get('queries_per_s', 0))
                    q = j.get('queries_per_cpu_s', 0)
                    add((batch, 'inproc', t, 'ns_cpu'), 1e9 / q if q else 0)
        for name, exe, unix, args, bexe in variants:
            d = Daemon(exe, unix, args, bexe)
            try:
                for batch in BATCHES:
                    for enc in ENCODINGS:
                        for conns in (1, 2):
                            for pipe in PIPELINES:
                                sample_run(d, name, batch, enc, conns, pipe)
                                if unix and SHM and name in ('unix', 'base-unix'):
                                    # A B in the same window: plain Unix, then with shared
                                    # memory
                                    sample_run(d, name + '+shm', batch, enc, conns, pipe,
                                               ['--shm'])
                                if unix and SHM and SHM_COPY and name == 'unix':
                                    # the queries copied into the region per request
                                    sample_run(d, 'unix+shmcp', batch, enc, conns, pipe,
                                               ['--shm-copy'])
                if not unix:
                    ping_runs(d, name)
            finally:
                d.stop()
        print(f'net_wire: repetition {rep + 1}/{REPS} done, load {load()}', file=sys.stderr,
              flush=True)
    load1 = load()
    med = {k: statistics.median(v) for k, v in raw.items()}

    rows = []
    print(f'\nnet_wire: SAMPLE bilinear traverse on the default set, -P '
          f'{",".join(map(str, PIPELINES))} per connection, '
          f'{os.cpu_count()} cores, load {load0} -> {load1}, medians of {REPS}')
    print(f"{'batch':>6} {'enc':<8} {'run':<10} {'conns':>5} {'P':>3} {'Mq/s':>8} "
          f"{'x inproc':>9} {'ns CPU/q':>9} {'x inproc':>9} {'client':>7} {'bound':>6} "
          f"{'cl-run':>7} {'cs/rq':>6}")
    for batch in BATCHES:
        for t in (1, 2):
            q = med.get((batch, 'inproc', t, 'qps'), 0)
            ns = med.get((batch, 'inproc', t, 'ns_cpu'), 0)
            print(f"{batch:>6} {'-':<8} {'inproc':<10} {t:>5} {'-':>3} {q / 1e6:8.2f} {'':>9} "
                  f"{ns:9.1f}")
            rows.append(dict(batch=batch, encoding='-', run='inproc', threads=t,
                             queries_per_s=q, ns_cpu_per_query=ns))
        for enc in ENCODINGS:
            names = [v[0] for v in variants]
            for u in ('unix', 'base-unix'):
                if SHM and u in names:
                    names.insert(names.index(u) + 1, u + '+shm')
            if SHM and SHM_COPY and 'unix' in names:
                names.insert(names.index('unix+shm') + 1, 'unix+shmcp')
            for name, conns, pipe in [(n, c, p) for n in names for c in (1, 2)
                                      for p in PIPELINES]:
                k = (batch, enc, name, conns, pipe)
                if (*k, 'qps') not in med:
                    continue
                q = med[(*k, 'qps')]
                ns = med.get((*k, 'ns_cpu'), 0)
                ncl = med.get((*k, 'ns_client'), 0)
                ncl_run = med.get((*k, 'ns_client_run'), 0)
                csw = med.get((*k, 'client_csw'))
                iq = med.get((batch, 'inproc', conns, 'qps'), 0)
                ins = med.get((batch, 'inproc', 1, 'ns_cpu'), 0)
                ins_t = med.get((batch, 'inproc', conns, 'ns_cpu'), 0)
                rq = q / iq if iq else 0
                rc = ns / ins if ins else 0
                # the ratio this run could reach if the daemon and the load tester had the
                # cores the in-process run has, all to themselves: in-process CPU per query
                # over daemon + client CPU per query (both measured, same thread count)
                bound = ins_t / (ns + ncl) if ns + ncl > 0 else 0
                print(f"{batch:>6} {enc:<8} {name:<10} {conns:>5} {pipe:>3} {q / 1e6:8.2f} "
                      f"{rq:9.2f} {ns:9.1f} {rc:9.2f} {ncl:7.1f} {bound:6.2f} {ncl_run:7.1f} "
                      + (f"{csw:6.2f}" if csw is not None else f"{'-':>6}"))
                row = dict(batch=batch, encoding=enc, run=name, conns=conns, pipeline=pipe,
                           queries_per_s=q, ratio_vs_inproc_same_threads=rq,
                           ns_daemon_cpu_per_query=ns, cpu_ratio_vs_inproc=rc,
                           ns_client_cpu_per_query=ncl, ratio_bound_from_cpu=bound,
                           ns_daemon_cpu_per_query_run=med.get((*k, 'ns_cpu_run'), 0),
                           ns_client_cpu_per_query_run=ncl_run,
                           client_switches_per_request=csw)
                # the A/Bs of the shared-memory path: against plain Unix of the same
                # daemon (same window), and against the base daemon's shared memory
                refs = [('unix', 'vs unix')] if name in ('unix+shm', 'unix+shmcp') else []
                refs += ([('base-unix+shm', 'vs base')] if name in ('unix+shm', 'unix+shmcp')
                         else [])
                refs += [('base-unix', 'vs unix')] if name == 'base-unix+shm' else []
                for ref, label in refs:
                    uq = med.get((batch, enc, ref, conns, pipe, 'qps'), 0)
                    uns = med.get((batch, enc, ref, conns, pipe, 'ns_cpu'), 0)
                    if not (uq and uns):
                        continue
                    key = 'vs_base_shm' if ref == 'base-unix+shm' else 'vs_unix'
                    row['ratio_' + key] = q / uq
                    row['cpu_ratio_' + key] = ns / uns
                    print(f"{'':>6} {'':<8} {'  ' + label:<10} {'':>5} {'':>3} {'':>8} "
                          f"{q / uq:9.2f} "
                          f"{'':>9} {ns / uns:9.2f}")
                rows.append(row)
    ping = {}
    for name, _, unix, _, _ in variants:
        if unix:
            continue
        ping[name] = {m: med.get(('ping', name, m), 0) for m in ('capacity', 'p50_us', 'p99_us')}
        print(f"PING {name:<9} capacity {ping[name]['capacity']:.0f} req/s (8 x P16); "
              f"open loop 20k req/s: p50 {ping[name]['p50_us']:.0f} us, "
              f"p99 {ping[name]['p99_us']:.0f} us")
    doc = {'benchmark': 'net_wire', 'machine': {'cores': os.cpu_count(), 'loadavg_before': load0,
                                                'loadavg_after': load1},
           'reps': REPS, 'seconds': float(SECS), 'mode': 'traverse', 'filter': 'bilinear',
           'pipeline': PIPELINES, 'base_daemon': BASE or None, 'base_bench': BASE_BENCH or None,
           'alt_args': ALT_ARGS or None,
           'shm': SHM, 'shm_copy': SHM_COPY,
           'encodings': {'f32': '28-byte queries, f32 replies',
                         'compact': '14-byte queries (UV16 | FACE16), f16 replies'},
           'targets': {'ratio_at_4096_and_up': 0.8, 'ratio_at_256': 0.5,
                       'cpu_ratio_at_4096_and_up': 1.2, 'unix_ratio': 0.9},
           'rows': rows, 'ping': ping,
           'raw': [{'key': [str(x) for x in k], 'values': v} for k, v in raw.items()]}
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, 'w') as f:
        json.dump(doc, f, indent=1)
    print(f'net_wire: wrote {out}')


if __name__ == '__main__':
    main()
