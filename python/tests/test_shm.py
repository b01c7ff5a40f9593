"""python/tests/test_shm.py - Client(..., shm=...): sampling through a shared-memory region on a
unix: connection (PROTOCOL.md 4.12) against live daemons on Unix sockets (conftest.Daemon with
unix=True).

Results through the region equal the socket path's byte for byte (f32, unorm8, f16, with
coverage and status, footprints, several calls on one region); a call too big for the region
goes over the socket and still matches; a daemon that refuses (over --shm-max: TooLarge;
--shm-max 0: Unsupported) or a TCP address raises with shm=True and falls back with
shm="auto" (the default), the reason in shm_status; bad arguments raise ValueError;
server and shm_status answer while another thread's call waits on a stopped daemon.
Run: /usr/bin/python3 -m pytest -q python/tests/test_shm.py
"""

import os
import signal
import threading
import time

import numpy as np
import pytest

import seamtex
from conftest import Daemon

RNG = np.random.default_rng(11)


def queries(n, deriv=0.004):
    face = RNG.integers(0, 384, n, dtype=np.uint32)
    u = RNG.random(n, dtype=np.float32)
    v = RNG.random(n, dtype=np.float32)
    d = RNG.random(n, dtype=np.float32) * np.float32(deriv)
    return face, u, v, d


@pytest.fixture(scope="module")
def unix_daemon():
    d = Daemon(unix=True)
    yield d
    assert d.stop() == 0


def started(*extra):
    return Daemon(*extra, unix=True)


def same(a, b):
    for x, y in zip(a, b):
        assert x.dtype == y.dtype and x.shape == y.shape
        assert x.tobytes() == y.tobytes()


def test_shm_results_equal_the_socket(unix_daemon):
    face, u, v, d = queries(200_000)
    with unix_daemon.client(shm=True) as s, unix_daemon.client(shm=False) as p:
        st = s.shm_status
        assert st["attached"] is True and st["bytes"] == 64 << 20 and st["reason"] is None
        assert p.shm_status["attached"] is False
        assert "shm=False" in p.shm_status["reason"]
        for fmt, mode, filt in [("f32", "traverse", "trilinear"), ("unorm8", "discard", "aniso"),
                                ("f16", "clamp", "bilinear"), ("f32", "traverse", "ptex-mitchell")]:
            kw = dict(mode=mode, filter=filt, format=fmt)
            a = s.sample("default", face, u, v, d, 0, 0, d, **kw)
            b = p.sample("default", face, u, v, d, 0, 0, d, **kw)
            same(a, b)
        # statuses travel through the region too
        bad = face.copy()
        bad[::7] = 100000
        same(s.sample("default", bad, u, v), p.sample("default", bad, u, v))
        st = s.shm_status
        assert st["via_shm"] >= 5 and st["via_socket"] == 0
        assert p.shm_status["via_shm"] == 0 and p.shm_status["via_socket"] >= 5


def test_call_bigger_than_the_region_goes_over_the_socket(unix_daemon):
    face, u, v, d = queries(100_000)     # 2.8 MB of queries: more than a 1 MiB region
    with unix_daemon.client(shm=True, shm_bytes=1 << 20) as s, \
            unix_daemon.client(shm=False) as p:
        assert s.shm_status["bytes"] == 1 << 20
        same(s.sample("default", face, u, v, d, 0, 0, d),
             p.sample("default", face, u, v, d, 0, 0, d))
        st = s.shm_status
        assert st["via_shm"] == 0 and st["via_socket"] == 1
        small = queries(1000)
        same(s.sample("default", *small[:3]), p.sample("default", *small[:3]))
        assert s.shm_status["via_shm"] == 1


@pytest.mark.parametrize("extra, cls, words", [
    (("--shm-max", "4096"), seamtex.TooLarge, "shm-max"),
    (("--shm-max", "0"), seamtex.Unsupported, "capability SHM"),
])
def test_refused_raises_or_falls_back(extra, cls, words):
    d = started(*extra)
    try:
        with pytest.raises(cls, match=words):
            d.client(shm=True)
        face, u, v, _ = queries(5000)
        with d.client() as a, d.client(shm=False) as p:    # auto by default
            st = a.shm_status
            assert st["attached"] is False and st["bytes"] == 0
            assert words in st["reason"]
            same(a.sample("default", face, u, v), p.sample("default", face, u, v))
            assert a.shm_status["via_socket"] == 1
    finally:
        assert d.stop() == 0


def test_tcp_address(daemon):
    with pytest.raises(seamtex.InvalidArgument, match="unix:"):
        daemon.client(shm=True)
    for kw in ({}, {"shm": "auto"}):
        with daemon.client(**kw) as c:
            assert c.shm_status["attached"] is False
            assert "unix:" in c.shm_status["reason"]
            assert c.ping() > 0


def test_auto_is_the_default_on_unix(unix_daemon):
    face, u, v, _ = queries(3000)
    with unix_daemon.client() as a:
        assert a.shm_status["attached"] is True
        a.sample("default", face, u, v)
        assert a.shm_status["via_shm"] == 1


def test_bad_arguments(unix_daemon):
    with pytest.raises(ValueError, match="shm must be"):
        unix_daemon.client(shm="yes")
    with pytest.raises(ValueError, match="shm_bytes"):
        unix_daemon.client(shm=True, shm_bytes=0)
    with pytest.raises(TypeError):
        unix_daemon.client(shm=True, shm_bytes="big")
    c = unix_daemon.client(shm=True)
    c.close()
    with pytest.raises(seamtex.ClosedError):
        c.shm_status


def test_server_and_shm_status_answer_during_another_threads_call():
    """lib35 (py35's list): Client.server and shm_status took the Client's lock, so they waited
    behind another thread's call (for ever with timeout=None and a stopped daemon). HELLO's
    facts are kept at connect and the shared-memory counts at each call's end: both answer
    at once. The other thread's ping cannot end before SIGCONT (no timeout), which the test
    checks, so the reads ran while it was in its call."""
    d = started()
    try:
        with d.client(shm=True, timeout=None) as c:
            face, u, v, _ = queries(100)
            c.sample("default", face, u, v)
            hello = c.server
            before = c.shm_status
            assert before["via_shm"] == 1 and before["attached"] is True
            os.kill(d.proc.pid, signal.SIGSTOP)
            deadline = time.monotonic() + 30
            while not d.stopped():
                assert time.monotonic() < deadline
                time.sleep(0.01)
            calling = threading.Event()
            ended = {}

            def long_call():
                calling.set()
                c.ping()
                ended["t"] = time.monotonic()

            a = threading.Thread(target=long_call)
            a.start()
            calling.wait()
            time.sleep(0.3)          # the ping has the lock by now (it waits on the socket)
            got = {}

            def reads():
                got["server"] = c.server
                got["shm"] = c.shm_status

            b = threading.Thread(target=reads)
            b.start()
            b.join(10)
            answered = not b.is_alive()
            cont = time.monotonic()
            os.kill(d.proc.pid, signal.SIGCONT)
            a.join(60)
            b.join(60)
            assert not a.is_alive() and ended["t"] >= cont   # the ping was waiting all along
            assert answered, "server / shm_status waited for the other thread's call"
            assert got["server"] == hello
            assert got["shm"] == before
        with pytest.raises(seamtex.ClosedError):
            c.server
        with pytest.raises(seamtex.ClosedError):
            c.shm_status
    finally:
        os.kill(d.proc.pid, signal.SIGCONT)
        assert d.stop() == 0
