"""Calls to the agents' services with timeouts, off the decision loop's thread."""
import threading
import time
import xmlrpc.client
from typing import Callable, Dict, Hashable, Optional

import rosgraph
import rospy
from anyscale_msgs.srv import (ListNodes, RenewLeases, SetWatchedTopics, StartNode,
                               StopNode)

from . import xmlrpc_calls
from .job_worker import JobWorker
from .service_lookup import RememberingServiceProxy, ServiceUris


def call_with_timeout(fn: Callable, timeout_s: float):
    """fn() or TimeoutError after timeout_s. rospy service calls have no timeout of their own
    and block for as long as TCP retries on a partitioned link, so the call runs in a daemon
    thread that is abandoned if it hangs."""
    box = {}

    def run():
        try:
            box["value"] = fn()
        except Exception as e:  # noqa: BLE001 - handed to the caller as is
            box["error"] = e

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        raise TimeoutError(f"no answer within {timeout_s:g} s")
    if "error" in box:
        raise box["error"]
    return box["value"]


START_RETRY_DELAY_S = 0.2


class AgentClient:
    """The services of the agents under /anyscale/<scale>/."""

    SERVICES = {"start_node": StartNode, "stop_node": StopNode, "renew_leases": RenewLeases,
                "list_nodes": ListNodes, "set_watched_topics": SetWatchedTopics}

    def __init__(self, timeout_s: float, stop_timeout_s: float, stop_sigint_timeout_s: float = 0.0):
        self.timeout_s = timeout_s
        self.stop_timeout_s = stop_timeout_s
        self.stop_sigint_timeout_s = stop_sigint_timeout_s
        self.uris = ServiceUris()

    def call(self, scale: str, service: str, timeout_s: Optional[float] = None, **request):
        # A fresh proxy per call: proxies are not meant to be shared between threads.
        proxy = RememberingServiceProxy(f"/anyscale/{scale}/{service}", self.SERVICES[service],
                                        self.uris)
        return call_with_timeout(lambda: proxy(**request),
                                 self.timeout_s if timeout_s is None else timeout_s)

    def start(self, scale, node, overrides, lease_s, cpu_percent=0.0, memory_mb=0.0):
        """One retry when the call broke off without an answer: in one CI run of the live
        migration test, the initial start of the EKF ended in "unable to receive data from
        sender", nothing started it again, and navigation never ran. Starting is idempotent at
        the agent (a node already running there is answered with its pid), so asking again
        cannot start a second instance. A timeout is not retried: on a partitioned link it would
        only double the wait."""
        def call():
            return self.call(scale, "start_node", node=node, param_overrides=overrides,
                             lease_s=lease_s, cpu_percent=cpu_percent, memory_mb=memory_mb)
        try:
            return call()
        except rospy.ServiceException as e:
            rospy.logwarn("anyscale decision: start %s on %s: %s; asking once more", node, scale, e)
            time.sleep(START_RETRY_DELAY_S)
            return call()

    def stop(self, scale, node, timeout_s=None, pause=False):
        return self.call(scale, "stop_node", timeout_s or self.stop_timeout_s, node=node,
                         wait=True, sigint_timeout_s=self.stop_sigint_timeout_s, pause=pause)

    def renew(self, scale, nodes, lease_s):
        return self.call(scale, "renew_leases", min(self.timeout_s, lease_s), nodes=list(nodes),
                         lease_s=lease_s)

    def set_watched(self, scale, topics, subscribers=()):
        return self.call(scale, "set_watched_topics", topics=list(topics),
                         subscribers=list(subscribers))


def registered_pid(node: str, caller_id: str, timeout_s: float = 1.0) -> Optional[int]:
    """pid of the process the master lists under `node` (asked over the node's own XML-RPC,
    with a timeout: it may sit behind a partitioned link); None if unknown."""
    try:
        uri = rosgraph.Master(caller_id).lookupNode(node)
        code, _, pid = xmlrpc_calls.proxy(uri, timeout_s).getPid(caller_id)
    except (rosgraph.MasterError, OSError, xmlrpc.client.Error):
        return None
    return pid if code == 1 else None


def wait_registered(node: str, pid: int, caller_id: str, timeout_s: float,
                    also: Callable[[], bool] = lambda: False, period_s: float = 0.05) -> bool:
    """True once the master lists `node` with `pid` (or `also()` says it runs), within
    timeout_s."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not rospy.is_shutdown():
        if registered_pid(node, caller_id) == pid or also():
            return True
        time.sleep(period_s)
    return False


class CallFailures:
    """Calls the decision node repeats (lease renewals, watch lists) fail for as long as an
    agent is out of reach: say so when a call starts failing and when it works again, not at
    every retry."""

    def __init__(self):
        self._failing: Dict[Hashable, int] = {}     # key -> failed calls in a row

    def failed(self, key: Hashable) -> bool:
        """Counts a failure; True if the call had been working (log it)."""
        self._failing[key] = self._failing.get(key, 0) + 1
        return self._failing[key] == 1

    def succeeded(self, key: Hashable) -> int:
        """How many calls had failed in a row before this one worked (0: log nothing)."""
        return self._failing.pop(key, 0)


def _log_failed_job(e: Exception, key) -> None:
    rospy.logerr("anyscale decision: %s", e)


class Worker(JobWorker):
    """The decision node's job thread (one per node, per scale, and for the registrations):
    a JobWorker whose failed jobs are logged as the decision node's errors. Keyed jobs replace
    a pending job of the same key (only the latest lease renewal or watch list of a scale
    matters)."""

    def __init__(self, name: str):
        super().__init__(name, on_error=_log_failed_job)
