"""The master keeper: `rosrun anyscale_core master_keeper [--period S]`, which robot.launch runs
on the master's scale. Every period it takes a snapshot of what the ROS master holds; when
another master answers at ROS_MASTER_URI (roscore restarted), it says so in one line and puts
the snapshot back (master_restore.py: what, in which order, and why that holds for roscpp and
rospy nodes), then says what it restored and what it could not.

It is no ROS node: it talks to the master and to the nodes' APIs over XML-RPC only, so it
needs nothing from a master it restores, and its settings are arguments, not parameters,
which a restarted master would have lost with the rest."""
import argparse
import http.client
import signal
import sys
import time
import xmlrpc.client
from typing import Callable, Dict, List, Optional, Sequence, Set, Tuple

import rosgraph

from . import xmlrpc_calls
from .master_restore import (MasterCallError, MasterIdentity, NodeGone, NodeSilent, Snapshot,
                             is_new_master, node_names, restore, service_names, take_snapshot)

# What an XML-RPC call raises when its peer is gone, does not answer, or breaks off.
CALL_ERRORS = (OSError, http.client.HTTPException, xmlrpc.client.Error)
# The master runs where the keeper does (robot.launch, on the master's scale): a request it
# has not answered in this long is one it will not answer (it is stopped or going).
MASTER_TIMEOUT_S = 2.0


class MasterUnreachable(OSError):
    """The master did not answer (stopped, restarting, out of reach)."""


def _reply(results, i: int):
    try:
        return results[i]
    except xmlrpc.client.Fault as fault:     # the master raised: no (code, message, value)
        return fault


def _found(reply):
    """A lookup's value; None for a name the master does not know."""
    return None if isinstance(reply, xmlrpc.client.Fault) or reply[0] != 1 else reply[2]


def _value(reply, what: str):
    if isinstance(reply, xmlrpc.client.Fault):
        raise MasterCallError(f"{what}: {reply.faultString}")
    code, message, value = reply
    if code != 1:
        raise MasterCallError(f"{what}: {message}")
    return value


class MasterClient:
    """The master's calls master_restore needs, and the snapshot's reads in one request each
    (system.multicall, which rosmaster serves: one request is answered by one master, so the
    reads of a snapshot cannot straddle a restart)."""

    def __init__(self, uri: str, caller_id: str, timeout_s: float):
        self.uri = uri
        self.caller_id = caller_id
        self.timeout_s = timeout_s

    def _call(self, calls: Sequence[Tuple[str, tuple]], caller_ids: Optional[List[str]] = None):
        """The replies ((code, message, value) each, or the xmlrpc.client.Fault a call raised)
        of `calls`, (method, args) pairs, each made as its caller id in `caller_ids` (the
        keeper's own by default)."""
        multi = xmlrpc.client.MultiCall(xmlrpc_calls.proxy(self.uri, self.timeout_s))
        for (method, args), caller_id in zip(calls, caller_ids or [self.caller_id] * len(calls)):
            getattr(multi, method)(caller_id, *args)
        try:
            results = multi()
        except CALL_ERRORS as e:
            raise MasterUnreachable(f"{type(e).__name__}: {e}") from None
        return [_reply(results, i) for i in range(len(calls))]

    def state(self):
        """(identity, parameters, system state, topic types), from one request."""
        calls = [("getPid", ()), ("getParam", ("/",)), ("getSystemState", ()),
                 ("getTopicTypes", ())]
        pid, params, system_state, types = (_value(reply, method) for reply, (method, _)
                                            in zip(self._call(calls), calls))
        run_id = params.get("run_id", "") if isinstance(params, dict) else ""
        return MasterIdentity(int(pid), str(run_id)), params, system_state, types

    def lookups(self, nodes: List[str], services: List[str], pid: int):
        """({node: URI or None}, {service: URI or None}), or None if by the end of the request
        the master was another one than `pid`."""
        replies = self._call([("lookupNode", (n,)) for n in nodes]
                             + [("lookupService", (s,)) for s in services] + [("getPid", ())])
        if _value(replies[-1], "getPid") != pid:
            return None
        found = [_found(reply) for reply in replies[:-1]]
        return dict(zip(nodes, found[:len(nodes)])), dict(zip(services, found[len(nodes):]))

    # --- what master_restore.restore calls ------------------------------------------------
    def get_params(self) -> dict:
        return _value(self._call([("getParam", ("/",))])[0], "getParam /")

    def set_params(self, pairs):
        if pairs:
            for reply, (key, _) in zip(self._call([("setParam", p) for p in pairs]), pairs):
                _value(reply, f"setParam {key}")

    def lookup_nodes(self, names: List[str]) -> Dict[str, Optional[str]]:
        replies = self._call([("lookupNode", (n,)) for n in names]) if names else []
        return {n: _found(reply) for n, reply in zip(names, replies)}

    def held_registrations(self) -> Dict[str, Set[Tuple[str, str]]]:
        held: Dict[str, Set[Tuple[str, str]]] = {}
        state = _value(self._call([("getSystemState", ())])[0], "getSystemState")
        for kind, table in zip(("pub", "sub", "srv"), state):
            for name_, names in table:
                for node in names:
                    held.setdefault(node, set()).add((kind, name_))
        return held

    def register(self, calls: Sequence[Tuple[str, str, tuple]]) -> list:
        """(method, caller_id, args) calls in one request: each one's value, or the
        MasterCallError it was refused with."""
        if not calls:
            return []
        replies = self._call([(method, args) for method, _, args in calls],
                             [caller_id for _, caller_id, _ in calls])
        out = []
        for reply, (method, _, args) in zip(replies, calls):
            try:
                out.append(_value(reply, method))
            except MasterCallError as e:
                out.append(e)
        return out


class NodeApi:
    """A node's slave API as master_restore needs it: a refused connection is a process that is
    gone; anything else that fails is a node that did not answer."""

    def __init__(self, uri: str, caller_id: str, timeout_s: float):
        self.uri = uri
        self.caller_id = caller_id
        self.timeout_s = timeout_s

    def _call(self, method: str, *args):
        try:
            code, message, value = getattr(xmlrpc_calls.proxy(self.uri, self.timeout_s),
                                           method)(*args)
        except ConnectionRefusedError:
            raise NodeGone(self.uri) from None
        except CALL_ERRORS as e:
            raise NodeSilent(f"{self.uri}: {type(e).__name__}: {e}") from None
        if code != 1:
            raise NodeSilent(f"{self.uri}: {method}: {message}")
        return value

    def publications(self) -> List[Tuple[str, str]]:
        return [tuple(p) for p in self._call("getPublications", self.caller_id)]

    def subscriptions(self) -> List[Tuple[str, str]]:
        return [tuple(s) for s in self._call("getSubscriptions", self.caller_id)]

    def publisher_update(self, topic: str, uris: List[str]):
        # As the master calls it: the node checks nothing of the caller's name.
        self._call("publisherUpdate", "/master", topic, uris)


class MasterKeeper:
    def __init__(self, master: MasterClient, node_api: Callable[[str], object],
                 log: Callable[[str, str], None], clock: Callable[[], float] = time.monotonic):
        self.master = master
        self.node_api = node_api
        self.log = log
        self.clock = clock
        self.snapshot: Optional[Snapshot] = None
        self.reachable: Optional[bool] = None

    def step(self):
        """One period: a snapshot, and first the restore if the master is another one."""
        try:
            self._step()
        except MasterCallError as e:    # a refused read or parameter: tried again next period
            self.log("ERROR", f"the ROS master at {self.master.uri} refused a call: {e}")
        except MasterUnreachable as e:
            if self.reachable is not False:
                held = (f"keeping the snapshot of {self.clock() - self.snapshot.taken_at:.1f} s "
                        f"ago" if self.snapshot else "no snapshot taken yet")
                self.log("WARN", f"the ROS master at {self.master.uri} does not answer ({e}); "
                                 f"{held}")
            self.reachable = False

    def _step(self):
        identity, params, system_state, types = self.master.state()
        if self.reachable is False and not is_new_master(
                self.snapshot and self.snapshot.identity, identity):
            self.log("INFO", f"the ROS master at {self.master.uri} answers again (the same "
                             f"master, pid {identity.pid})")
        self.reachable = True
        if self.snapshot is not None and is_new_master(self.snapshot.identity, identity):
            old = self.snapshot.identity
            self.log("WARN", f"the ROS master at {self.master.uri} restarted (pid {old.pid} -> "
                             f"{identity.pid}): it lost every parameter and registration; "
                             f"putting back what it held "
                             f"{self.clock() - self.snapshot.taken_at:.1f} s before")
            report = restore(self.master, self.node_api, self.snapshot)
            self.log("ERROR" if report.failures else "INFO", report.describe())
            identity, params, system_state, types = self.master.state()
        found = self.master.lookups(node_names(system_state), service_names(system_state),
                                    identity.pid)
        if found is not None:       # else the master changed during the reads: next period
            self.snapshot = take_snapshot(identity, self.clock(), params, system_state, types,
                                          *found)


def parse_args(argv):
    p = argparse.ArgumentParser(prog="master_keeper", description=__doc__.split("\n\n")[0])
    p.add_argument("--period", type=float, default=1.0, metavar="S",
                   help="seconds between snapshots (1): a node first registered within the "
                        "last period before the master went is not restored")
    p.add_argument("--timeout", type=float, default=0.5, metavar="S",
                   help="seconds a node's API has to answer during a restore (0.5); one that "
                        "does not is restored as the snapshot had it")
    args = p.parse_args(argv)
    for name in ("period", "timeout"):
        value = getattr(args, name)
        if not 0 < value < 3600:
            p.error(f"--{name}: expected seconds in (0, 3600), got {value:g}")
    return args


def log_line(level: str, text: str):
    # rospy's layout, so that the lines read like the other nodes' in roslaunch's output.
    print(f"[{level}] [{time.time():.6f}] anyscale master keeper: {text}", flush=True)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    # roslaunch passes __name:=, __log:= and any remaps: not arguments of this program.
    name = next((a.split(":=", 1)[1] for a in argv if a.startswith("__name:=")),
                "master_keeper")
    args = parse_args([a for a in argv if ":=" not in a])
    uri = rosgraph.get_master_uri()
    caller_id = "/" + name.lstrip("/")
    master = MasterClient(uri, caller_id, MASTER_TIMEOUT_S)
    keeper = MasterKeeper(master, lambda u: NodeApi(u, caller_id, args.timeout), log_line)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    log_line("INFO", f"a snapshot of the ROS master at {uri} every {args.period:g} s, put back "
                     f"if the master restarts")
    due = time.monotonic()
    try:
        while True:
            keeper.step()
            due = max(due + args.period, time.monotonic())
            time.sleep(max(0.0, due - time.monotonic()))
    except KeyboardInterrupt:
        return 0
