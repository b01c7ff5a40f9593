"""python/tests/test_shm.py - Client(..., shm=...): sampling through a shared-memory region on a
unix: connection (PROTOCOL.md 4.12) against live daemons on Unix sockets (conftest.Daemon with
unix=True).

Results through the region equal the socket path's byte for byte (f32, unorm8, f16, with
coverage and status, footprints, several calls on one region); a call too big for the region
goes over the socket and still matches; a daemon that refuses (over --shm-max: TooLarge;
--shm-max 0: Unsupported) or a TCP address raises with shm=True and falls back with
shm="auto" (the default), the reason in shm_status; bad arguments raise ValueError.
Run: /usr/bin/python3 -m pytest -q python/tests/test_shm.py
"""

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
