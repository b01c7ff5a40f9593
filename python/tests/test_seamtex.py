"""python/tests/test_seamtex.py - the Python module against a live seamtexd (conftest.py).

Every call of Client, sample values equal to the C client's (the CLI `seamtex sample
--queries FILE --binary`, which is libseamtex), arrays through the buffer protocol with and
without numpy, bad arguments raising clear exceptions, server statuses as exceptions, the
GIL released while a long sample runs. Run: /usr/bin/python3 -m pytest -q python/tests
"""

import array
import os
import subprocess
import threading
import time

import numpy as np
import pytest

import seamtex

RNG = np.random.default_rng(7)


def queries(n, nfaces=384, deriv=0.0):
    face = RNG.integers(0, nfaces, n, dtype=np.uint32)
    u = RNG.random(n, dtype=np.float32)
    v = RNG.random(n, dtype=np.float32)
    d = np.full(n, deriv, np.float32)
    return face, u, v, d


# ---- connecting ----------------------------------------------------------------------------

def test_connect_ping_and_server_info(client):
    assert client.ping() > 0
    s = client.server
    assert s["version"] >= 1 and s["max_batch"] > 0 and s["name"].startswith("seamtexd")
    assert "127.0.0.1" in repr(client)


def test_context_manager_closes(daemon):
    with daemon.client() as c:
        assert not c.closed
    assert c.closed
    with pytest.raises(seamtex.ClosedError):
        c.ping()
    c.close()  # again: no-op


def test_connect_refused_raises_connect_failed(daemon):
    # a port nothing listens on: the daemon's own port + 1 is as good a guess as any, so
    # find a closed one by binding and closing
    import socket
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(seamtex.ConnectFailed) as e:
        seamtex.Client("127.0.0.1", port, timeout=2)
    assert isinstance(e.value, ConnectionError)
    assert e.value.status == "ECONNECT"


def test_timeout_attribute(client):
    assert client.timeout == 10.0
    client.timeout = 2.5
    assert client.timeout == 2.5
    client.timeout = None
    assert client.timeout is None
    with pytest.raises(ValueError):
        client.timeout = -1


# ---- ls, info, stats -------------------------------------------------------------------------

def test_ls_lists_default(client):
    sets = {s["name"]: s for s in client.ls()}
    d = sets["default"]
    assert d["kind"] == "perface" and d["nchan"] == 4 and d["dtype"] == "u8"
    assert d["nfaces"] == 384 and d["memory"] > 0


def test_info_with_faces(client):
    i = client.info("default", faces=(2, 3))
    assert i["nfaces"] == 384 and i["nchan"] == 4 and i["kind"] == "perface"
    assert [f["id"] for f in i["faces"]] == [2, 3, 4]
    f = i["faces"][0]
    assert f["w"] > 0 and f["h"] > 0 and len(f["adjface"]) == 4 and len(f["adjedge"]) == 4
    assert client.info("default")["faces"] == []


def test_info_unknown_set_raises_not_found(client):
    with pytest.raises(seamtex.NotFound) as e:
        client.info("no-such-set")
    assert e.value.status == "NOT_FOUND"
    assert e.value.code == -105
    assert "no-such-set" in str(e.value)
    assert isinstance(e.value, seamtex.Error)
    assert seamtex.errors["NOT_FOUND"] is seamtex.NotFound


def test_bad_set_name_raises_invalid_argument(client):
    with pytest.raises(seamtex.InvalidArgument):
        client.info("../etc")


def test_stats_is_a_dict_of_numbers(client):
    client.ping()
    st = client.stats()
    assert st["uptime_ms"] >= 0
    assert all(isinstance(v, (int, float)) for v in st.values())


def test_exception_classes_follow_the_status_list():
    for name in ("NotFound", "Invalid", "Busy", "TooLarge", "Exists", "Perm", "Unsupported",
                 "Shutdown", "BadRequest"):
        assert issubclass(getattr(seamtex, name), seamtex.Error)
    assert issubclass(seamtex.TimedOut, TimeoutError)
    assert set(seamtex.errors) >= {"NOT_FOUND", "TOO_LARGE", "BUSY", "ETIMEDOUT", "EIO"}


# ---- sample -----------------------------------------------------------------------------------

def test_sample_matches_readme_values(client):
    v, cov, st = client.sample("default", np.array([12], np.uint32), np.array([0.98]),
                               np.array([0.5]), 0.05, 0.0, 0.0, 0.05, filter="trilinear")
    assert v.shape == (1, 4) and v.dtype == np.float32
    assert np.allclose(v[0], [0.544351, 0.508689, 0.6864, 1], atol=1e-6)
    assert cov[0] == 1 and st[0] == seamtex.Q_OK
    v, cov, st = client.sample("default", 12, 0.98, 0.5, 0.05, 0, 0, 0.05,
                               filter="trilinear", mode="discard")
    assert np.allclose(v[0], [0.539437, 0.505377, 0.676914, 1], atol=1e-6)
    assert abs(cov[0] - 0.7115) < 1e-4


def run_cli(build, daemon, args, stdin=None):
    r = subprocess.run([str(build / "seamtex"), "-p", str(daemon.port), *args],
                       capture_output=True, input=stdin)
    assert r.returncode == 0, r.stderr.decode()
    return r.stdout


@pytest.mark.parametrize("mode,filt", [("traverse", "bilinear"), ("discard", "trilinear"),
                                       ("clamp", "point"), ("traverse", "ptex-gaussian")])
def test_sample_values_equal_the_c_clients(client, daemon, build, tmp_path, mode, filt):
    n = 2000
    face, u, v, _ = queries(n)
    d = RNG.random((4, n), dtype=np.float32) * 0.02
    qf = tmp_path / "q.txt"
    with open(qf, "w") as f:
        for i in range(n):
            f.write("%d %.9g %.9g %.9g %.9g %.9g %.9g\n" % (
                face[i], u[i], v[i], d[0, i], d[1, i], d[2, i], d[3, i]))
    out = run_cli(build, daemon, ["sample", "default", "--queries", str(qf), "--binary",
                                  "--mode", mode, "--filter", filt])
    ref = np.frombuffer(out, np.float32).reshape(n, 4)
    vals, cov, st = client.sample("default", face, u, v, d[0], d[1], d[2], d[3], mode=mode,
                                  filter=filt)
    assert np.array_equal(vals, ref)
    assert (st == 0).all()


def test_sample_lerp_reaches_the_sampler_and_equals_the_cli(client, daemon, build, tmp_path):
    # Ptex's lerp (SAMPLE flag bit 5): footprints between levels change the width-4 filters,
    # footprints on a level (1/4 of a face) do not; the CLI's --lerp gives the same values
    n = 200
    face, u, v, _ = queries(n)
    w = (0.3 + 0.4 * RNG.random(n)).astype(np.float32) * 0.5  # 0.15-0.35 of a face
    off, _, _ = client.sample("default", face, u, v, w, 0, 0, w, filter="ptex-gaussian")
    on, _, st = client.sample("default", face, u, v, w, 0, 0, w, filter="ptex-gaussian",
                              lerp=True)
    assert (st == 0).all() and not np.array_equal(on, off)
    q = np.full(n, 0.25, np.float32)
    a, _, _ = client.sample("default", face, u, v, q, 0, 0, q, filter="ptex-mitchell")
    b, _, _ = client.sample("default", face, u, v, q, 0, 0, q, filter="ptex-mitchell",
                            lerp=True)
    assert np.array_equal(a, b)
    qf = tmp_path / "q.txt"
    qf.write_text("".join("%d %.9g %.9g %.9g 0 0 %.9g\n" % (face[i], u[i], v[i], w[i], w[i])
                          for i in range(n)))
    out = run_cli(build, daemon, ["sample", "default", "--queries", str(qf), "--binary",
                                  "--filter", "ptex-gaussian", "--lerp"])
    assert np.array_equal(np.frombuffer(out, np.float32).reshape(n, 4), on)


def test_sample_unorm_formats_equal_the_c_clients(client, daemon, build, tmp_path):
    n = 500
    face, u, v, _ = queries(n)
    qf = tmp_path / "q.txt"
    qf.write_text("".join("%d %.9g %.9g\n" % (face[i], u[i], v[i]) for i in range(n)))
    for fmt, dt in (("unorm8", np.uint8), ("unorm16", np.uint16)):
        out = run_cli(build, daemon, ["sample", "default", "--queries", str(qf), "--binary",
                                      "--format", fmt])
        vals, _, _ = client.sample("default", face, u, v, format=fmt)
        assert vals.dtype == dt
        assert np.array_equal(vals, np.frombuffer(out, dt).reshape(n, 4))


def test_sample_accepts_dtypes_and_strides(client):
    face, u, v, _ = queries(100)
    ref, _, _ = client.sample("default", face, u, v)
    for f in (face.astype(np.int64), face.astype(np.int32), face.astype(np.uint16)):
        got, _, _ = client.sample("default", f, u.astype(np.float64), v.astype(np.float64))
        assert np.array_equal(got, ref)
    # strided views and array.array / memoryview inputs
    big = np.zeros((100, 3), np.float32)
    big[:, 1] = u
    got, _, _ = client.sample("default", array.array("I", face.tolist()), big[:, 1],
                              memoryview(v))
    assert np.array_equal(got, ref)


def test_sample_into_out(client):
    face, u, v, _ = queries(64)
    out = np.empty((64, 4), np.float32)
    vals, cov, st = client.sample("default", face, u, v, out=out)
    assert vals is out
    ref, _, _ = client.sample("default", face, u, v)
    assert np.array_equal(out, ref)
    with pytest.raises(ValueError, match="out holds"):
        client.sample("default", face, u, v, out=np.empty((63, 4), np.float32))
    with pytest.raises(TypeError, match="format"):
        client.sample("default", face, u, v, out=np.empty((64, 4), np.float64))


def test_sample_without_numpy_returns_buffer_arrays(daemon):
    with daemon.client(numpy=False) as c:
        vals, cov, st = c.sample("default", array.array("I", [12, 13]),
                                 array.array("f", [0.98, 0.5]), array.array("d", [0.5, 0.5]))
        assert isinstance(vals, seamtex.Array)
        assert vals.shape == (2, 4) and vals.format == "f" and len(vals) == 2
        m = memoryview(vals)
        assert m.shape == (2, 4) and m.format == "f"
        assert st.tolist() == [0, 0] and cov.shape == (2,)
    with daemon.client() as c:
        ref, _, _ = c.sample("default", np.array([12, 13]), np.array([0.98, 0.5]),
                             np.array([0.5, 0.5]))
    assert np.array_equal(np.asarray(vals), ref)


def test_per_query_statuses(client):
    vals, cov, st = client.sample("default", np.array([0, 99999], np.uint32),
                                  np.array([0.5, 0.5]), np.array([0.5, 0.5]))
    assert st.tolist() == [seamtex.Q_OK, seamtex.Q_BAD_FACE]
    assert seamtex.QSTATUS[st[1]] == "BAD_FACE"


def test_nan_raises_unless_nonfinite_status(client):
    u = np.array([0.5, np.nan], np.float32)
    v = np.array([0.5, 0.5], np.float32)
    with pytest.raises(ValueError, match=r"u\[1\] is NaN"):
        client.sample("default", np.array([0, 1], np.uint32), u, v)
    with pytest.raises(ValueError, match=r"dvdy\[0\] is infinite"):
        client.sample("default", 0, 0.5, 0.5, dvdy=np.array([np.inf, 0.0]))
    _, _, st = client.sample("default", np.array([0, 1], np.uint32), u, v, nonfinite="status")
    assert st.tolist() == [seamtex.Q_OK, seamtex.Q_NONFINITE]


def test_bad_arguments_raise_clear_errors(client):
    face, u, v, _ = queries(10)
    with pytest.raises(TypeError, match="u must hold float32 or float64"):
        client.sample("default", face, u.astype(np.int32), v)
    with pytest.raises(TypeError, match="face must hold integers"):
        client.sample("default", face.astype(np.float32), u, v)
    with pytest.raises(ValueError, match="v has 9 queries but face has 10"):
        client.sample("default", face, u, v[:9])
    with pytest.raises(ValueError, match=r"face\[0\] = -1 is not a face id"):
        client.sample("default", np.array([-1], np.int32), 0.5, 0.5)
    with pytest.raises(ValueError, match="unknown mode 'wrap'.*traverse"):
        client.sample("default", face, u, v, mode="wrap")
    with pytest.raises(ValueError, match="unknown filter 'cubic'.*bilinear"):
        client.sample("default", face, u, v, filter="cubic")
    with pytest.raises(ValueError, match="unknown format"):
        client.sample("default", face, u, v, format="f64")
    with pytest.raises(TypeError, match="buffer protocol"):
        client.sample("default", face, "abc", v)
    with pytest.raises(ValueError, match="one-dimensional"):
        client.sample("default", face, u.reshape(2, 5), v)
    with pytest.raises(TypeError, match="byte order"):
        client.sample("default", face, u.astype(">f4"), v)
    with pytest.raises(seamtex.NotFound):
        client.sample("default-missing", face, u, v)
    client.ping()  # still usable after each



def test_numpy_scalars_are_numbers(client):
    """A numpy scalar (what indexing an array gives) or a 0-d array is a number, broadcast like
    a Python one: it used to raise "face must be one-dimensional, not 0-dimensional"."""
    face, u, v, _ = queries(10)
    ref, _, _ = client.sample("default", int(face[3]), float(u[3]), float(v[3]), dudx=0.01)
    got, _, _ = client.sample("default", face[3], u[3], v[3], dudx=np.float32(0.01))
    assert np.array_equal(got, ref)
    for f in (np.uint32(face[3]), np.int64(face[3]), np.array(face[3]), np.uint8(face[3] % 256)):
        want, _, _ = client.sample("default", int(f), 0.5, 0.25)
        assert np.array_equal(client.sample("default", f, np.float32(0.5), np.array(0.25))[0],
                              want)
    assert np.array_equal(client.sample("default", 1, np.int64(0), 0.5)[0],   # ints for u, too
                          client.sample("default", 1, 0.0, 0.5)[0])
    many, _, _ = client.sample("default", face, np.float64(0.5), np.float32(0.5))  # broadcast
    assert many.shape == (10, 4)
    with pytest.raises(TypeError, match="face must hold integers"):
        client.sample("default", np.float32(1), 0.5, 0.5)
    with pytest.raises(ValueError, match="face = -1 is not a face id"):
        client.sample("default", np.int32(-1), 0.5, 0.5)
    with pytest.raises(ValueError, match="is not a face id"):
        client.sample("default", 2**70, 0.5, 0.5)
    with pytest.raises(ValueError, match=r"u\[0\] is NaN"):
        client.sample("default", 0, np.float32("nan"), 0.5)


def test_integer_arguments_are_range_checked(daemon, client):
    """port, faces, chunk, level and max_aniso are checked, not wrapped modulo 2^32 (PyArg's
    "I"): faces=(0, 2**32) used to ask for 0 records, chunk=2**32 + 1 sent 1-byte chunks."""
    with pytest.raises(ValueError, match="port is 0..65535"):
        seamtex.Client("127.0.0.1", 2**32 + daemon.port)
    with pytest.raises(ValueError, match="port is 0..65535"):
        seamtex.Client("127.0.0.1", -1)
    with pytest.raises(ValueError, match="faces' count is 0..4294967295"):
        client.info("default", faces=(0, 2**32))
    with pytest.raises(ValueError, match="faces' first is 0..4294967295"):
        client.info("default", faces=(-1, 2))
    with pytest.raises(ValueError, match="faces is 0..4294967295"):
        client.info("default", faces=-1)
    with pytest.raises(TypeError, match="faces must be a count or a"):
        client.info("default", faces=(1, 2, 3))
    with pytest.raises(TypeError, match="must be an integer"):
        client.info("default", faces=(0, 2.5))
    assert [f["id"] for f in client.info("default", faces=(np.uint32(5), 2))["faces"]] == [5, 6]
    with pytest.raises(ValueError, match="max_aniso is 0..255"):
        client.sample("default", 0, 0.5, 0.5, max_aniso=2**32)
    with pytest.raises(ValueError, match="max_aniso is 0..255"):
        client.sample("default", 0, 0.5, 0.5, max_aniso=-1)
    with pytest.raises(ValueError, match="level is 0..9"):
        client.compress("default", "py-never", level=2**32 + 1)
    with pytest.raises(ValueError, match="chunk is 0..4294967295"):
        client.upload(__file__, "py-never", chunk=2**32 + 1)
    with pytest.raises(ValueError, match="chunk is 0..4294967295"):
        client.upload(__file__, "py-never", chunk=-1)
    assert "py-never" not in [s["name"] for s in client.ls()]
    client.ping()


def test_init_again_waits_for_a_call_in_flight(daemon):
    """Client.__init__ on an open Client (another thread mid-call) used to stc_close the
    connection under that call (use after free); now it waits for the call, then reconnects.
    The other thread has started its call only by the scheduler's leave: an attempt counts
    when the call was still running as __init__ began and __init__ returned after it ended;
    a loaded machine may start the call late (it then runs on the new connection), so the
    attempt is made again with a longer head start."""
    c = daemon.client(shm=False)
    n = 2_000_000
    face = np.zeros(n, np.uint32)
    u = np.full(n, 0.5, np.float32)
    seen = []
    for head_start in (0.1, 0.3, 0.6, 1.0):
        ended = {}
        calling = threading.Event()

        def big():
            calling.set()
            try:
                vals, _, st = c.sample("default", face, u, u, filter="trilinear", dudx=0.01)
                ended["ok"] = vals.shape == (n, 4) and not st.any()
            except Exception as e:  # pragma: no cover - reported below
                ended["ok"] = repr(e)
            ended["t"] = time.monotonic()

        t = threading.Thread(target=big)
        t.start()
        calling.wait()
        time.sleep(head_start)      # the call is packing or on the wire by now (> 0.3 s)
        begun = time.monotonic()
        c.__init__(daemon.host, daemon.port, shm=False)
        reinit = time.monotonic()
        t.join()
        assert ended["ok"] is True  # a connection closed under the call fails it
        c.ping()
        seen.append((head_start, begun < ended["t"], reinit >= ended["t"]))
        if begun < ended["t"] and reinit >= ended["t"]:
            break
    else:
        pytest.fail("__init__ never waited for a call in flight: (head start, call running "
                    "at __init__, __init__ returned after it) = %r" % (seen,))
    c.close()


def test_none_for_face_u_or_v_is_a_type_error(client):
    """py35: None for face, u or v was read as "not given": sample("default", None, 0.5, 0.5)
    sampled face 0 and a None u or v the edge 0, without a word."""
    for i, name in enumerate(("face", "u", "v")):
        args = [3, 0.5, 0.5]
        args[i] = None
        with pytest.raises(TypeError, match="%s must be .* not None" % name):
            client.sample("default", *args)
    client.sample("default", 3, 0.5, 0.5, dudx=None)   # the derivatives may be None (= 0)


def _fork_child(body):
    """Runs body() in a forked child; its exit status: 0 when it returned True, 1 when it
    returned something else, 2 when it raised; -1 when it had not ended after 20 s (killed)."""
    pid = os.fork()
    if pid == 0:   # no pytest in here: only the exit status goes back
        code = 2
        try:
            code = 0 if body() is True else 1
        finally:
            os._exit(code)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.02)
    os.kill(pid, 9)
    os.waitpid(pid, 0)
    return -1


def test_a_fork_child_cannot_use_the_parents_client(daemon):
    """py35: a Client used in a child after fork shared the parent's socket and request ids:
    the parent's Client broke with ProtocolError (and through shared memory results came back
    wrong). The child gets StateError naming fork, even while a parent's thread held the
    Client's lock at the fork (it waited for ever); close() there leaves the parent's Client
    working."""
    c = daemon.client(shm=False)
    face, u, v, _ = queries(1000)
    ref = c.sample("default", face, u, v)[0].copy()

    def child():
        try:
            c.ping()
            return False
        except seamtex.StateError as e:
            ok = "fork" in str(e) and e.status == "ESTATE"
        try:
            c.sample("default", face, u, v)
            return False
        except seamtex.StateError:
            pass
        c.close()
        c.close()
        return ok and c.closed

    assert _fork_child(child) == 0
    assert np.array_equal(c.sample("default", face, u, v)[0], ref)
    assert c.ping() > 0

    # a fork while another thread is in a call on the Client (holding its lock)
    n = 2_000_000
    big = np.zeros(n, np.uint32), np.full(n, 0.5, np.float32)
    in_call = threading.Event()

    def long_call():
        in_call.set()
        c.sample("default", big[0], big[1], big[1], filter="trilinear", dudx=0.01)

    t = threading.Thread(target=long_call)
    t.start()
    in_call.wait()
    time.sleep(0.05)
    assert _fork_child(child) == 0
    t.join()
    assert np.array_equal(c.sample("default", face, u, v)[0], ref)
    c.close()


def test_a_fork_child_may_open_its_own_client(daemon):
    c = daemon.client(shm=False)

    def child():
        c.__init__(daemon.host, daemon.port, shm=False)   # a new connection of its own
        ok = c.ping() > 0 and c.info("default")["nfaces"] == 384
        c.close()
        return ok

    assert _fork_child(child) == 0
    assert c.ping() > 0
    c.close()


def test_large_batch_is_split_by_the_library(daemon):
    # more than the server's max_batch when the daemon is told so
    d = type(daemon)("--max-batch", "1000")
    try:
        with d.client() as c:
            face, u, v, _ = queries(4500)
            vals, cov, st = c.sample("default", face, u, v)
            with daemon.client() as ref_c:
                ref, _, _ = ref_c.sample("default", face, u, v)
            assert np.array_equal(vals, ref)
    finally:
        assert d.stop() == 0


def test_sample_releases_the_gil(daemon):
    n = 1_000_000
    face, u, v, d = queries(n, deriv=0.01)
    ticks = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            ticks[0] += 1
            time.sleep(0.001)

    with daemon.client(timeout=120) as c:
        t = threading.Thread(target=spin)
        t.start()
        try:
            t0 = time.monotonic()
            before = ticks[0]
            c.sample("default", face, u, v, d, 0, 0, d, filter="trilinear")
            during = ticks[0] - before
            secs = time.monotonic() - t0
        finally:
            stop.set()
            t.join()
    # with the GIL held for the whole call the other thread would not tick at all; one tick
    # per ms asked, so a tenth of that is a loose floor on a loaded machine
    assert during >= max(3, secs * 1000 * 0.1), (during, secs)


def test_sample_dir_on_a_cube(client, data):
    client.upload(data / "env" / "OrientationLatLong.exr", "py-env", cube="latlong:64",
                  replace=True)
    dirs = np.array([[1, 0.2, 0.1], [0, 0, -1], [0.3, -1, 0.2]], np.float32)
    v1, cov, st = client.sample_dir("py-env", dirs, cone=0.01, filter="trilinear")
    assert v1.shape[0] == 3 and (st == 0).all()
    v2, _, _ = client.sample_dir("py-env", dirs.astype(np.float64).ravel(),
                                 cone=np.full(3, 0.01), filter="trilinear")
    assert np.array_equal(v1, v2)
    v3, _, _ = client.sample_dir("py-env", dirs, ddx=np.zeros((3, 3)), ddy=np.zeros((3, 3)))
    assert v3.shape == v1.shape
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        client.sample_dir("py-env", np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match="either cone or ddx"):
        client.sample_dir("py-env", dirs, ddx=dirs, cone=0.1)
    client.delete("py-env")


# ---- upload, delete, compress, fetch --------------------------------------------------------------

def test_upload_with_progress_then_delete(client, data):
    seen = []
    r = client.upload(data / "ptex-ref" / "cube8_k6_u8.ptx", "py-cube8",
                      progress=lambda done, total: seen.append((done, total)), chunk=65536)
    assert r["name"] == "py-cube8" and r["kind"] == "perface" and r["nfaces"] > 0
    assert seen and seen[-1][0] == seen[-1][1] == os.path.getsize(
        data / "ptex-ref" / "cube8_k6_u8.ptx")
    assert "py-cube8" in [s["name"] for s in client.ls()]
    with pytest.raises(seamtex.Exists):
        client.upload(data / "ptex-ref" / "cube8_k6_u8.ptx", "py-cube8")
    client.upload(str(data / "ptex-ref" / "cube8_k6_u8.ptx"), "py-cube8", replace=True)
    client.delete("py-cube8")
    with pytest.raises(seamtex.NotFound):
        client.delete("py-cube8")


def test_upload_progress_exception_aborts(client, data):
    class Stop(Exception):
        pass

    def cb(done, total):
        raise Stop()

    with pytest.raises(Stop):
        client.upload(data / "ptex-ref" / "cube8_k6_u8.ptx", "py-aborted", progress=cb,
                      chunk=65536)
    assert "py-aborted" not in [s["name"] for s in client.ls()]
    client.ping()


def test_progress_callback_cannot_reenter_its_client(client, data):
    def cb(done, total):
        client.ping()

    with pytest.raises(seamtex.StateError, match="progress callback"):
        client.upload(data / "ptex-ref" / "cube8_k6_u8.ptx", "py-reenter", progress=cb,
                      chunk=65536)
    client.ping()
    assert "py-reenter" not in [s["name"] for s in client.ls()]


def test_close_in_a_progress_callback_is_not_silently_ignored(client, data):
    """close() from its own call's progress callback cannot close the connection under that
    call: it raises StateError (which aborts the transfer) instead of returning None with the
    Client still open, as it used to."""
    seen = []

    def cb(done, total):
        client.close()
        seen.append(client.closed)       # not reached

    with pytest.raises(seamtex.StateError, match="progress callback"):
        client.upload(data / "ptex-ref" / "cube8_k6_u8.ptx", "py-close-cb", progress=cb,
                      chunk=65536)
    assert seen == [] and not client.closed
    assert "py-close-cb" not in [s["name"] for s in client.ls()]
    client.close()
    client.close()
    assert client.closed


def test_upload_options_and_errors(client, data, tmp_path):
    with pytest.raises(seamtex.Invalid):
        client.upload(data / "images" / "brick.png", "py-brick", colour="red")
    with pytest.raises(ValueError, match="blank"):
        client.upload(data / "images" / "brick.png", "py-brick", cube="latlong 64")
    with pytest.raises(seamtex.FileError):
        client.upload(tmp_path / "missing.png", "py-missing")
    r = client.upload(data / "images" / "brick.png", "py-brick", colorspace="srgb")
    assert r["kind"] == "atlas"
    client.delete("py-brick")


def test_upload_option_with_a_nul_is_refused_not_cut(client, data):
    """An option value (or name) holding a NUL or a control character is refused before
    anything is sent: texture="py-nt\\0x" used to go out as texture=py-nt (the C string cut at
    the NUL) and upload against the wrong texture."""
    duck = data / "meshes" / "duck"
    client.upload(duck / "DuckCM.png", "py-nt", replace=True)
    for bad in ("py-nt\0x", "py-nt\r", "py-nt\x7f"):
        with pytest.raises(ValueError, match="control character"):
            client.upload(duck / "Duck.obj", "py-nt-duck", texture=bad)
    with pytest.raises(ValueError, match="control character"):
        client.upload(duck / "Duck.obj", "py-nt-duck", **{"texture\0x": "py-nt"})
    assert "py-nt-duck" not in [s["name"] for s in client.ls()]
    client.delete("py-nt")


def test_compress_job_and_fetch(client, data, tmp_path):
    duck = data / "meshes" / "duck"
    client.upload(duck / "DuckCM.png", "py-duck-tex", replace=True)
    client.upload(duck / "Duck.obj", "py-duck", texture="py-duck-tex", replace=True)
    job = client.compress("py-duck", "py-duck-bc1", level=1, replace=True)
    assert isinstance(job, seamtex.Job) and job.id > 0
    assert job.status()["state"] in ("queued", "running", "done")
    done = job.wait(timeout=300)
    assert done["state"] == "done" and done["progress"] == 1.0
    assert [s["kind"] for s in client.ls() if s["name"] == "py-duck-bc1"] == ["bc1"]
    v, _, st = client.sample("py-duck-bc1", 0, 0.31, 0.62, 0.004, 0, 0, 0.004,
                             filter="trilinear")
    assert st[0] == 0 and 0 <= v[0, 0] <= 1
    # fetch: format from the extension, given by name, or passed through as a number
    p = tmp_path / "duck.dds"
    got = []
    client.fetch("py-duck-bc1", p, progress=lambda d, t: got.append(d))
    assert p.read_bytes()[:4] == b"DDS " and got
    client.fetch("py-duck-bc1", tmp_path / "duck.bin", format="dds")
    client.fetch("default", tmp_path / "default.ptx")
    assert (tmp_path / "default.ptx").read_bytes()[:4] == b"Ptex"
    client.fetch("default", tmp_path / "default2", format=0)
    assert (tmp_path / "default2").read_bytes() == (tmp_path / "default.ptx").read_bytes()
    with pytest.raises(ValueError, match="unknown fetch format"):
        client.fetch("default", tmp_path / "x.xyz")
    with pytest.raises(seamtex.NotFound):
        client.compress("py-none", "py-none-bc1").wait()
    for s in ("py-duck-bc1", "py-duck", "py-duck-tex"):
        client.delete(s)


def test_fetch_every_protocol_format(client, data, tmp_path):
    """fetch knows every format of the protocol's list (png, obj, exr too, as `seamtex fetch`
    does), by extension and by name; a format the set cannot be written as is the server's
    Unsupported, naming the ones it can."""
    duck = data / "meshes" / "duck"
    client.upload(duck / "DuckCM.png", "py-fx-tex", replace=True)
    client.upload(duck / "Duck.obj", "py-fx", texture="py-fx-tex", replace=True)
    client.fetch("py-fx", tmp_path / "duck.png")
    assert (tmp_path / "duck.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    client.fetch("py-fx", tmp_path / "duck.OBJ")              # case-insensitive, like the CLI
    assert b"\nv " in (tmp_path / "duck.OBJ").read_bytes()
    client.fetch("py-fx", tmp_path / "duck-as-png.bin", format="png")
    assert (tmp_path / "duck-as-png.bin").read_bytes() == (tmp_path / "duck.png").read_bytes()
    with pytest.raises(seamtex.Unsupported, match="png obj"):
        client.fetch("py-fx", tmp_path / "duck.exr")
    assert not (tmp_path / "duck.exr").exists()
    with pytest.raises(ValueError, match="ptx dds exr png obj"):
        client.fetch("py-fx", tmp_path / "duck.xyz")
    with pytest.raises(ValueError, match="no extension"):
        client.fetch("py-fx", tmp_path / "duck")
    for s in ("py-fx", "py-fx-tex"):
        client.delete(s)


def test_job_wait_zero_polls_once(client):
    """wait(timeout=0) (or a negative one) polls once and raises TimedOut while the job runs;
    it used to wait for the whole job (libseamtex took 0 ms as "no deadline"). NaN is a
    ValueError (it used to spin until the job ended)."""
    job = client.compress("default", "py-wait0", level=9, replace=True)
    try:
        for t in (0, -1.0):
            with pytest.raises(seamtex.TimedOut):
                job.wait(timeout=t)
        with pytest.raises(ValueError, match="timeout"):
            job.wait(timeout=float("nan"))
        assert job.status()["state"] in ("queued", "running")
    finally:
        job.cancel()
        try:
            job.wait(timeout=120)
        except seamtex.Canceled:
            pass
        try:
            client.delete("py-wait0")
        except seamtex.NotFound:
            pass


def test_job_cancel_and_timeout(client, data):
    client.upload(data / "images" / "StillLife.jpg", "py-still", replace=True)
    job = client.compress("py-still", "py-still-bc1", level=9, replace=True)
    try:
        job.wait(timeout=0.001)
    except seamtex.TimedOut:
        pass
    st = job.cancel()
    assert st["state"] in ("canceled", "done", "running", "queued")
    try:
        job.wait(timeout=120)
    except seamtex.Canceled:
        pass
    assert job.status()["state"] in ("canceled", "done")
    for s in ("py-still-bc1", "py-still"):
        try:
            client.delete(s)
        except seamtex.NotFound:
            pass


def test_token_is_needed_for_mutations(data):
    from conftest import Daemon
    d = Daemon("--token", "s3cret")
    try:
        with d.client() as c:
            assert c.server["authenticated"] is False
            with pytest.raises(seamtex.Perm):
                c.upload(data / "images" / "brick.png", "py-brick")
        with d.client(token="s3cret") as c:
            assert c.server["authenticated"] is True
            c.upload(data / "images" / "brick.png", "py-brick")
            c.delete("py-brick")
    finally:
        assert d.stop() == 0


def test_fetch_format_of_a_wrong_type_names_it(client, tmp_path):
    """py35: format=1.0 or b"ptx" raised "bad argument type for built-in operation", and
    format=True fetched as format 1 (dds)."""
    for bad in (1.0, b"ptx", True):
        with pytest.raises(TypeError, match="format must be a name"):
            client.fetch("default", str(tmp_path / "x.ptx"), bad)
    client.fetch("default", str(tmp_path / "x.ptx"), 0)


def test_timeout_cannot_be_deleted(client):
    """py35: del c.timeout set "no timeout" silently."""
    client.timeout = 3
    with pytest.raises(AttributeError, match="None for no timeout"):
        del client.timeout
    assert client.timeout == 3.0


def test_closed_error_carries_its_message(daemon):
    """py35: ClosedError's .message was the class's "" (only str(e) had the text)."""
    c = daemon.client()
    c.close()
    with pytest.raises(seamtex.ClosedError) as e:
        c.ping()
    assert e.value.message == str(e.value) == "the Client is closed"
    assert e.value.status is None and e.value.code == 0


def test_threads_share_a_client_safely(client):
    face, u, v, _ = queries(1000)
    ref, _, _ = client.sample("default", face, u, v)
    errs = []

    def work():
        try:
            for _ in range(5):
                got, _, _ = client.sample("default", face, u, v)
                assert np.array_equal(got, ref)
        except Exception as e:  # pragma: no cover - reported below
            errs.append(e)

    ts = [threading.Thread(target=work) for _ in range(4)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert not errs


def test_name_lists_come_from_the_protocol():
    assert seamtex.MODES == ("discard", "traverse", "clamp")
    assert "ptex-mitchell" in seamtex.FILTERS and "bilinear" in seamtex.FILTERS
    assert seamtex.FORMATS == ("f32", "unorm8", "unorm16", "f16")
    assert seamtex.QSTATUS[seamtex.Q_NONFINITE] == "NONFINITE"


def test_f16_replies_arrive_as_floats(client):
    face = np.array([0, 1, 2], np.uint32)
    u, v = np.array([0.25, 0.5, 0.75]), np.array([0.5, 0.5, 0.5])
    v32, _, _ = client.sample("default", face, u, v)
    v16, _, _ = client.sample("default", face, u, v, format="f16")
    assert memoryview(v16).format == "f"
    a, b = memoryview(v32).cast("B").cast("f"), memoryview(v16).cast("B").cast("f")
    assert len(a) == len(b) == 12
    for x, y in zip(a, b):
        assert abs(x - y) <= abs(x) / 1024 + 1e-7   # binary16: 11 significant bits


def test_unix_socket_address(tmp_path):
    """Client("unix:/path") talks to a daemon on --listen unix:/path."""
    from pathlib import Path
    build = Path(os.environ.get("SEAMTEX_BUILD", Path(__file__).resolve().parents[2] / "build"))
    sock = tmp_path / "s.sock"
    port_file = tmp_path / "port"
    proc = subprocess.Popen([str(build / "seamtexd"), "--listen", "unix:%s" % sock,
                             "--port-file", str(port_file), "--log-level", "warn"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not (port_file.exists() and port_file.read_text().strip()):
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        with seamtex.Client("unix:%s" % sock) as c:
            assert c.ping() > 0
            assert "unix:" in repr(c) and ":7450" not in repr(c)
            assert [s["name"] for s in c.ls()] == ["default"]
    finally:
        proc.terminate()
        assert proc.wait(30) == 0
    assert not sock.exists()
