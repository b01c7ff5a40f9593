"""python/tests/test_interrupt.py - Ctrl-C (SIGINT) stops a call that waits on a stopped
daemon, even with timeout=None (py36).

libseamtex used to retry poll on EINTR and wait for ever with the GIL released, so
KeyboardInterrupt came only when the call returned (never, from a SIGSTOPped daemon). The
module now installs libseamtex's interrupt hook: each blocking call the module makes
(connect, request / reply, sample through the socket or a shared-memory region, upload and
fetch transfers, Job.wait) raises KeyboardInterrupt at once, and the Client stays usable (the
abandoned request's late reply is dropped).

Each case runs in a child process (SIGINT must not reach pytest): the child connects with
timeout=None, the test SIGSTOPs the daemon (or the child does, from a transfer's progress
callback), the child makes the call, the test sends SIGINT; the child reports
KeyboardInterrupt, the test SIGCONTs the daemon, the child checks its Client (or a new one
after an interrupted connect) answers and prints "usable".
Run: /usr/bin/python3 -m pytest -q python/tests/test_interrupt.py
"""

import os
import signal
import subprocess
import sys
import time

import pytest

import seamtex
from conftest import DATA, Daemon

# What the child runs. argv: case, host, port, daemon pid, data dir, scratch dir.
CHILD = r'''
import os, signal, sys, threading, time
import seamtex
case, host, port, dpid, data, tmp = sys.argv[1:]
port, dpid = int(port), int(dpid)

def say(*a):
    print(*a, flush=True)

def stopped():
    # every thread of the daemon stopped (SIGSTOP reaches them one at a time: a thread not
    # yet stopped could still answer)
    for t in os.listdir("/proc/%d/task" % dpid):
        with open("/proc/%d/task/%s/stat" % (dpid, t)) as f:
            if f.read().rsplit(")", 1)[1].split()[0] not in ("T", "t"):
                return False
    return True

def stop_daemon(*_):
    os.kill(dpid, signal.SIGSTOP)
    while not stopped():
        time.sleep(0.01)
    say("calling")            # the next wait is on a stopped daemon

stopped_once = []
def stop_at_first(done, total):
    if not stopped_once:
        stopped_once.append(1)
        stop_daemon()

def stop_and_raise(done, total):
    # Ctrl-C seen between chunks: the callback itself raises, no SIGINT comes after
    stop_daemon()
    raise KeyboardInterrupt

shm = case == "sample_shm"
c = None if case == "connect" else seamtex.Client(host, port, timeout=None, shm=shm)
job = None
if case == "job_wait":
    job = c.compress("default", "py-intr-bc1", level=9, replace=True)
if case == "elsewhere":
    # the kernel gives SIGINT to another thread (the main one blocks it): the hook's
    # interval, not EINTR, finds the pending handler
    threading.Thread(target=time.sleep, args=(60,), daemon=True).start()
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
say("ready")
sys.stdin.readline()          # the daemon is stopped now (or is stopped from a callback)
t0 = time.monotonic()
try:
    if case not in ("upload_midway", "fetch_midway", "upload_raises", "fetch_raises"):
        say("calling")
    if case == "connect":
        seamtex.Client(host, port, timeout=None)
    elif case in ("ping", "elsewhere"):
        c.ping()
    elif case in ("sample", "sample_shm"):
        import array
        c.sample("default", array.array("I", [1, 2, 3]), array.array("f", [0.5, 0.25, 0.75]),
                 array.array("f", [0.5, 0.5, 0.5]))
    elif case == "upload":
        c.upload(os.path.join(data, "ptex-ref", "cube8_k6_u8.ptx"), "py-intr-" + case)
    elif case == "upload_midway":
        c.upload(os.path.join(data, "ptex-ref", "cube8_k6_u8.ptx"), "py-intr-" + case,
                 chunk=4096, replace=True, progress=stop_at_first)
    elif case == "upload_raises":
        c.upload(os.path.join(data, "ptex-ref", "cube8_k6_u8.ptx"), "py-intr-" + case,
                 chunk=4096, replace=True, progress=stop_and_raise)
    elif case == "fetch_raises":
        c.fetch("default", os.path.join(tmp, "out.ptx"), progress=stop_and_raise)
    elif case == "fetch":
        c.fetch("default", os.path.join(tmp, "out.ptx"))
    elif case == "fetch_midway":
        c.fetch("default", os.path.join(tmp, "out.ptx"), progress=stop_at_first)
    elif case == "job_wait":
        job.wait()
    say("returned")
except KeyboardInterrupt:
    say("interrupted %.3f" % (time.monotonic() - t0))
sys.stdin.readline()          # the daemon runs again
if case == "elsewhere":
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
if c is None:
    c = seamtex.Client(host, port, timeout=30)
c.timeout = 30
assert not c.closed
c.ping()
c.ping()
assert any(s["name"] == "default" for s in c.ls())
if job is not None:
    job.cancel()
if case.startswith("upload"):
    try:
        c.delete("py-intr-" + case)
    except seamtex.NotFound:
        pass
say("usable")
'''

CASES = ["connect", "ping", "elsewhere", "sample", "upload", "upload_midway", "fetch",
         "fetch_midway", "job_wait"]
NEEDS_DATA = {"upload", "upload_midway", "upload_raises"}
# the progress callback stops the daemon and raises (Ctrl-C seen between chunks): no SIGINT is
# sent; the UPLOAD_ABORT / FETCH_CLOSE must not be waited for (left36: it was, for ever)
RAISES = ["upload_raises", "fetch_raises"]
MIDWAY = ("_midway", "_raises")


@pytest.fixture(scope="module")
def own_daemon():
    """A daemon of this module's own: the tests stop and continue it."""
    d = Daemon()
    yield d
    os.kill(d.proc.pid, signal.SIGCONT)
    assert d.stop() == 0


@pytest.fixture(scope="module")
def unix_daemon():
    d = Daemon(unix=True)
    yield d
    os.kill(d.proc.pid, signal.SIGCONT)
    assert d.stop() == 0


def line(p, want, secs):
    """The child's next line, which must start with one of want (a tuple), within secs."""
    deadline = time.monotonic() + secs
    import select
    while time.monotonic() < deadline:
        r, _, _ = select.select([p.stdout], [], [], 0.05)
        if r:
            s = p.stdout.readline()
            if not s:
                break
            if s.startswith(want):
                return s.strip()
            raise AssertionError("child said %r, expected %r" % (s, want))
    raise AssertionError("no %r from the child within %s s (stderr: %s)" % (
        want, secs, p.stderr.read() if p.poll() is not None else "(still running)"))


def run_case(d, case, tmp_path):
    if case in NEEDS_DATA and not (DATA / "ptex-ref" / "cube8_k6_u8.ptx").exists():
        pytest.skip("SEAMTEX_DATA=%s lacks ptex-ref/cube8_k6_u8.ptx" % DATA)
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(seamtex.__file__)),
               PYTHONDONTWRITEBYTECODE="1")
    p = subprocess.Popen([sys.executable, "-c", CHILD, case, d.host, str(d.port),
                          str(d.proc.pid), str(DATA), str(tmp_path)],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env)
    try:
        line(p, ("ready",), 60)
        if not case.endswith(MIDWAY):
            os.kill(d.proc.pid, signal.SIGSTOP)
            deadline = time.monotonic() + 30
            while not d.stopped():      # before the call: no thread left to answer
                assert time.monotonic() < deadline
                time.sleep(0.01)
        p.stdin.write("go\n")
        p.stdin.flush()
        line(p, ("calling",), 60)
        assert d.stopped()
        if case not in RAISES:
            time.sleep(0.3)       # the call is waiting by now (it cannot end: no timeout)
            p.send_signal(signal.SIGINT)
        # without the hook nothing comes while the daemon stays stopped; with it the
        # interrupt comes at once (the child's figure is in the message on failure)
        got = line(p, ("interrupted", "returned"), 10)
        assert got.startswith("interrupted"), got
        os.kill(d.proc.pid, signal.SIGCONT)
        p.stdin.write("go\n")
        p.stdin.flush()
        line(p, ("usable",), 60)
        assert p.wait(30) == 0, p.stderr.read()
    finally:
        os.kill(d.proc.pid, signal.SIGCONT)
        if p.poll() is None:
            p.kill()
            p.wait()


@pytest.mark.parametrize("case", CASES)
def test_ctrl_c_stops_a_call_on_a_stopped_daemon(own_daemon, case, tmp_path):
    run_case(own_daemon, case, tmp_path)


@pytest.mark.parametrize("case", RAISES)
def test_a_transfer_its_callback_stopped_does_not_wait_for_its_cleanup(own_daemon, case,
                                                                       tmp_path):
    run_case(own_daemon, case, tmp_path)


def test_ctrl_c_stops_a_sample_through_shared_memory(unix_daemon, tmp_path):
    run_case(unix_daemon, "sample_shm", tmp_path)
