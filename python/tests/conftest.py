"""Fixtures of the frictiond Python tests: a daemon on loopback with a
temporary SQLite database, and a simulated fingertip stroke file."""

import os
import signal
import socket
import subprocess
import time
import urllib.request

import numpy as np
import pytest

TOKEN = "pytest-operator-0123456789abcdef0123456789abcdef"
ROOT = os.environ.get(
    "FRICTIOND_SOURCE_DIR",
    os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
BIN = os.environ.get("FRICTIOND_BIN_DIR", os.path.join(ROOT, "build", "bin"))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Daemon:
    """build/bin/frictiond on 127.0.0.1 with its own database."""

    def __init__(self, db: str, log: str) -> None:
        self.db, self.log = db, log
        self.port = 0
        self.proc = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self) -> None:
        exe = os.path.join(BIN, "frictiond")
        if not os.access(exe, os.X_OK):
            pytest.fail(f"{exe} missing: build the frictiond target first")
        for _ in range(5):
            self.port = free_port()
            with open(self.log, "ab") as log:
                self.proc = subprocess.Popen(
                    [exe, "--db", self.db, "--port", str(self.port), "--bind",
                     "127.0.0.1", "--data", "none", "--lcm", "none",
                     "--bootstrap-token", TOKEN],
                    stdout=log, stderr=subprocess.STDOUT)
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and self.proc.poll() is None:
                try:
                    with urllib.request.urlopen(self.url + "/healthz", timeout=1) as r:
                        if r.status == 200:
                            return
                except OSError:
                    time.sleep(0.05)
            self.stop()
        with open(self.log) as f:
            pytest.fail("frictiond did not start:\n" + f.read()[-2000:])

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc = None


@pytest.fixture(scope="session")
def daemon(tmp_path_factory):
    d = tmp_path_factory.mktemp("daemon")
    proc = Daemon(str(d / "frictiond.db"), str(d / "frictiond.log"))
    proc.start()
    yield proc
    proc.stop()


def simulate_strokes(seed: int = 7, strokes: int = 40) -> dict:
    """Fingertip-like strokes (CONTRACT.md columns): rest, then sliding at a
    constant speed; mu = 0.9 + 0.004 v - 0.03 Fn + eps, eps skewed."""
    rng = np.random.default_rng(seed)
    rate_hz, rest_s, slide_s = 200.0, 0.3, 0.5
    t, fn, ft, v = [], [], [], []
    now = 0.0
    for _ in range(strokes):
        f = rng.uniform(1.0, 4.0)
        s = rng.uniform(15.0, 60.0)
        for k in range(int(rest_s * rate_hz)):
            t.append(now)
            fn.append(f)
            ft.append(0.3 * f)
            v.append(0.0)
            now += 1 / rate_hz
        for k in range(int(slide_s * rate_hz)):
            eps = 0.05 * (rng.gamma(4.0) - 4.0) / 2.0
            t.append(now)
            fn.append(f)
            ft.append((0.9 + 0.004 * s - 0.03 * f + eps) * f)
            v.append(s)
            now += 1 / rate_hz
    return {"t_s": np.array(t), "fn_n": np.array(fn), "ft_n": np.array(ft),
            "v_mm_s": np.array(v)}


@pytest.fixture(scope="session")
def strokes():
    return simulate_strokes()


@pytest.fixture(scope="session")
def felt(daemon, strokes):
    """A daemon with material "felt" identified from simulated strokes."""
    import frictiond

    c = frictiond.Client(daemon.url, token=TOKEN)
    reply = c.upload("felt", strokes)
    assert reply["version"] >= 1, reply
    return daemon
