"""A restarted ROS master (roscore) given back what the old one held, pure: the snapshot, how
a new master is told from the old one, and the restore, against any object with the master's
calls (master_keeper.py's XML-RPC client, or a test's fake).

Why. ROS 1's master holds the parameter server and every registration (each node's XML-RPC
URI, its publications, subscriptions and services) in memory only, and neither roscpp nor
rospy (ros_comm 1.15) registers again with a master that restarted: no client library
re-initialises in-process (ros/ros_comm#214), and the usual advice is to restart every node.
Their peer-to-peer connections go on (no message passes through the master), but the new
master knows none of them: a subscriber that starts later finds no publisher, a publisher that
starts later is never announced to the old subscribers, a service cannot be looked up, and
every parameter is gone (roslaunch sets them once, at launch: a node it respawns, or that an
agent starts, finds none). Restarting every node would restart the robot's critical ones too,
and their Δ is 0.

How. What the new master needs is what the old one held, and it can be put back through the
master's own XML-RPC API, as the nodes first told it: setParam, and registerPublisher,
registerSubscriber and registerService with each node's own name and URI. The master cannot
tell that from the node's own call: it announces later publishers to those subscribers
(publisherUpdate to their URI), hands their URIs to later subscribers, and a node's own
unregister at its shutdown matches. In order:

- the parameters the new master lacks; it keeps its own values (roscore's /rosversion, what
  was set since it started), and /run_id is never written: the new roscore's roslaunch
  checks that /run_id is its own and fails otherwise;
- each node of the snapshot whose URI does not refuse the connection (a refusal: the process
  is gone), unless the new master holds its name under another URI: a new process took it
  (e.g. respawned), and registering the old URI under its name would make the master shut
  the new process down. Under its own URI the new master may know it already (rospy and
  roscpp register with whichever master answers: a resumed AMCL subscribes again; or a
  restore was broken off): what it holds is kept, the rest is added. Its topics as the node
  reports them (getPublications, getSubscriptions: current, typed); as the snapshot had them
  if it does not answer (a paused node, a starved one, one behind a partitioned link). The
  nodes are asked all at once, so that a silent one costs one timeout in all and holds up
  no other, and the master is asked who holds each name only once they have answered;
- every publisher before any subscriber, each kind in one request: each registerPublisher
  makes the master send the topic's subscribers the publishers it knows so far, and roscpp
  drops its connection to a publisher missing from that list (Subscription::pubUpdate), so
  no restored subscriber may be registered while a list is incomplete;
- a restored subscriber whose topic has a publisher it cannot know of (one that registered
  with the new master before the restore, e.g. the new rosout): publisherUpdate with the full
  list, as the master would have sent had the subscriber been registered.

Not restored: a node that first registered after the last snapshot (at most a keeper's period
before the master went), parameter subscriptions (a roscpp getParamCached stays as it was),
and anything if no keeper ran when the master went."""
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Set, Tuple

# The old master's value would make the new roscore's roslaunch fail: "run_id on parameter
# server does not match declared run_id".
NEVER_RESTORED = frozenset({"/run_id"})
# Nodes asked at once during a restore: enough for the test bed's graph (about 30 nodes) to
# take one round, few enough for the keeper's share of the robot.
MAX_THREADS = 32


class MasterCallError(Exception):
    """The master answered a call with an error (its code was not 1)."""


class NodeGone(Exception):
    """The node's URI refuses connections: no process listens there any more."""


class NodeSilent(Exception):
    """The node did not answer (stopped, out of reach, busy); it may still run."""


@dataclass(frozen=True)
class MasterIdentity:
    pid: int
    run_id: str         # "" while roslaunch has not set /run_id yet


def is_new_master(before: Optional[MasterIdentity], now: MasterIdentity) -> bool:
    """Whether `now` is another master process than `before`: another pid, or another /run_id
    (a master restarted in a container can have the pid its predecessor had). /run_id being
    set where it was not is the same master, which roslaunch has just initialised."""
    if before is None:
        return False
    if now.pid != before.pid:
        return True
    return bool(before.run_id) and bool(now.run_id) and now.run_id != before.run_id


@dataclass
class NodeRegistrations:
    uri: str
    publications: List[Tuple[str, str]] = field(default_factory=list)    # (topic, type)
    subscriptions: List[Tuple[str, str]] = field(default_factory=list)
    services: List[Tuple[str, str]] = field(default_factory=list)        # (service, its URI)


@dataclass
class Snapshot:
    identity: MasterIdentity
    taken_at: float                                  # monotonic clock
    params: dict
    nodes: Dict[str, NodeRegistrations]
    publisher_uris: Dict[str, Set[str]]              # topic -> its publishers' URIs


def take_snapshot(identity: MasterIdentity, taken_at: float, params: dict, system_state,
                  topic_types: Sequence[Tuple[str, str]], node_uris: Dict[str, Optional[str]],
                  service_uris: Dict[str, Optional[str]]) -> Snapshot:
    """The snapshot from the master's answers: getParam('/'), getSystemState(),
    getTopicTypes(), and lookupNode / lookupService of the names these list (None: not
    found). A node whose URI is unknown cannot be restored and is left out."""
    publishers, subscribers, services = system_state
    types = dict(topic_types)
    nodes: Dict[str, NodeRegistrations] = {}

    def node(name):
        uri = node_uris.get(name)
        return nodes.setdefault(name, NodeRegistrations(uri)) if uri else None

    for topic, names in publishers:
        for name in names:
            if node(name):
                nodes[name].publications.append((topic, types.get(topic, "*")))
    for topic, names in subscribers:
        for name in names:
            if node(name):
                nodes[name].subscriptions.append((topic, types.get(topic, "*")))
    for service, names in services:
        for name in names:
            if node(name) and service_uris.get(service):
                nodes[name].services.append((service, service_uris[service]))
    publisher_uris = {topic: {nodes[n].uri for n in names if n in nodes}
                      for topic, names in publishers}
    return Snapshot(identity, taken_at, params, nodes, publisher_uris)


def node_names(system_state) -> List[str]:
    return sorted({n for kind in system_state for _, names in kind for n in names})


def service_names(system_state) -> List[str]:
    return sorted(service for service, _ in system_state[2])


def missing_params(saved: dict, current: dict, prefix: str = "/") -> List[Tuple[str, object]]:
    """(key, value) of each parameter in `saved` that `current` lacks, as whole namespaces
    where `current` lacks the namespace; a value `current` has is kept (it was set since)."""
    out = []
    for name, value in sorted(saved.items()):
        key = prefix + name
        if key in NEVER_RESTORED:
            continue
        if name not in current:
            out.append((key, value))
        elif isinstance(value, dict) and isinstance(current[name], dict):
            out += missing_params(value, current[name], key + "/")
    return out


@dataclass
class RestoreReport:
    params: int = 0
    nodes: List[str] = field(default_factory=list)          # registered again
    unanswered: List[str] = field(default_factory=list)     # ... as the snapshot had them
    gone: List[str] = field(default_factory=list)           # their URI refused
    already: List[str] = field(default_factory=list)        # names taken by a new process
    registrations: int = 0
    updates: int = 0                                        # publisherUpdates sent
    failures: List[str] = field(default_factory=list)

    def describe(self) -> str:
        line = (f"put back {self.params} parameters and {self.registrations} registrations of "
                f"{len(self.nodes)} nodes")
        if self.updates:
            line += f" (and told {self.updates} subscriptions of publishers they missed)"
        if self.unanswered:
            line += f"; {', '.join(self.unanswered)} did not answer: as the snapshot had them"
        if self.already:
            line += f"; taken by a new process (left to it): {', '.join(self.already)}"
        if self.gone:
            line += f"; gone (their API refuses connections): {', '.join(self.gone)}"
        if self.failures:
            line += f"; FAILED: {'; '.join(self.failures)}"
        return line


def restore(master, node_api: Callable[[str], object], snapshot: Snapshot) -> RestoreReport:
    """Puts `snapshot` back on a new master (see the module's docstring). `master` has
    get_params(), set_params(pairs), lookup_nodes(names) -> {name: uri or None},
    held_registrations() -> {name: {(kind, topic or service)}} (kind "pub", "sub" or "srv")
    and register(calls), each call (method, caller_id, args), answered in one request with a
    value or the MasterCallError it was refused with per call; it raises OSError if it cannot
    be reached (which ends the restore: the next one completes it). `node_api(uri)` has
    publications(), subscriptions() and publisher_update(topic, uris), raising NodeGone or
    NodeSilent; node_api and its calls must be safe to use from several threads."""
    report = RestoreReport()
    pairs = missing_params(snapshot.params, master.get_params())
    master.set_params(pairs)
    report.params = len(pairs)
    answers = _ask_all(node_api, snapshot.nodes)
    # Looked up after the nodes answered, right before registering: a process that took a
    # node's name meanwhile would be shut down by the master if the old URI were registered.
    known = master.lookup_nodes(sorted(snapshot.nodes))
    held = master.held_registrations()
    todo: Dict[str, NodeRegistrations] = {}
    for name, saved in sorted(snapshot.nodes.items()):
        if known.get(name) and known[name] != saved.uri:
            report.already.append(name)
            continue
        answer = answers[name]
        if isinstance(answer, NodeGone):
            report.gone.append(name)
            continue
        if isinstance(answer, NodeSilent):
            report.unanswered.append(name)
            answer = saved
        # Under its own URI the master may know it already: rospy and roscpp register with
        # whichever master answers (a resumed AMCL subscribes again), or a restore was broken
        # off; what it holds is left as it is, the rest is added.
        todo[name] = _without(NodeRegistrations(saved.uri, answer.publications,
                                                answer.subscriptions, saved.services),
                              held.get(name, set()))
    firsts = [("registerPublisher", name, (topic, type_, reg.uri))
              for name, reg in todo.items() for topic, type_ in reg.publications]
    firsts += [("registerService", name, (service, service_uri, reg.uri))
               for name, reg in todo.items() for service, service_uri in reg.services]
    _registered(report, firsts, master.register(firsts))
    subs = [("registerSubscriber", name, (topic, type_, reg.uri))
            for name, reg in todo.items() for topic, type_ in reg.subscriptions]
    replies = master.register(subs)
    _registered(report, subs, replies)
    missed = [(todo[name].uri, args[0], list(publishers))
              for (_, name, args), publishers in zip(subs, replies)
              if name not in report.unanswered and not isinstance(publishers, Exception)
              and set(publishers) - snapshot.publisher_uris.get(args[0], set())]
    report.updates = _tell_all(node_api, missed)
    report.nodes = sorted(n for n, reg in todo.items()
                          if reg.publications or reg.subscriptions or reg.services)
    return report


def _ask_all(node_api, nodes: Dict[str, NodeRegistrations]) -> Dict[str, object]:
    """Each node's own registrations, asked of all at once: a node that does not answer (paused,
    starved) costs its timeout once for all of them, and no node waits behind it. Per name:
    NodeRegistrations (its topics), or the NodeGone or NodeSilent it raised."""
    def ask(saved):
        try:
            api = node_api(saved.uri)
            return NodeRegistrations(saved.uri, api.publications(), api.subscriptions())
        except (NodeGone, NodeSilent) as e:
            return e
    with ThreadPoolExecutor(max_workers=max(1, min(MAX_THREADS, len(nodes)))) as pool:
        futures = {name: pool.submit(ask, saved) for name, saved in nodes.items()}
        return {name: f.result() for name, f in futures.items()}


def _tell_all(node_api, updates: List[Tuple[str, str, List[str]]]) -> int:
    """publisherUpdate(topic, uris) to each (node URI, topic, uris), all at once; how many
    nodes took it."""
    def tell(update):
        uri, topic, uris = update
        try:
            node_api(uri).publisher_update(topic, uris)
            return 1
        except (NodeGone, NodeSilent):
            return 0
    if not updates:
        return 0
    with ThreadPoolExecutor(max_workers=min(MAX_THREADS, len(updates))) as pool:
        return sum(pool.map(tell, updates))


def _without(reg: NodeRegistrations, held: Set[Tuple[str, str]]) -> NodeRegistrations:
    return NodeRegistrations(reg.uri, [p for p in reg.publications if ("pub", p[0]) not in held],
                             [s for s in reg.subscriptions if ("sub", s[0]) not in held],
                             [s for s in reg.services if ("srv", s[0]) not in held])


def _registered(report: RestoreReport, calls, replies):
    for (_, name, args), reply in zip(calls, replies):
        if isinstance(reply, Exception):    # one refused registration is reported, no more
            report.failures.append(f"{name} {args[0]}: {reply}")
        else:
            report.registrations += 1
