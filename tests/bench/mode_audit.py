#!/usr/bin/env python3
"""tests/bench/mode_audit.py - instructions per query of Traverse, Discard and Clamp for every
cell (file x filter x footprint x order) of bench_ptex --sample-only, under callgrind, and the
cells where Discard or Clamp costs more than Traverse (issue 17: "Discard and Clamp no slower
than Traverse").

Timed runs on a shared machine cannot resolve a few percent; callgrind's instruction counts
are deterministic. One valgrind process per file runs every cell with --batches 1 and
--dump-after=st_ptexfilter_batch: each cell makes two calls (the untimed warm-up, which also
holds make_queries, then the timed one), so the even-numbered dumps are the timed calls, one
batch of 4096 queries each, in bench_ptex's loop order (mode in enum order Discard,
Traverse, Clamp; order; footprint; filter). A cell's figure is that dump's total / 4096 -
the same as (batches 5 - batches 1) / 16384 to within the few instructions of the timer
reads.

usage: mode_audit.py ROOT [--files a,b] [--exclude tri,triangle] [--filters ..] [--fp ..]
                     [--order random|coherent|both] [--jobs 2] [--over 0.03] [--tsv OUT]
ROOT is a built checkout (ROOT/build/bench/bench_ptex); SEAMTEX_DATA defaults to
../shared/data beside this repository, as for the tests. Files default to every file bench_ptex lists but the excluded ones (the
triangle meshes: their filter is another one). Prints every cell and then the cells where
Discard or Clamp is over Traverse by more than --over.
"""
import argparse
import concurrent.futures as cf
import glob
import os
import re
import subprocess
import sys
import tempfile

NQ = 4096
MODES = ["discard", "traverse", "clamp"]  # bench_ptex's loop order (the enum's)
ALL_FILTERS = ["point", "bilinear", "box", "gaussian", "bicubic", "bspline", "catmullrom",
               "mitchell"]


def list_files(bench, env):
    out = subprocess.run([bench, "--sample-only", "--filters", "point", "--fp", "1",
                          "--modes", "traverse", "--order", "random", "--batches", "1"],
                         env=env, capture_output=True, text=True, check=True).stdout
    names, on = [], False
    for line in out.splitlines():
        if line.startswith("file "):
            on = True
            continue
        if on and line.strip():
            names.append(line.split()[0])
    return names


def run_file(bench, env, name, filters, fps, orders):
    with tempfile.TemporaryDirectory(prefix="mode_audit.") as d:
        cmd = ["valgrind", "--tool=callgrind", "--dump-after=st_ptexfilter_batch",
               "--callgrind-out-file=" + os.path.join(d, "cg"), bench, "--sample-only",
               "--files", "=" + name, "--filters", ",".join(filters),
               "--fp", ",".join(fps), "--order", orders, "--modes", ",".join(MODES),
               "--batches", "1"]
        subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       check=True)
        parts = {}
        for p in glob.glob(os.path.join(d, "cg.*")):
            with open(p) as fh:
                for line in fh:
                    if line.startswith("summary:") or line.startswith("totals:"):
                        parts[int(p.rsplit(".", 1)[1])] = int(line.split()[1])
                        break
    ords = ["random", "coherent"] if orders == "both" else [orders]
    cells = [(m, o, fp, fl) for m in MODES for o in ords for fp in fps for fl in filters]
    if len(parts) != 2 * len(cells):
        raise RuntimeError("%s: %d dumps for %d cells" % (name, len(parts), len(cells)))
    res = {}
    for i, (m, o, fp, fl) in enumerate(cells):
        res[(name, fl, fp, o, m)] = parts[2 * i + 2] / NQ
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("root")
    ap.add_argument("--files")
    ap.add_argument("--exclude", default="tri,triangle")
    ap.add_argument("--filters", default=",".join(ALL_FILTERS))
    ap.add_argument("--fp", default="0.25,4,16")
    ap.add_argument("--order", default="random")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--over", type=float, default=0.03)
    ap.add_argument("--tsv")
    a = ap.parse_args()
    env = dict(os.environ)
    env.setdefault("SEAMTEX_DATA", os.path.normpath(os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "data")))
    bench = os.path.join(a.root, "build/bench/bench_ptex")
    files = a.files.split(",") if a.files else list_files(bench, env)
    excl = set(a.exclude.split(",")) if a.exclude else set()
    files = [f for f in files if f not in excl]
    # bench_ptex runs the filters in its own order, the footprints in the order given
    filters = sorted(a.filters.split(","), key=ALL_FILTERS.index)
    fps = a.fp.split(",")
    res = {}
    with cf.ThreadPoolExecutor(a.jobs) as ex:
        futs = {ex.submit(run_file, bench, env, f, filters, fps, a.order): f for f in files}
        for fu in cf.as_completed(futs):
            res.update(fu.result())
            print("# done %s" % futs[fu], file=sys.stderr, flush=True)
    ords = ["random", "coherent"] if a.order == "both" else [a.order]
    rows = []
    for f in files:
        for fl in filters:
            for fp in fps:
                for o in ords:
                    t, d, c = (res[(f, fl, fp, o, m)] for m in ("traverse", "discard", "clamp"))
                    rows.append((f, fl, fp, o, t, d, c))
    hdr = "file\tfilter\tfp\torder\ttraverse\tdiscard\tclamp\tD/T\tC/T"
    lines = [hdr] + ["%s\t%s\t%s\t%s\t%.1f\t%.1f\t%.1f\t%.3f\t%.3f" %
                     (f, fl, fp, o, t, d, c, d / t, c / t) for f, fl, fp, o, t, d, c in rows]
    if a.tsv:
        with open(a.tsv, "w") as fh:
            fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    over = [r for r in rows if r[5] > r[4] * (1 + a.over) or r[6] > r[4] * (1 + a.over)]
    print("\n# %d cells, %d with Discard or Clamp over Traverse by more than %g%%" %
          (len(rows), len(over), a.over * 100))
    for f, fl, fp, o, t, d, c in over:
        print("over\t%s\t%s\t%s\t%s\t%.1f\t%.1f\t%.1f\t%.3f\t%.3f" %
              (f, fl, fp, o, t, d, c, d / t, c / t))


if __name__ == "__main__":
    main()
