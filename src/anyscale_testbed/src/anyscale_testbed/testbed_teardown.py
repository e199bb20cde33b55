"""The test bed's teardown steps: ending process groups, the processes of a network
namespace, the namespace and a veth. Each is bounded in time and returns what it could not
remove, in words, instead of raising: a teardown must go on to its last step whatever one
step met, and end in one clear line rather than a traceback."""
import contextlib
import os
import signal
import subprocess
import threading
import time
from typing import List, Sequence


def quiet(argv: List[str]) -> subprocess.CompletedProcess:
    return subprocess.run(argv, capture_output=True, text=True)


def attempt(left: List[str], what: str, step):
    """Runs one teardown step; an error is noted in `left`, so the next steps still run."""
    try:
        step()
    except Exception as e:  # noqa: BLE001 - teardown goes on whatever one step met
        left.append(f"{what}: {e}")


def stop_process_groups(processes: List[subprocess.Popen], grace_s: float,
                        kill_wait_s: float = 2.0) -> List[str]:
    """SIGINT to every process group (roslaunch then stops its nodes), SIGKILL after grace_s,
    and SIGKILL to what is left of each group once its leader ended (a member that ignored
    SIGINT outlives it). Returns the processes that did not end, in words."""
    for proc in processes:
        if proc.poll() is None:
            signal_group(proc.pid, signal.SIGINT)
    deadline = time.monotonic() + grace_s
    left = []
    for proc in processes:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            signal_group(proc.pid, signal.SIGKILL)
            try:
                proc.wait(timeout=kill_wait_s)
            except subprocess.TimeoutExpired:
                left.append(f"process {proc.pid} ({' '.join(map(str, proc.args))[:60]})")
        signal_group(proc.pid, signal.SIGKILL)
    return left


def remove_namespace(namespace: str, wait_s: float = 2.0) -> List[str]:
    """Kills whatever still runs in the namespace (started by others, e.g. an agent's nodes),
    then deletes it; returns what is left, in words."""
    listed = quiet(["ip", "netns", "pids", namespace]).stdout.split()
    pids = [int(p) for p in listed if p.isdigit()]
    for pid in pids:
        signal_quietly(pid, signal.SIGKILL)
    alive = wait_until_gone(pids, wait_s)
    quiet(["ip", "netns", "del", namespace])
    left = [f"process {pid} in namespace {namespace}" for pid in alive]
    if namespace in quiet(["ip", "netns", "list"]).stdout.split():
        left.append(f"namespace {namespace}")
    return left


def remove_veths(interfaces: Sequence[str]) -> List[str]:
    """Deletes those of the interfaces that exist in this (the root) namespace; returns the
    ones left."""
    left = []
    for name in interfaces:
        if quiet(["ip", "link", "show", name]).returncode != 0:
            continue
        quiet(["ip", "link", "del", name])
        if quiet(["ip", "link", "show", name]).returncode == 0:
            left.append(f"veth {name}")
    return left


def wait_until_gone(pids: Sequence[int], wait_s: float, poll_s: float = 0.05) -> List[int]:
    """The pids still alive (not ended, not a zombie) after waiting up to wait_s."""
    deadline = time.monotonic() + wait_s
    alive = [p for p in pids if is_alive(p)]
    while alive and time.monotonic() < deadline:
        time.sleep(poll_s)
        alive = [p for p in alive if is_alive(p)]
    return alive


def is_alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except (OSError, IndexError):
        return False


@contextlib.contextmanager
def signals_deferred(signals=(signal.SIGINT, signal.SIGTERM)):
    """A second Ctrl-C during the teardown would stop it half-way and leave the bed behind:
    SIGINT and SIGTERM wait until the block is done, then arrive. Only the main thread can
    set handlers; elsewhere the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: List[int] = []
    previous = {sig: signal.signal(sig, lambda sig, _frame: caught.append(sig))
                for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        for sig in dict.fromkeys(caught):
            signal.raise_signal(sig)


def signal_group(pid: int, sig: int):
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def signal_quietly(pid: int, sig: int):
    try:
        os.kill(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass
