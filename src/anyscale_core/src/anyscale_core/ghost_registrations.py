"""Registrations the master keeps for node instances that are gone.

A process killed without unregistering (its lease ran out behind a partition, its agent died)
stays registered with the master under its instance name, e.g. /amcl__laptop. Its topics then
list a publisher nobody can reach. That is harmless for the data, but `rostopic info` shows a
ghost, and every subscriber keeps trying to connect to it. A request the dead process sent
before the link went, and that TCP delivers once the link is back, registers it again. The
decision node removes such registrations the way `rosnode cleanup` does, but only for instance
names it manages, and only once the instance no longer answers on its XML-RPC API.
"""
import math
from typing import AbstractSet, Iterable, List, Mapping, Optional, Set, Tuple

import rosgraph
import rosnode

from .agent_client import registered_pid


def ghost_candidates(model, mapping: Mapping[str, str], busy: AbstractSet[str],
                     paused: AbstractSet[str]) -> List[str]:
    """Instance names to check: each node's on every scale but the one it runs on, except
    nodes being handed over (both instances live) and paused instances (launch.pause_at_home:
    registered, alive, but silent on their API until resumed)."""
    return [name for node, where in mapping.items() if node not in busy
            for scale in model.scale_names if scale != where
            for name in [model.instance_name(node, scale)] if name not in paused]


# The agents report at 2 Hz: a status received this long after a pause was acknowledged was
# sampled after the pause, and says whether the instance is still paused.
PAUSE_SETTLED_S = 1.0


def pauses_under_way(pausing: Mapping[str, Tuple[str, Optional[float]]],
                     status_received: Mapping[str, float]) -> Set[str]:
    """The instances to take for paused although no agent reports them so yet: instance ->
    (its scale, when its pause was acknowledged, or None while the call is under way), and
    scale -> when its latest status came (the same monotonic clock). Once a status of the scale
    came PAUSE_SETTLED_S after the acknowledgement, the agent's report decides, so an instance
    that died while being paused is purged like any other ghost (docs/measurements/
    fault_soak.md)."""
    return {instance for instance, (scale, acked) in pausing.items()
            if acked is None or status_received.get(scale, -math.inf) < acked + PAUSE_SETTLED_S}


def registered_nodes(master: rosgraph.Master) -> set:
    """Every node the master lists as a publisher, subscriber or service provider."""
    return {node for kind in master.getSystemState() for _, nodes in kind for node in nodes}


def dead_registrations(master: rosgraph.Master, candidates: Iterable[str], caller_id: str,
                       timeout_s: float) -> List[str]:
    """The candidate names the master lists whose process does not answer within timeout_s."""
    listed = registered_nodes(master)
    return [n for n in candidates
            if n in listed and registered_pid(n, caller_id, timeout_s) is None]


def purge(master: rosgraph.Master, names: List[str]):
    """Unregisters every topic and service of `names` (rosnode cleanup's own routine)."""
    if names:
        rosnode.cleanup_master_blacklist(master, names)
