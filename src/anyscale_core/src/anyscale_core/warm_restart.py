"""A warm restart for a rospy node that roslaunch respawns (pure Python, no ROS): the process
roslaunch started keeps the node's imports and forks the node from them, and forks it again at
once when it is killed, so that a restart costs no imports.

Why. A remote node lives only while the decision node renews its lease (robot.launch: lease_s
3 s), and on the robot's quota the decision node's imports alone took longer than that after a
respawn; forked from a process that holds them, it runs again in about 1 s and adopts the
remote nodes while their leases still run (the measured incident: docs/design/decision_node.md).

How. become_node() returns in the node's process. The process that called it stays behind as
the node's warm standby: it names itself "standby:<name>" (/proc/PID/comm, as the agents'
python_standby does, so that tools looking for the node's process skip it), waits for the
node, and
- when the node is killed by a signal it did not pass on: forks it again, at once the first
  time, then after delays that double (restart_backoff; a crash loop does not spin);
- when the node exits by itself: exits with its status (roslaunch's respawn, or its required,
  then does what it always did);
- on SIGINT or SIGTERM (roslaunch stopping it): passes the signal to the node, waits for it
  and ends as it ended.
The node runs in a process group of its own, so that roslaunch's signal to the group reaches
it once, through the standby, and it gets SIGKILL if the standby dies (PR_SET_PDEATHSIG): a
standby killed by roslaunch's last escalation leaves no node behind."""
import ctypes
import os
import signal
import sys
import time
from typing import Callable, Optional

from .restart_backoff import BackoffParams, RestartBackoff

# The agents' standbys (anyscale_agent_cpp's python_standby) are named so too: a tool that looks
# for a node's process (the test bed's census) skips them.
STANDBY_COMM_PREFIX = "standby:"
PR_SET_PDEATHSIG = 1
PR_SET_NAME = 15
PASSED_ON = (signal.SIGINT, signal.SIGTERM)
POLL_S = 0.05


def become_node(backoff: BackoffParams = BackoffParams(),
                say: Callable[[str], None] = lambda line: print(line, file=sys.stderr,
                                                                flush=True)) -> None:
    """Returns in the node's process (a child of the caller); the caller stays its warm standby
    until the node ends for good, then exits with the node's status (SystemExit, or the
    node's signal)."""
    standby = _Standby(_comm(), backoff, say)
    if standby.run():
        return
    if standby.signal is not None:
        signal.signal(standby.signal, signal.SIG_DFL)
        os.kill(os.getpid(), standby.signal)    # ended as the node ended, for roslaunch's log
    sys.exit(standby.code)


class _Standby:
    def __init__(self, comm: str, backoff: BackoffParams, say: Callable[[str], None]):
        self.comm = comm
        self.backoff = RestartBackoff(backoff)
        self.say = say
        self.node = 0
        self.stop: Optional[int] = None     # the signal that asked this process to stop
        self.code = 0                       # the node's exit status, if it exited
        self.signal: Optional[int] = None   # the node's signal, if one ended it for good

    def run(self) -> bool:
        """True in the node's process; False in the standby once the node ended for good."""
        _set_comm(STANDBY_COMM_PREFIX + self.comm)
        for sig in PASSED_ON:
            signal.signal(sig, self._pass_on)
        while True:
            if not self._fork():
                return True
            status = _wait(self.node)
            self.node = 0
            if self.stop is not None or not os.WIFSIGNALED(status):
                self.code = os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else 1
                self.signal = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
                return False
            killed_by = signal.Signals(os.WTERMSIG(status)).name
            if not self._wait_for_turn(killed_by):
                return False

    def _fork(self) -> bool:
        """Forks the node: True in the standby, False in the node. Signals are held meanwhile,
        so that neither runs the other's handler."""
        parent = os.getpid()
        signal.pthread_sigmask(signal.SIG_BLOCK, PASSED_ON)
        pid = os.fork()
        if pid == 0:
            os.setpgid(0, 0)
            ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            if os.getppid() != parent:
                os._exit(1)                 # the standby died before the line above
            _set_comm(self.comm)
            # As a new process starts: rospy chains its handlers to these.
            signal.signal(signal.SIGINT, signal.default_int_handler)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, PASSED_ON)
            return False
        try:
            os.setpgid(pid, pid)
        except OSError:
            pass                            # the node did it first, or has ended already
        self.node = pid
        signal.pthread_sigmask(signal.SIG_UNBLOCK, PASSED_ON)
        if self.stop is not None:           # asked to stop while the fork was under way
            _kill(pid, self.stop)
        return True

    def _wait_for_turn(self, killed_by: str) -> bool:
        """After the node was killed: True when it may be forked again (restart_backoff), False
        if this process was asked to stop meanwhile."""
        self.backoff.due(time.monotonic())
        delay = self.backoff.delay_s() - (time.monotonic() - self.backoff.last_restart)
        self.say(f"{self.comm}: the node was killed ({killed_by}); started again from its warm "
                 f"standby (pid {os.getpid()}) " + (f"in {delay:.1f} s (restarts back off)"
                                                    if delay > 0 else "at once"))
        while not self.backoff.due(time.monotonic()):
            if self.stop is not None:
                self.code = 0
                return False
            time.sleep(POLL_S)
        self.backoff.restarted(time.monotonic())
        return self.stop is None

    def _pass_on(self, sig, _frame):
        self.stop = sig
        if self.node:
            _kill(self.node, sig)


def _wait(pid: int) -> int:
    while True:
        try:
            return os.waitpid(pid, 0)[1]
        except ChildProcessError:
            return 0
        except InterruptedError:
            continue


def _kill(pid: int, sig: int):
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass


def _comm() -> str:
    try:
        with open("/proc/self/comm") as f:
            return f.read().strip()
    except OSError:
        return os.path.basename(sys.argv[0])[:15]


def _set_comm(name: str):
    # The kernel keeps 15 bytes of a comm.
    ctypes.CDLL(None).prctl(PR_SET_NAME, ctypes.c_char_p(name.encode()[:15]), 0, 0, 0)
