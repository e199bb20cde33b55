"""What the live tests share: a free port for a private roscore, the environment that points
the commands and nodes they start at it, Debian's stock executables, and the processes they
start, each in a session of its own, ended as a group after the test."""
import os
import socket
import subprocess
import sys
from typing import Dict, List

import pytest

from anyscale_core.process_group import stop_process_group

STOP_GRACE_S = 10.0


def free_port(preferred: int) -> int:
    """`preferred` when nothing listens there, else a port the kernel hands out."""
    for port in (preferred, 0):
        with socket.socket() as s:
            try:
                s.bind(("localhost", port))
                return s.getsockname()[1]
            except OSError:
                continue
    raise OSError("no free port")


def private_master_env(port: int, tmp) -> Dict[str, str]:
    """This process's environment for a roscore on localhost:`port`, with its ROS home and logs
    below the directory `tmp`, and this interpreter's sys.path for the commands it runs."""
    env = {**os.environ, "ROS_MASTER_URI": f"http://localhost:{port}",
           "ROS_HOSTNAME": "localhost", "ROS_HOME": str(tmp / "ros_home"),
           "ROS_LOG_DIR": str(tmp / "log"), "PYTHONPATH": os.pathsep.join(sys.path),
           "PATH": "/usr/bin:" + os.environ["PATH"]}
    env.pop("ROS_IP", None)
    return env


def stock_executable(package: str, name: str) -> str:
    """A Debian- or catkin-installed executable, where the agent finds it: <prefix>/lib/pkg/."""
    prefixes = [p for p in os.environ.get("CMAKE_PREFIX_PATH", "").split(":") if p] + ["/usr"]
    for prefix in prefixes:
        path = os.path.join(prefix, "lib", package, name)
        if os.access(path, os.X_OK):
            return path
    pytest.skip(f"{package}/{name} is not installed (apt-get install topic-tools)")


class Processes:
    """Processes started with `env`, each in a session of its own with its output in a log file
    in `log_dir`; stop() ends one, close() all that are left, newest first."""

    def __init__(self, log_dir, env: Dict[str, str]):
        self.log_dir = log_dir
        self.env = env
        self.procs: List[subprocess.Popen] = []

    def start(self, argv: List[str]) -> subprocess.Popen:
        log = open(self.log_dir / f"proc{len(self.procs)}.log", "w")
        proc = subprocess.Popen(argv, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
        log.close()
        self.procs.append(proc)
        return proc

    @staticmethod
    def stop(proc: subprocess.Popen):
        stop_process_group(proc, STOP_GRACE_S)

    def close(self):
        for proc in reversed(self.procs):
            self.stop(proc)
