#!/usr/bin/env python3
"""tests/bench/ptex_import_ab.py - .ptx import of two or more builds, alternated, fresh process each.

Usage: ptex_import_ab.py [--rounds N] [--json PATH] NAME=BENCH_PTEX [NAME=BENCH_PTEX ...] FILE.ptx ...

Each BENCH_PTEX is a build's bench_ptex (or any program that takes `--import-one FILE` and prints
"wall_s cpu_s" of one st_ptex_read_file in its new process, process start-up not timed). Every
round runs each file once per build, the builds' order rotated per round (A B C, B C A, ...), so
that a change of machine load falls on every build alike. Prints per file the median process CPU
ms of each build and the ratio of each build to the last one ('-' where a build refused the
file), and the load average seen (1-minute, min / median / max over the rounds). CPU time, not wall time: on a shared machine the
wall time measures the other jobs.
"""
import json
import os
import statistics
import subprocess
import sys


def main(argv):
    rounds, jpath, builds, files = 11, None, [], []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == '--rounds':
            rounds = int(argv[i + 1])
            i += 2
            continue
        if a == '--json':
            jpath = argv[i + 1]
            i += 2
            continue
        if '=' in a and not a.endswith('.ptx'):
            builds.append(tuple(a.split('=', 1)))
        else:
            files.append(a)
        i += 1
    if len(builds) < 1 or not files:
        sys.stderr.write(__doc__)
        return 2
    cpu = {f: {n: [] for n, _ in builds} for f in files}
    loads = []
    for r in range(rounds):
        loads.append(os.getloadavg()[0])
        order = builds[r % len(builds):] + builds[:r % len(builds)]
        for f in files:
            for n, exe in order:
                p = subprocess.run([exe, '--import-one', f], capture_output=True, text=True)
                if p.returncode:  # refused (an old build and a triangle mesh): '-' in the table
                    continue
                cpu[f][n].append(float(p.stdout.split()[1]) * 1e3)
    names = [n for n, _ in builds]
    print('load average (1 min) min / median / max: %.1f / %.1f / %.1f; %d rounds' %
          (min(loads), statistics.median(loads), max(loads), rounds))
    print('\t'.join(['file'] + ['%s ms' % n for n in names] +
                    ['%s / %s' % (n, names[-1]) for n in names[:-1]]))
    rows = []
    for f in files:
        med = [statistics.median(cpu[f][n]) if cpu[f][n] else None for n in names]
        rows.append({'file': f, 'median_cpu_ms': dict(zip(names, med))})
        print('\t'.join([f] + ['%.2f' % m if m is not None else '-' for m in med] +
                        ['%.2f' % (m / med[-1]) if m is not None and med[-1] else '-'
                         for m in med[:-1]]))
    if jpath:
        with open(jpath, 'w') as out:
            json.dump({'bench': 'ptex_import_ab', 'rounds': rounds, 'loads': loads,
                       'rows': rows, 'cpu_ms': cpu}, out)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
