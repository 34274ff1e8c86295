"""Fixtures for the Python client's tests: a real fulcrum-server on a loopback port.

ctest sets FULCRUM_SERVER_BIN, FULCRUM_CLI_BIN, FULCRUM_SCENES_DIR and PYTHONPATH (the build's
python/ directory); run by hand, the defaults below find a build in build/.
"""

import os
import pathlib
import signal
import subprocess
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("FULCRUM_BUILD_DIR", ROOT / "build"))
SERVER_BIN = pathlib.Path(os.environ.get("FULCRUM_SERVER_BIN", BUILD / "bin" / "fulcrum-server"))
CLI_BIN = pathlib.Path(os.environ.get("FULCRUM_CLI_BIN", BUILD / "bin" / "fulcrum"))
SCENES = pathlib.Path(os.environ.get("FULCRUM_SCENES_DIR", ROOT / "scenes"))
EXAMPLES = ROOT / "client" / "python" / "examples"
# The interpreter Debian's python3-grpcio is installed for (not whatever python3 is first on
# PATH): examples run as subprocesses use the same one as the tests.
PYTHON = os.environ.get("FULCRUM_PYTHON", "/usr/bin/python3")


class Server:
    """fulcrum-server --listen 127.0.0.1:0 as a subprocess; `address` is the port it chose."""

    def __init__(self, workdir, *flags):
        self.workdir = pathlib.Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.stdout_path = self.workdir / "server.out"
        self.stderr_path = self.workdir / "server.err"
        with open(self.stdout_path, "wb") as out, open(self.stderr_path, "wb") as err:
            self.process = subprocess.Popen(
                [str(SERVER_BIN), "--listen", "127.0.0.1:0", *map(str, flags)],
                stdout=out, stderr=err)
        self.address = self._wait_for_address()

    def _wait_for_address(self, seconds=10.0):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for line in self.stdout_path.read_text().splitlines():
                if line.startswith("listening on "):
                    return line[len("listening on "):].strip()
            if self.process.poll() is not None:
                break
            time.sleep(0.05)
        self.process.kill()
        raise RuntimeError(f"fulcrum-server did not start: {self.stderr_path.read_text()}")

    def stop(self):
        """SIGTERM; the server must exit 0."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                return self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                raise
        return self.process.returncode


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    if not SERVER_BIN.exists():
        pytest.fail(f"{SERVER_BIN} is missing: build the fulcrum-server target first")
    workdir = tmp_path_factory.mktemp("server")
    running = Server(workdir, "--replay-dir", workdir / "replays")
    yield running
    assert running.stop() == 0, running.stderr_path.read_text()


@pytest.fixture(scope="module")
def client(server):
    import fulcrum
    with fulcrum.connect(server.address, wait=10) as connected:
        yield connected


@pytest.fixture
def scenes():
    return SCENES


@pytest.fixture
def make_server(tmp_path):
    """Starts servers with extra flags; each is stopped (and must exit 0) after the test."""
    started = []

    def start(*flags):
        running = Server(tmp_path / f"server{len(started)}", *flags)
        started.append(running)
        return running

    yield start
    for running in started:
        assert running.stop() == 0, running.stderr_path.read_text()
