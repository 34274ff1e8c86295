"""The package installs into a virtual environment from the build tree, without the network."""

import os
import pathlib
import shutil
import subprocess

import fulcrum
from conftest import PYTHON

BUILT = pathlib.Path(fulcrum.__file__).resolve().parents[1]  # build/python


def test_pip_installs_the_build_tree_into_a_venv(server, tmp_path):
    source = tmp_path / "source"  # a copy: pip builds in place and would write into build/
    shutil.copytree(BUILT, source, ignore=shutil.ignore_patterns("__pycache__", "build",
                                                                 "*.egg-info"))
    venv = tmp_path / "venv"
    # --system-site-packages: the venv uses Debian's grpcio, protobuf and numpy (and
    # setuptools, for --no-build-isolation), so nothing is downloaded.
    subprocess.run([PYTHON, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    pip = subprocess.run([str(venv / "bin" / "pip"), "install", "--no-index",
                          "--no-build-isolation", "--quiet", str(source)],
                         capture_output=True, text=True, env=env, check=False)
    assert pip.returncode == 0, pip.stdout + pip.stderr
    check = ("import fulcrum, sys; c = fulcrum.connect(sys.argv[1], wait=10); "
             "print(fulcrum.__file__); print(c.stats().uptime_s > 0)")
    done = subprocess.run([str(venv / "bin" / "python"), "-c", check, server.address],
                          capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr
    installed, answered = done.stdout.split()
    assert installed.startswith(str(venv)) and answered == "True"
    assert (pathlib.Path(installed).parent / "v1" / "service_pb2_grpc.py").exists()
