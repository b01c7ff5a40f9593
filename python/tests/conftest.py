"""python/tests/conftest.py - fixtures of the Python module's tests: a real seamtexd on
loopback, like tests/common/daemon_fixture.h does for the C tests.

The daemon is $SEAMTEX_BUILD/seamtexd (default: build/ of this tree), started on 127.0.0.1
port 0 with --port-file and a fresh temp data dir, stopped with SIGTERM at the end (a
non-zero exit fails the session). The module is imported from $SEAMTEX_BUILD/python
(`make python` puts it there) unless SEAMTEX_PY_INSTALLED=1 (test an installed copy).
Shared assets come from $SEAMTEX_DATA (default ../shared/data); tests that need them are
skipped without it.
"""

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("SEAMTEX_BUILD", ROOT / "build"))
DATA = Path(os.environ.get("SEAMTEX_DATA", ROOT.parent / "shared" / "data"))
if os.environ.get("SEAMTEX_PY_INSTALLED") != "1":
    sys.path.insert(0, str(BUILD / "python"))

import seamtex  # noqa: E402


class Daemon:
    """One seamtexd process on 127.0.0.1:<free port>, or with unix=True on
    unix:<its temp dir>/s.sock (host is then that address)."""

    def __init__(self, *extra, unix=False):
        self.dir = Path(tempfile.mkdtemp(prefix="seamtex-py-"))
        self.log = self.dir / "daemon.log"
        exe = BUILD / "seamtexd"
        if not exe.exists():
            pytest.exit("%s is missing: run make first" % exe, returncode=1)
        port_file = self.dir / "port"
        self.host = "unix:%s" % (self.dir / "s.sock") if unix else "127.0.0.1"
        self.port = 0
        with open(self.log, "wb") as log:
            self.proc = subprocess.Popen(
                [str(exe), "--listen", self.host if unix else "127.0.0.1:0",
                 "--data-dir", str(self.dir / "data"),
                 "--port-file", str(port_file), "--log-level", "warn", *extra],
                stdout=log, stderr=log)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError("seamtexd exited at start:\n" + self.log.read_text())
            if port_file.exists() and port_file.read_text().strip():
                self.port = 0 if unix else int(port_file.read_text().strip())
                try:
                    seamtex.Client(self.host, self.port, timeout=5).close()
                    return
                except seamtex.Error:
                    pass
            time.sleep(0.05)
        self.proc.kill()
        raise RuntimeError("seamtexd did not become ready in 60 s")

    def client(self, **kw):
        return seamtex.Client(self.host, self.port, **kw)

    def stopped(self):
        """True when every thread of the daemon is stopped (SIGSTOP is taken by one thread at
        a time: a thread not yet stopped could still answer)."""
        tasks = "/proc/%d/task" % self.proc.pid
        for t in os.listdir(tasks):
            with open("%s/%s/stat" % (tasks, t)) as f:
                if f.read().rsplit(")", 1)[1].split()[0] not in ("T", "t"):
                    return False
        return True

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        rc = self.proc.returncode
        shutil.rmtree(self.dir, ignore_errors=True)
        return rc


@pytest.fixture(scope="session")
def daemon():
    d = Daemon()
    yield d
    rc = d.stop()
    assert rc == 0, "seamtexd exited with status %s" % rc


@pytest.fixture
def client(daemon):
    with daemon.client() as c:
        yield c


@pytest.fixture(scope="session")
def data():
    if not DATA.is_dir():
        pytest.skip("SEAMTEX_DATA=%s is missing" % DATA)
    return DATA


@pytest.fixture(scope="session")
def build():
    return BUILD
