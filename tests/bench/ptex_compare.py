#!/usr/bin/env python3
"""tests/bench/ptex_compare.py - seamtex against the Ptex library, cell by cell (issue 17:
"every filter at least 3x Ptex's throughput ... import at least 2x faster").

Ptex is not in Debian and is never part of this repository: build it yourself, then build the
two harnesses of tests/bench/ptexcmp/ against it (`make ptex-compare PTEX_PREFIX=/usr/local`
does both that and this run):
  ptexq     times PtexFilter::eval on a query file, grouped as `bench_ptex --queries` groups
            them (per filter, its lines in file order as one batch, thread CPU time);
  ptexopen  times PtexTexture::open + getData of every face's level 0 in a fresh process.

What it does:
  1. `bench_ptex --emit-queries DIR` writes the sampling tables' queries (every shared .ptx, or
     --files; footprints --fp; orders --order) as query files, 4096 lines per filter;
  2. per query file, --rounds rounds of ptexq then `bench_ptex --queries` (A B A B: both in the
     same window of the machine's load), per filter the ratio seamtex / Ptex of M queries/s,
     the median of the per-round ratios;
  3. per .ptx (unless --no-import), --rounds rounds of ptexopen then `bench_ptex --import-only`
     (both a fresh process per run, process CPU time, median of --import-reps runs): the ratio
     Ptex ms / seamtex ms.
Prints one table per (order, footprint): file x filter ratios; then per file x filter the
worst cell and how many cells are under 3x; the import ratios; writes everything to --json.

usage: ptex_compare.py --ptexq PATH --ptexopen PATH [--bench build/bench/bench_ptex]
                       [--files a,b] [--filters f,..] [--fp 0.25,4,16] [--order both]
                       [--rounds 3] [--reps 3] [--min-ms 15] [--import-reps 9] [--no-import]
                       [--json OUT]
SEAMTEX_DATA as for the other benchmarks (default ../shared/data).
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
FILTERS = ['point', 'bilinear', 'box', 'gaussian', 'bicubic', 'bspline', 'catmullrom',
           'mitchell']
ROW = re.compile(r'^(\w+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)')


def per_filter(text):
    """M queries/s per filter from ptexq's or bench_ptex --queries' table"""
    d = {}
    for line in text.splitlines():
        m = ROW.match(line)
        if m and m.group(1) in FILTERS + ['all']:
            d[m.group(1)] = float(m.group(3))
    return d


def run(cmd, env):
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    if r.returncode:
        sys.exit(f'ptex_compare: {" ".join(cmd)} failed: {r.stderr[-400:]}')
    return r.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--ptexq', required=True)
    ap.add_argument('--ptexopen', required=True)
    ap.add_argument('--bench', default=os.path.join(ROOT, 'build', 'bench', 'bench_ptex'))
    ap.add_argument('--files', default='')
    ap.add_argument('--filters', default=','.join(FILTERS))
    ap.add_argument('--fp', default='0.25,4,16')
    ap.add_argument('--order', default='both')
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--reps', type=int, default=3)
    ap.add_argument('--min-ms', default='15')
    ap.add_argument('--import-reps', type=int, default=9)
    ap.add_argument('--no-import', action='store_true')
    ap.add_argument('--json', default='')
    a = ap.parse_args()
    data = os.environ.get('SEAMTEX_DATA', os.path.join(ROOT, '..', 'shared', 'data'))
    env = dict(os.environ, SEAMTEX_DATA=data)
    qdir = tempfile.mkdtemp(prefix='seamtex-ptexcmp.')
    try:
        emit = [a.bench, '--emit-queries', qdir, '--filters', a.filters, '--fp', a.fp,
                '--order', a.order]
        if a.files:
            emit += ['--files', a.files]
        run(emit, env)
        index = [line.split() for line in open(os.path.join(qdir, 'index.txt'))]   # qf rel name
        cells = {}   # (file, order, fp) -> filter -> [ratios]
        raw = []
        for qf, rel, _ in index:
            m = re.match(r'(.*)_(random|coherent)_fp([\d.]+)\.txt$', qf)
            key = m.groups()
            ptx, path = os.path.join(data, rel), os.path.join(qdir, qf)
            for r in range(a.rounds):
                p = per_filter(run([a.ptexq, ptx, path, '--reps', str(a.reps), '--min-ms',
                                    a.min_ms], env))
                s = per_filter(run([a.bench, '--queries', path, '--ptx', ptx, '--modes',
                                    'traverse', '--reps-sample', str(a.reps), '--min-ms',
                                    a.min_ms], env))
                for f in p:
                    if f in s and p[f] > 0:
                        cells.setdefault(key, {}).setdefault(f, []).append(s[f] / p[f])
                        raw.append(dict(file=key[0], order=key[1], footprint=float(key[2]),
                                        filter=f, round=r, ptex_mqps=p[f], seamtex_mqps=s[f]))
            print(f'{qf}: ' + ' '.join(f'{f} {statistics.median(v):.2f}'
                                      for f, v in cells.get(key, {}).items()), flush=True)
        med = {k: {f: statistics.median(v) for f, v in d.items()} for k, d in cells.items()}
        filt = [f for f in FILTERS if f in a.filters.split(',')]
        files = sorted({k[0] for k in med})
        for order in ('random', 'coherent'):
            for fp in sorted({k[2] for k in med}, key=float):
                if not any(k[1] == order and k[2] == fp for k in med):
                    continue
                print(f'\nseamtex / Ptex, M queries/s ratio, Traverse, {order} order, '
                      f'footprint {fp} texels (median of {a.rounds} alternated rounds)')
                print(f'{"file":22s}' + ''.join(f'{f[:10]:>11s}' for f in filt))
                for n in files:
                    d = med.get((n, order, fp), {})
                    print(f'{n:22s}' + ''.join(f'{d[f]:11.2f}' if f in d else f'{"-":>11s}'
                                               for f in filt))
        under = sum(1 for d in med.values() for f in filt if f in d and d[f] < 3)
        total = sum(1 for d in med.values() for f in filt if f in d)
        print('\nworst cell per file and filter (over footprints and orders)')
        print(f'{"file":22s}' + ''.join(f'{f[:10]:>11s}' for f in filt))
        for n in files:
            print(f'{n:22s}' + ''.join(
                f'{min(d[f] for k, d in med.items() if k[0] == n and f in d):11.2f}'
                for f in filt))
        print(f'cells under 3x: {under} of {total}')
        imports = {}
        if not a.no_import:
            print('\nimport: Ptex open + level-0 getData / seamtex st_ptex_read_file, process CPU '
                  'ms in a fresh process (median of runs); ratio = seamtex\'s speed-up')
            for rel, name in sorted({(rel, name) for _, rel, name in index}):
                ptx, rr = os.path.join(data, rel), []
                for r in range(a.rounds):
                    out = run([a.ptexopen, ptx, '--reps', str(a.import_reps)], env)
                    pm = float(re.search(r'fresh_cpu_ms=([\d.]+)', out).group(1))
                    jf = os.path.join(qdir, 'import.json')
                    run([a.bench, '--import-only', '--files', '=' + name,
                         '--reps', str(a.import_reps), '--json', jf], env)
                    sm = [e for e in json.load(open(jf))['import']][0]['fresh_cpu_ms']
                    rr.append((pm, sm, pm / sm))
                imports[name] = rr
                print(f'{name:22s} Ptex {statistics.median(x[0] for x in rr):8.2f} ms  '
                      f'seamtex {statistics.median(x[1] for x in rr):8.2f} ms  '
                      f'{statistics.median(x[2] for x in rr):6.2f}x')
        if a.json:
            json.dump(dict(rounds=a.rounds, cells=[dict(file=k[0], order=k[1],
                                                        footprint=float(k[2]), ratios=d)
                                                   for k, d in med.items()],
                           raw=raw, import_rounds=imports), open(a.json, 'w'), indent=1)
    finally:
        shutil.rmtree(qdir, ignore_errors=True)


if __name__ == '__main__':
    main()
