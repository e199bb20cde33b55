"""The decision node's actions through the agents, on worker threads: starts, make-before-break
handovers, stops, lease renewals, watch lists, and the removal of dead instances' registrations.
DecisionNode (decision_ros.py) owns one AgentActions and hands it what it needs."""
import math
import threading
import time
from dataclasses import replace
from typing import Callable, Dict, Iterable, Set, Tuple

import rosgraph
import rospy

from . import ros_convert as conv
from .agent_client import CallFailures, Worker, wait_registered
from .decision_types import RenewLeases, StartNode, StopNode
from .ghost_registrations import dead_registrations, ghost_candidates, pauses_under_way, purge
from .handover_ros import PUBLISHED, TIMED_OUT, OutputWatch, wait_for_output

REGISTER_TIMEOUT_S = 30.0  # a started node not registered by then is reported as failed
GHOST_PING_TIMEOUT_S = 0.5  # a registered instance that does not answer this fast is gone
WATCH_RESEND_S = 10.0     # re-send watch lists now and then: an agent may have restarted
# A watched topic missing from a report this long after the list was sent: the list is sent again.
WATCH_CHECK_S = 1.0


class AgentActions:
    """Carries out the engine's actions through `agents`. `lock` is the decision node's: it
    guards the engine, `reports` and `statuses` (the node's, updated in place) and the
    bookkeeping here, which the node reads for its ticks (busy)."""

    def __init__(self, model, params, engine, lock: threading.Lock, agents,
                 reports: Dict[str, object], statuses: Dict[str, object],
                 publish_event: Callable[..., None], publish_mapping: Callable[[], None],
                 caller_id: str):
        self.model, self.params, self.engine, self.lock = model, params, engine, lock
        self.master = model.master.name
        self.agents = agents
        self.reports, self.statuses = reports, statuses
        self._publish_event, self._publish_mapping = publish_event, publish_mapping
        self.caller_id = caller_id
        self.link_up: Dict[str, bool] = {}    # remote scale -> up, as of the node's latest tick
        self.starting: Set[Tuple[str, str]] = set()  # (node, scale) of starts not yet answered
        self.handing_over: Set[str] = set()   # nodes whose old and new instance both run
        self.node_jobs: Dict[str, int] = {}   # node -> its jobs queued or running on its worker
        # instance paused at our request -> (its scale, when the pause was acknowledged)
        self.pausing: Dict[str, tuple] = {}
        self.watch_sent: Dict[str, tuple] = {}  # scale -> (watch list, when it was sent)
        self.call_failures = CallFailures()
        # One worker per node: a slow start on one scale does not hold up another node's move.
        self.node_workers = {n: Worker(f"anyscale_node_{n}") for n in model.node_names}
        self.scale_workers = {s: Worker(f"anyscale_{s}") for s in model.scale_names}
        self.registrations = Worker("anyscale_registrations")

    # --- what the decision node calls ----------------------------------------------------------
    def busy(self) -> Tuple[Set[str], Set[str]]:
        """Under the lock: (nodes whose start is not yet answered, nodes with an action under
        way), which the engine's tick leaves alone."""
        return {n for n, _ in self.starting}, set(self.handing_over) | set(self.node_jobs)

    def dispatch(self, actions: Iterable, events: Dict[str, object], stamp, decided: float):
        """Queues a tick's actions: lease renewals on their scale's worker, the rest of each
        node's actions, in order, on its node's worker; `events` by node, reported once done."""
        jobs: Dict[str, list] = {}
        for action in actions:
            if isinstance(action, RenewLeases):
                self.scale_workers[action.scale].submit(
                    lambda a=action: self._renew(a), key="renew")
            else:
                jobs.setdefault(action.node, []).append(action)
                if isinstance(action, StartNode):
                    with self.lock:
                        self.starting.add((action.node, action.scale))
        for node, node_actions in jobs.items():
            self._submit_node_job(node, lambda n=node, a=node_actions, e=events.get(node):
                                  self._execute_move(n, a, e, stamp, decided))

    # --- on the workers -----------------------------------------------------------------------
    def _submit_node_job(self, node, job):
        """`job` on the node's worker, counted in node_jobs until it ended: the engine leaves
        alone the strays of a node whose actions are still to come (DecisionEngine._strays)."""
        def run():
            try:
                job()
            finally:
                with self.lock:
                    left = self.node_jobs.get(node, 1) - 1
                    if left > 0:
                        self.node_jobs[node] = left
                    else:
                        self.node_jobs.pop(node, None)

        with self.lock:
            self.node_jobs[node] = self.node_jobs.get(node, 0) + 1
        self.node_workers[node].submit(run)

    def _execute_move(self, node, actions, event, stamp, decided):
        """One decision's actions for one node, in order. A planned move starts the new instance
        first and hands the old one's stop to a thread that waits for the new one's output
        (make before break); a duplicate found at start-up is stopped at once."""
        handover = next((a for a in actions if isinstance(a, StopNode) and a.after_output_on),
                        None)
        if handover is not None:
            with self.lock:
                self.handing_over.add(node)
        watch, pid = None, 0
        for action in actions:
            if isinstance(action, StartNode):
                topics = self.model.output_topics(node)
                if handover is not None and topics:
                    watch = OutputWatch(topics, self.model.instance_name(node, action.scale),
                                        self.params.handover_messages)
                with self.lock:
                    action = replace(
                        action, param_overrides=self.engine.handoff_overrides(node))
                pid = self._start(action, event, stamp, decided, handover)
                if not pid:
                    if watch is not None:
                        watch.close()
                    with self.lock:
                        self.handing_over.discard(node)
                    return
            elif action is handover:
                threading.Thread(target=self._hand_over, args=(node, action, watch, pid),
                                 daemon=True).start()
            elif action.stray:
                self._stop_stray(node, action)
            elif action.best_effort:
                # Not waited for: it ends before the lease does, or not at all.
                threading.Thread(target=self._stop, args=(node, action.scale, True),
                                 daemon=True).start()
            else:
                self._stop(node, action.scale)

    def _hand_over(self, node, stop: StopNode, watch, pid):
        """Stops the old instance once the new one on stop.after_output_on has published (for a
        node without outputs in the model: registered), while the node is still meant to run
        there; if the new one never does, the node stays where it was."""
        try:
            self._overlap(node, stop, watch, pid)
        finally:
            with self.lock:
                self.handing_over.discard(node)

    def _overlap(self, node, stop: StopNode, watch, pid):
        source, target = stop.scale, stop.after_output_on
        began = time.monotonic()

        def assigned():
            with self.lock:
                return self.engine.mapping()[node]

        def renew_old_lease():
            if source != self.master:
                self.scale_workers[source].submit(
                    lambda: self._renew(RenewLeases(source, (node,), self.params.engine.lease_s)),
                    key=("handover", node))

        if watch is not None:
            outcome = wait_for_output(watch, self.params.handover_timeout_s,
                                      lambda: assigned() == target, renew_old_lease)
            watch.close()
        else:
            registered = wait_registered(self.model.instance_name(node, target), pid,
                                         self.caller_id, self.params.handover_timeout_s)
            outcome = PUBLISHED if registered else TIMED_OUT
        if outcome != TIMED_OUT:
            if outcome == PUBLISHED:
                with self.lock:
                    self.engine.output_seen(node, time.monotonic())
                rospy.loginfo("anyscale decision: %s on %s published %.2f s after its start; "
                              "%s the instance on %s", node, target, time.monotonic() - began,
                              "pausing" if stop.pause else "stopping", source)
            # On the node's worker, after any start a later decision queued there, and only if
            # the node is not meant to run on `source` by then: a link loss that brought it
            # back while the new instance was publishing keeps the old instance.
            self._submit_node_job(node, lambda: assigned() != source and
                                  self._stop(node, source, pause=stop.pause))
            return
        if not self.link_up.get(source, True):
            # The old instance is out of reach: going back to it would leave the node running
            # nowhere that can be reached (docs/measurements/tolerances.md, "two decision-node
            # races").
            rospy.logwarn("anyscale decision: %s on %s: no output seen within %.1f s, but %s is "
                          "out of reach; it stays on %s", node, target,
                          self.params.handover_timeout_s, source, target)
            return
        rospy.logwarn("anyscale decision: %s on %s did not publish within %.1f s; it stays on %s",
                      node, target, self.params.handover_timeout_s, source)
        self._stop(node, target)
        with self.lock:
            back = self.engine.move_failed(node, source, target, time.monotonic())
        if back is not None:
            self._publish_event("failed", node, source, target, back.reason, rospy.Time.now(),
                                math.nan, False)
            self._publish_mapping()

    def _stop_stray(self, node, stop: StopNode):
        """Stops (or pauses) an instance the engine found where the mapping does not place its
        node, if the agent's latest status still shows it running and the node is still not
        meant to run there: a stop queued before this one may have ended it meanwhile."""
        with self.lock:
            elsewhere = self.engine.mapping()[node] != stop.scale
        if not (elsewhere and self.reports_running(stop.scale, node, states=conv.ALIVE_STATES)):
            return
        rospy.logwarn("anyscale decision: %s runs on %s, where the mapping does not place it "
                      "(a stop that did not get through, e.g. its agent was restarted); %s it",
                      node, stop.scale, "pausing" if stop.pause else "stopping")
        self._stop(node, stop.scale, pause=stop.pause)

    def _stop(self, node, scale, best_effort=False, pause=False):
        try:
            self._stop_once(node, scale, best_effort, pause)
        finally:
            with self.lock:
                self.engine.stop_answered(node, time.monotonic())

    def _stop_once(self, node, scale, best_effort, pause):
        if not best_effort and not self.link_up.get(scale, True):
            return          # out of reach: its lease ends it there
        instance = self.model.instance_name(node, scale)
        if pause:
            # Before the call: a paused instance does not answer on its API, and the ghost
            # check must not take it for a dead one while the pause is under way.
            with self.lock:
                self.pausing[instance] = (scale, None)
        try:
            reply = self.agents.stop(scale, node, self.params.engine.lease_s if best_effort
                                     else None, pause=pause)
            if not reply.success:
                rospy.logwarn("anyscale decision: %s %s on %s: %s%s", "pause" if pause else "stop",
                              node, scale, reply.message, "; stopping it instead" if pause else "")
        except Exception as e:  # noqa: BLE001 - its lease ends it anyway
            reply = None
            if not best_effort:
                rospy.logwarn("anyscale decision: stop %s on %s failed: %s", node, scale, e)
        if pause and reply is not None and reply.success:
            with self.lock:
                self.pausing[instance] = (scale, time.monotonic())
        if pause and (reply is None or not reply.success):
            with self.lock:
                self.pausing.pop(instance, None)
            # Not paused (e.g. it was still starting): left running, it would publish beside
            # the instance that replaced it.
            self._stop_once(node, scale, best_effort, False)

    def _start(self, action: StartNode, event, stamp, decided, handover=None) -> int:
        """Starts the node; its pid, or 0 if the start failed (then handled here)."""
        node, scale = action.node, action.scale
        full = None
        try:
            reply = self.agents.start(scale, node,
                                      conv.param_overrides_to_kv(action.param_overrides),
                                      action.lease_s, action.cpu_percent, action.memory_mb)
            ok, message, pid = reply.success, reply.message, reply.pid
            if not ok and reply.scale_full:
                full = (reply.cpu_free_percent, reply.memory_free_mb)
        except Exception as e:  # noqa: BLE001 - reported as a failed start below
            ok, message, pid = False, str(e), 0
        with self.lock:
            self.starting.discard((node, scale))
            if ok:
                self.engine.start_acknowledged(node, time.monotonic())
                self.pausing.pop(self.model.instance_name(node, scale), None)  # resumed
        if not ok:
            self._start_failed(action, event, message, handover, full)
            return 0
        if event is not None:
            # Waiting for the registration must not hold up the next move.
            threading.Thread(target=self._report_when_registered,
                             args=(node, scale, pid, event, stamp, decided), daemon=True).start()
        return pid

    def _start_failed(self, action: StartNode, event, message, handover, full=None):
        """A start that failed: the node stays where it runs (a handover's old instance was
        never stopped) or comes home. full: (CPU %, MB) a shared scale's ledger had room for
        when it refused the start for capacity; the nodes that do not fit are backed off there."""
        node, scale = action.node, action.scale
        rospy.logerr("anyscale decision: start %s on %s failed: %s", node, scale, message)
        self._publish_event("failed", node, event.from_scale if event else "", scale,
                            f"start on {scale} failed: {message}", rospy.Time.now(), math.nan,
                            False)
        with self.lock:
            backed_off = [] if full is None else \
                self.engine.capacity_refused(node, scale, full[0], full[1], time.monotonic())
            if handover is not None:    # the old instance still runs: the node stays there
                back = self.engine.move_failed(node, handover.scale, scale, time.monotonic())
            else:
                back = self.engine.action_failed(node, scale, time.monotonic())
        for line in backed_off:
            rospy.loginfo("anyscale decision: %s", line)
        if back is None:
            return
        rospy.loginfo("anyscale decision: %s", conv.describe_change(
            {node: scale}, {node: back.to_scale}, {node: back.reason}))
        self._publish_mapping()
        if handover is None:
            self._start(StartNode(node, back.to_scale, action.param_overrides, 0.0), back,
                        rospy.Time.now(), time.monotonic())

    def _report_when_registered(self, node, scale, pid, event, stamp, decided):
        registered = wait_registered(self.model.instance_name(node, scale), pid, self.caller_id,
                                     REGISTER_TIMEOUT_S,
                                     lambda: self.reports_running(scale, node, pid))
        reason = event.reason if registered else \
            f"{event.reason}; not registered within {REGISTER_TIMEOUT_S:g} s"
        self._publish_event(event.kind, node, event.from_scale, scale, reason, stamp,
                            time.monotonic() - decided if registered else math.nan, registered)

    def reports_running(self, scale, node, pid=None, states=None):
        """Whether the agent's latest status shows the node's instance (with `pid`, if given)
        in one of `states` (default: RUNNING)."""
        with self.lock:
            status = self.statuses.get(scale)
        return status is not None and any(
            p.name == "/" + node and pid in (None, p.pid) and
            p.state in (states or (p.RUNNING,)) for p in status.nodes)

    def _renew(self, action: RenewLeases):
        # A node whose start is still queued gets its lease from the start itself.
        with self.lock:
            nodes = [n for n in action.nodes if (n, action.scale) not in self.starting]
        if not nodes:
            return
        try:
            reply = self.agents.renew(action.scale, nodes, action.lease_s)
            failure = None if reply.success else f"{reply.message} (not running: " \
                                                 f"{', '.join(reply.not_running)})"
        except Exception as e:  # noqa: BLE001 - the engine sees a dead scale in its status
            failure = f"failed: {e}"
        self._note_call(("renew_leases", action.scale), failure)

    def send_watch_lists(self, force=False):
        """Sends each scale the topics to count for the mapping when they changed, when its
        agent lost them, and every WATCH_RESEND_S."""
        with self.lock:
            lists = conv.watched_topics(self.model, self.engine.mapping())
            reports = dict(self.reports)
        now = time.monotonic()
        for scale, watched in lists.items():
            last = self.watch_sent.get(scale)
            if scale not in reports or (not force and last and last[0] == watched and
                                        now - last[1] < WATCH_RESEND_S and
                                        not self._watch_list_lost(reports[scale], watched,
                                                                  last[1])):
                continue
            self.watch_sent[scale] = (watched, now)
            self.scale_workers[scale].submit(lambda s=scale, w=watched: self._set_watched(s, w),
                                             key="watch")

    @staticmethod
    def _watch_list_lost(report, watched, sent_at):
        """Whether a report received WATCH_CHECK_S after the list was sent lacks a watched
        topic whose subscriber it shows running: the agent that got the list is gone (a
        restarted agent starts with none; docs/design/decision_node.md, Strays)."""
        return report.received_at > sent_at + WATCH_CHECK_S and any(
            topic not in report.topic_rates and conv.model_node_name(subscriber) in report.running
            for topic, subscriber in watched)

    def _set_watched(self, scale, watched):
        try:
            self.agents.set_watched(scale, [t for t, _ in watched], [n for _, n in watched])
            failure = None
        except Exception as e:  # noqa: BLE001 - retried at the next resend
            self.watch_sent.pop(scale, None)
            failure = f"failed: {e}"
        self._note_call(("set_watched_topics", scale), failure)

    def _note_call(self, key, failure):
        """Logs a repeated call's failure when it starts, and when the call works again."""
        service, scale = key
        if failure is not None:
            if self.call_failures.failed(key):
                rospy.logwarn("anyscale decision: %s on %s: %s; retrying quietly until it works",
                              service, scale, failure)
        elif self.call_failures.succeeded(key):
            rospy.loginfo("anyscale decision: %s on %s works again", service, scale)

    def purge_ghosts(self):
        """Removes the master's registrations of this system's node instances that are gone
        (see ghost_registrations), except where a node runs or is being handed over, and
        paused instances (launch.pause_at_home), which are registered but do not answer."""
        names = self._ghost_candidates()
        self.registrations.submit(lambda: self._purge(names), key="purge")

    def _ghost_candidates(self):
        with self.lock:
            mapping = self.engine.mapping()
            busy = set(self.handing_over)
            received = {scale: report.received_at for scale, report in self.reports.items()}
            paused = pauses_under_way(self.pausing, received) | {
                p.instance for status in self.statuses.values() for p in status.nodes
                if p.state == p.PAUSED}
        return ghost_candidates(self.model, mapping, busy, paused)

    def _purge(self, names):
        master = rosgraph.Master(self.caller_id)
        try:
            dead = dead_registrations(master, names, self.caller_id, GHOST_PING_TIMEOUT_S)
            # Each ping may wait GHOST_PING_TIMEOUT_S: an instance whose pause began meanwhile
            # does not answer either, and is no ghost; purged, it would run on unregistered once
            # resumed (docs/measurements/tolerances.md, "two decision-node races").
            candidates_now = set(self._ghost_candidates())
            dead = [name for name in dead if name in candidates_now]
            purge(master, dead)
        except (rosgraph.MasterError, OSError) as e:
            rospy.logdebug("anyscale decision: registration check failed: %s", e)
            return
        if dead:
            rospy.loginfo("anyscale decision: removed the master's registrations of %s (gone: "
                          "no answer on their API)", ", ".join(dead))
