"""tests/bench/py_sample.py PORT QDIR - the Python half of bench_python (tests/bench/
bench_python.c, which starts it and the daemon): reads the queries bench_python wrote to
QDIR (face.u32, u.f32, v.f32: raw native arrays), connects to seamtexd on 127.0.0.1:PORT,
makes two untimed warm-up calls, then for each line "go" on stdin times one
Client.sample() of all the queries (wall and process CPU seconds) (bilinear, Traverse; values, coverage and status into
numpy arrays, or seamtex.Array without numpy) and prints the wall and CPU seconds it took, the
seconds spent inside libseamtex's stc_sample and the rest (packing, copying out, Python). Imports the
module from $SEAMTEX_BUILD/python (default build/python).
"""
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(os.environ.get("SEAMTEX_BUILD", os.path.join(ROOT, "build")),
                                "python"))
import seamtex  # noqa: E402

try:
    import numpy as np

    def load(path, dtype):
        return np.fromfile(path, dtype)
except ImportError:  # the module needs no numpy: array.array has the buffer protocol
    import array

    def load(path, typecode):
        a = array.array({"uint32": "I", "float32": "f"}[typecode])
        with open(path, "rb") as f:
            a.frombytes(f.read())
        return a


def main():
    port, qdir = int(sys.argv[1]), sys.argv[2]
    face = load(os.path.join(qdir, "face.u32"), "uint32")
    u = load(os.path.join(qdir, "u.f32"), "float32")
    v = load(os.path.join(qdir, "v.f32"), "float32")
    with seamtex.Client("127.0.0.1", port, timeout=120) as c:
        for _ in range(2):  # warm-up: libseamtex's and malloc's buffers reach their size
            vals, cov, st = c.sample("default", face, u, v)
        print("ready %d %d" % (len(vals), sum(1 for s in st[:1000] if s)), flush=True)
        for line in sys.stdin:
            if line.strip() != "go":
                break
            t0, c0 = time.perf_counter(), time.process_time()
            vals, cov, st = c.sample("default", face, u, v)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            t = c.last_sample_times
            print("%.6f %.6f %.6f %.6f" % (dt, dc, t["call"], dt - t["call"]), flush=True)


if __name__ == "__main__":
    main()
