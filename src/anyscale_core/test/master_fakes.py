"""Fakes for the master keeper's tests (no ROS): a master with rosmaster's semantics on dicts,
answering its XML-RPC API's calls, and a node that keeps its connections as roscpp does."""
from typing import Dict, List, Set, Tuple

from anyscale_core.master_restore import MasterCallError, NodeGone, NodeSilent


class FakeRosMaster:
    """What the restore relies on of rosmaster: registrations by caller_id and URI; a node name
    registered again under another URI makes the master shut the older URI's process down; a
    publisher's registration sends the topic's subscribers the full list of its publishers
    (`notify(subscriber_uri, topic, publisher_uris)`). Methods take the caller_id first and
    return (code, message, value), as rosmaster's XML-RPC API does."""

    def __init__(self, pid: int, run_id: str = "", notify=lambda uri, topic, uris: None):
        self.pid = pid
        self.params: Dict = {"run_id": run_id} if run_id else {}
        self.nodes: Dict[str, str] = {}                          # name -> URI
        self.publishers: Dict[str, List[Tuple[str, str]]] = {}   # topic -> (name, URI)
        self.subscribers: Dict[str, List[Tuple[str, str]]] = {}
        self.services: Dict[str, Tuple[str, str]] = {}           # service -> (name, its URI)
        self.types: Dict[str, str] = {}
        self.notify = notify
        self.shutdowns: List[str] = []                           # URIs told to shut down
        self.refuse: Set[str] = set()                            # topics it answers -1 for

    def _node(self, name, uri):
        if self.nodes.get(name, uri) != uri:
            self.shutdowns.append(self.nodes[name])
        self.nodes[name] = uri

    def getPid(self, caller):
        return 1, "", self.pid

    def getParam(self, caller, key):
        value = self.params
        for part in filter(None, key.split("/")):
            if not isinstance(value, dict) or part not in value:
                return -1, f"no {key}", 0
            value = value[part]
        return 1, "", value

    def setParam(self, caller, key, value):
        *path, last = key.strip("/").split("/")
        tree = self.params
        for part in path:
            tree = tree.setdefault(part, {})
        tree[last] = value
        return 1, "", 0

    def getSystemState(self, caller):
        def listing(table):
            return [[t, [n for n, _ in regs]] for t, regs in sorted(table.items()) if regs]
        return 1, "", [listing(self.publishers), listing(self.subscribers),
                       [[s, [n]] for s, (n, _) in sorted(self.services.items())]]

    def getTopicTypes(self, caller):
        return 1, "", [[t, ty] for t, ty in sorted(self.types.items())]

    def lookupNode(self, caller, name):
        return (1, "", self.nodes[name]) if name in self.nodes else (-1, "unknown", "")

    def lookupService(self, caller, service):
        return (1, "", self.services[service][1]) if service in self.services \
            else (-1, "unknown", "")

    @staticmethod
    def _add(table, topic, caller, uri):
        # As rosmaster's Registrations.register: a registration made twice is held once.
        regs = table.setdefault(topic, [])
        if (caller, uri) not in regs:
            regs.append((caller, uri))

    def registerPublisher(self, caller, topic, type_, uri):
        if topic in self.refuse:
            return -1, f"refused {topic}", 0
        self._node(caller, uri)
        self._add(self.publishers, topic, caller, uri)
        self.types.setdefault(topic, type_)
        uris = [u for _, u in self.publishers[topic]]
        for _, sub in self.subscribers.get(topic, []):
            self.notify(sub, topic, uris)
        return 1, "", [u for _, u in self.subscribers.get(topic, [])]

    def registerSubscriber(self, caller, topic, type_, uri):
        self._node(caller, uri)
        self._add(self.subscribers, topic, caller, uri)
        self.types.setdefault(topic, type_)
        return 1, "", [u for _, u in self.publishers.get(topic, [])]

    def registerService(self, caller, service, service_uri, uri):
        self._node(caller, uri)
        self.services[service] = (caller, service_uri)
        return 1, "", 0


def value(reply):
    code, message, val = reply
    if code != 1:
        raise MasterCallError(message)
    return val


class Direct:
    """master_restore's calls on a FakeRosMaster, as master_keeper.MasterClient makes them over
    XML-RPC."""

    def __init__(self, master: FakeRosMaster):
        self.m = master

    def get_params(self):
        return value(self.m.getParam("/keeper", "/"))

    def set_params(self, pairs):
        for key, val in pairs:
            value(self.m.setParam("/keeper", key, val))

    def lookup_nodes(self, names):
        return {n: self.m.lookupNode("/keeper", n)[2] or None for n in names}

    def held_registrations(self):
        held = {}
        for kind, table in zip(("pub", "sub", "srv"), value(self.m.getSystemState("/keeper"))):
            for topic, names in table:
                for name in names:
                    held.setdefault(name, set()).add((kind, topic))
        return held

    def register(self, calls):
        """Each (method, caller_id, args) in turn, as one multicall: its value, or the
        MasterCallError it was refused with."""
        out = []
        for method, name, args in calls:
            try:
                out.append(value(getattr(self.m, method)(name, *args)))
            except MasterCallError as e:
                out.append(e)
        return out


class FakeNode:
    """A node's API: its topics, and its subscriptions' connections kept as roscpp keeps them
    (Subscription::pubUpdate: connects to new publishers, drops those missing from the list)."""

    def __init__(self, name, uri, publications=(), subscriptions=(), connected=None):
        self.name = name
        self.uri = uri
        self.pubs = list(publications)
        self.subs = list(subscriptions)
        self.connected: Dict[str, Set[str]] = {t: set(u) for t, u in (connected or {}).items()}
        self.dropped: List[Tuple[str, str]] = []     # (topic, publisher URI)
        self.updates = 0

    def publications(self):
        return list(self.pubs)

    def subscriptions(self):
        return list(self.subs)

    def publisher_update(self, topic, uris):
        self.updates += 1
        before = self.connected.get(topic, set())
        self.dropped += [(topic, u) for u in sorted(before - set(uris))]
        self.connected[topic] = set(uris)


class FakeGraph:
    """The nodes by URI: live ones answer, `gone` URIs refuse, `silent` ones do not answer."""

    def __init__(self, nodes, gone=(), silent=()):
        self.nodes = {n.uri: n for n in nodes}
        self.gone = set(gone)
        self.silent = set(silent)

    def api(self, uri):
        if uri in self.gone:
            raise NodeGone(uri)
        if uri in self.silent:
            raise NodeSilent(uri)
        return self.nodes[uri]

    def notify(self, uri, topic, uris):
        """The master's publisherUpdate: it reaches live nodes only."""
        if uri in self.nodes and uri not in self.gone | self.silent:
            self.nodes[uri].publisher_update(topic, uris)
