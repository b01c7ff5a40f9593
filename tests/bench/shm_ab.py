#!/usr/bin/env python3
"""tests/bench/shm_ab.py OUT.json - shared-memory SAMPLE, A/B in short alternating runs.

net_wire.py runs each variant for seconds at a time, one daemon after the other; on a loaded
shared machine the daemon's CPU per query then swings by 2x between runs, more than the
effect of a change in the shared-memory path. This script keeps every daemon up for the
whole run and cycles through the variants with short runs (SHM_AB_SECS, default 1 s, after a
0.2 s warm-up), SHM_AB_ROUNDS times (default 15), so the runs of one round are seconds apart;
it reports medians of the per-round ratios (A and B of one round share the machine's state).

Variants, per batch (SHM_AB_BATCHES, default 1024,4096,16384) and connection count (1, 2;
-P 2 each), bilinear Traverse, f32 queries and replies:
  inproc   seamtex-bench --inproc -T conns (the in-process sampler, the target);
  base     the base daemon (SHM_AB_BASE, a seamtexd) driven by SHM_AB_BASE_BENCH --shm;
  shmcp    this daemon, seamtex-bench --shm-copy (queries copied into the region per request);
  shm      this daemon, seamtex-bench --shm (queries written once: zero copy);
  unix     this daemon, plain Unix socket.
The daemon's CPU per query is utime + stime from /proc over the queries served. The machine's
load average is recorded before and after.
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
B = os.path.join(ROOT, os.environ.get('B', 'build'))
DAEMON = os.path.join(B, 'seamtexd')
BENCH = os.path.join(B, 'seamtex-bench')
BASE = os.environ.get('SHM_AB_BASE', '')
BASE_BENCH = os.environ.get('SHM_AB_BASE_BENCH', '') or BENCH
ROUNDS = int(os.environ.get('SHM_AB_ROUNDS', '15'))
SECS = os.environ.get('SHM_AB_SECS', '1')
BATCHES = [int(x) for x in os.environ.get('SHM_AB_BATCHES', '1024,4096,16384').split(',')]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from net_wire import cpu_s, load  # noqa: E402  (one reader of /proc for both benches)


def bench(exe, args):
    with tempfile.NamedTemporaryFile(suffix='.json') as j:
        r = subprocess.run([exe] + args + ['-q', '-j', j.name], capture_output=True, text=True,
                           timeout=120)
        try:
            return json.load(open(j.name))
        except (ValueError, OSError):
            print('shm_ab: run failed:', ' '.join(args), r.stderr[-300:], file=sys.stderr)
            return None


class Daemon:
    def __init__(self, exe):
        self.dir = tempfile.mkdtemp(prefix='seamtex-shmab.')
        self.sock = f'unix:{self.dir}/s.sock'
        port = os.path.join(self.dir, 'port')
        self.p = subprocess.Popen([exe, '--listen', self.sock, '--data-dir', self.dir + '/data',
                                   '--port-file', port, '--log-level', 'warn'],
                                  stderr=open(self.dir + '/log', 'w'))
        for _ in range(600):
            if self.p.poll() is not None:
                sys.exit(f'shm_ab: {exe} died at start')
            if os.path.exists(port) and os.path.getsize(port) > 0:
                break
            time.sleep(0.05)

    def stop(self):
        self.p.terminate()
        self.p.wait(timeout=30)
        subprocess.run(['rm', '-rf', self.dir])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(B, 'bench', 'shm_ab.json')
    load0 = load()
    new = Daemon(DAEMON)
    base = Daemon(BASE) if BASE else None
    common = ['-o', 'sample', '-m', 'traverse', '-f', 'bilinear', '-P', '2', '-d', SECS,
              '-w', '0.2']
    variants = [('inproc', None, BENCH, ['--inproc'])]
    if base:
        variants.append(('base', base, BASE_BENCH, ['--shm']))
    variants += [('shmcp', new, BENCH, ['--shm-copy']), ('shm', new, BENCH, ['--shm']),
                 ('unix', new, BENCH, [])]
    raw = {}
    try:
        for rnd in range(ROUNDS):
            for batch in BATCHES:
                for conns in (1, 2):
                    for name, d, exe, extra in variants:
                        args = common + ['-b', str(batch), '-T', str(conns)] + extra
                        if d:
                            args += ['-h', d.sock, '-c', str(conns)]
                            c0 = cpu_s(d.p.pid)
                        j = bench(exe, args)
                        if not j:
                            continue
                        key = (batch, conns, name)
                        raw.setdefault(key + ('qps',), []).append(j.get('queries_per_s', 0))
                        if d:
                            served = j.get('completed', 0) * batch
                            ns = (cpu_s(d.p.pid) - c0) * 1e9 / served if served else 0
                        else:
                            q = j.get('queries_per_cpu_s', 0)
                            ns = 1e9 / q if q else 0
                        raw.setdefault(key + ('ns',), []).append(ns)
            print(f'shm_ab: round {rnd + 1}/{ROUNDS}, load {load()}', file=sys.stderr, flush=True)
    finally:
        new.stop()
        if base:
            base.stop()
    load1 = load()
    names = [v[0] for v in variants]

    def ratio(batch, conns, a, b, m):
        xa, xb = raw.get((batch, conns, a, m), []), raw.get((batch, conns, b, m), [])
        rs = [x / y for x, y in zip(xa, xb) if y]
        return statistics.median(rs) if rs else 0

    print(f'\nshm_ab: f32 bilinear traverse, -P 2, {ROUNDS} rounds of {SECS} s, load {load0} -> '
          f'{load1}; medians, and medians of per-round ratios')
    print(f"{'batch':>6} {'conns':>5} {'run':<7} {'Mq/s':>7} {'ns CPU/q':>9} {'q/s x inproc':>13} "
          f"{'CPU x inproc':>13} {'q/s x base':>11} {'CPU x base':>11}")
    rows = []
    for batch in BATCHES:
        for conns in (1, 2):
            for name in names:
                q = raw.get((batch, conns, name, 'qps'))
                ns = raw.get((batch, conns, name, 'ns'))
                if not q:
                    continue
                row = dict(batch=batch, conns=conns, run=name,
                           queries_per_s=statistics.median(q), ns_cpu_per_query=statistics.median(ns),
                           qps_vs_inproc=ratio(batch, conns, name, 'inproc', 'qps'),
                           cpu_vs_inproc=ratio(batch, conns, name, 'inproc', 'ns'),
                           qps_vs_base=ratio(batch, conns, name, 'base', 'qps') if base else 0,
                           cpu_vs_base=ratio(batch, conns, name, 'base', 'ns') if base else 0)
                rows.append(row)
                print(f"{batch:>6} {conns:>5} {name:<7} {row['queries_per_s'] / 1e6:7.2f} "
                      f"{row['ns_cpu_per_query']:9.1f} {row['qps_vs_inproc']:13.2f} "
                      f"{row['cpu_vs_inproc']:13.2f} {row['qps_vs_base']:11.2f} "
                      f"{row['cpu_vs_base']:11.2f}")
    doc = {'benchmark': 'shm_ab', 'rounds': ROUNDS, 'seconds': float(SECS),
           'machine': {'cores': os.cpu_count(), 'loadavg_before': load0, 'loadavg_after': load1},
           'base_daemon': BASE or None, 'base_bench': BASE_BENCH, 'rows': rows,
           'raw': [{'key': [str(x) for x in k], 'values': v} for k, v in raw.items()]}
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, 'w') as f:
        json.dump(doc, f, indent=1)
    print(f'shm_ab: wrote {out}')


if __name__ == '__main__':
    main()
