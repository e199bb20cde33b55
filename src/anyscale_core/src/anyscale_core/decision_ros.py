"""The decision node's rospy layer: parameters, agent status in, agent services out, the
mapping, events and diagnostics published. The decisions themselves are DecisionEngine's."""
import http.client
import math
import os
import threading
import time
import xmlrpc.client
from typing import Dict, List

import diagnostic_updater
import rospy
from anyscale_msgs.msg import MigrationEvent, ScaleStatus
from anyscale_msgs.msg import Mapping as MappingMsg
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped

from . import ros_convert as conv
from .agent_actions_ros import REGISTER_TIMEOUT_S, AgentActions
from .agent_client import AgentClient, Worker
from .cost import perf
from .cost_estimates_ros import CostEstimatesOut
from .decision_engine import DecisionEngine
from .decision_params import NodeParams, ParamError, prepare_decision, read_params
from .decision_types import StartNode, silent_scales
from .link_forecast_ros import LinkForecastRos
from .model import ModelError
from .process_priority import set_own_nice
from .restart_state import encode, worth_writing
from .status_check import status_problem

# A remote scale's status silent this long while the robot's uplink is up: a new connection.
RESUBSCRIBE_AFTER_S = 5.0

# The engine's holds for the decision node started after this one (restart_state.py), written on
# change and, while nodes are out, every STATE_REFRESH_S, from a worker of its own: a gone master
# holds no tick. Why a parameter: docs/design/decision_node.md, "Its holds survive a restart".
STATE_PARAM = "~restart_state"
STATE_REFRESH_S = 2.0
# What an XML-RPC call to the master raises when it is gone, does not answer, or breaks off.
MASTER_CALL_ERRORS = (OSError, http.client.HTTPException, xmlrpc.client.Error,
                      rospy.ROSException)


class DecisionNode:
    def __init__(self, params: NodeParams):
        self.params = params
        self.model, self.ch, allocator = prepare_decision(
            params.model, params.allocator, params.engine, params.time_budget_s)
        self.master = self.model.master.name
        self.engine = DecisionEngine(self.ch, allocator, params.engine, time.monotonic())
        self._restore_state()
        self.state_worker = Worker("anyscale_state")
        self.state_written = None             # the RestartState last written
        self.state_written_at = -math.inf
        self.lock = threading.Lock()          # the engine and the reports, across threads
        self.wake = threading.Event()         # set: tick now (a link was lost, a node ended)
        self.reports: Dict[str, object] = {}
        self.statuses: Dict[str, ScaleStatus] = {}
        self.violating: List[str] = []
        self.state = None                     # DynamicState of the latest tick
        self.actions = AgentActions(
            self.model, params, self.engine, self.lock,
            AgentClient(params.service_timeout_s, params.stop_timeout_s,
                        params.stop_sigint_timeout_s),
            self.reports, self.statuses, self._publish_event, self._publish_mapping,
            rospy.get_name())
        rospy.set_param("/anyscale/model", os.path.abspath(params.model))  # `anyscale top`
        self.mapping_pub = rospy.Publisher("/anyscale/mapping", MappingMsg, queue_size=1,
                                           latch=True)
        self.event_pub = rospy.Publisher("/anyscale/events", MigrationEvent, queue_size=50)
        self.costs_out = CostEstimatesOut(self.engine, self.lock, params.learned_costs_out,
                                          os.path.abspath(params.model), self.state_worker)
        # On the server, diagnostic_updater's read at every update is answered from rospy's
        # cache, never asked of a master that may be gone (a roscore restart, a teardown).
        rospy.set_param("~diagnostic_period", rospy.get_param("~diagnostic_period", 1.0))
        self.updater = diagnostic_updater.Updater()
        self.updater.setHardwareID("anyscale_decision")
        self.updater.add("mapping", self._diag_mapping)
        self.updater.add("connections", self._diag_connections)
        self.updater.add("scales", self._diag_scales)
        self.updater.add("link and load", self._diag_link_and_load)
        self.link_ahead = self._link_ahead()                 # the link ahead (issue 36)
        self.status_sub = rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_status,
                                           queue_size=20)
        self.resubscribed_at = time.monotonic()
        self.resubscribe_logged: List[str] = []
        for node in self.model.nodes:
            if node.state_handoff is not None and node.state_handoff.kind == "pose":
                rospy.Subscriber(node.state_handoff.topic, PoseWithCovarianceStamped,
                                 self._on_pose, callback_args=node.name, queue_size=1)

    # --- inputs -------------------------------------------------------------------------------
    def _on_status(self, msg):
        if msg.scale not in self.ch.scale_names:
            rospy.logwarn_once("anyscale decision: status from scale '%s', which is not in %s",
                               msg.scale, self.params.model)
            return
        problem = status_problem(msg)
        if problem is not None:
            # The scale's last good status stays; one that keeps coming bad goes stale like a
            # silent one. Throttled per line: a sender repeating itself is one line a minute.
            sender = (getattr(msg, "_connection_header", None) or {}).get("callerid", "?")
            rospy.logwarn_throttle_identical(
                60.0, "anyscale decision: refused a status of scale '%s' from %s: %s" %
                (msg.scale[:80], sender, problem))
            return
        if self.link_ahead:
            self.link_ahead.observe_status(msg)
        age = (rospy.Time.now() - msg.header.stamp).to_sec() if not msg.header.stamp.is_zero() \
            else math.nan
        report = conv.scale_report_from_msg(msg, time.monotonic(), self.ch.node_names, age)
        with self.lock:
            before = self.reports.get(msg.scale)
            self.reports[msg.scale] = report
            self.statuses[msg.scale] = msg
            silent = self.engine.silence_alarm(report, report.received_at)
        if silent or before is not None and (before.link_up and not report.link_up
                                             or set(report.ended) - set(before.ended)):
            # a link lost (e.g. the uplink's carrier), a node ended, a remote node's connection
            # silent too long: each is a return that a period's wait would make later
            self.wake.set()

    def _on_pose(self, msg, node):
        params = conv.handoff_params_from_pose(msg)
        with self.lock:
            self.engine.observe_handoff(node, params)

    # --- the loop -----------------------------------------------------------------------------
    def run(self):
        self._wait_for_agents()
        with self.lock:
            before = self.engine.mapping()
            result = self.engine.adopt_or_start(dict(self.reports), time.monotonic())
        self._dispatch(result, before, initial=True)
        self._save_state()
        # The allocator acts on measured rates and loads: not before the paper's initial
        # configuration runs (a node moved while the rest still imports is judged on nothing).
        coming_up = {(a.node, a.scale) for a in result.actions if isinstance(a, StartNode)}
        give_up_at = time.monotonic() + REGISTER_TIMEOUT_S
        next_tick = time.monotonic()
        while not rospy.is_shutdown():
            next_tick = self._wait_for_tick(next_tick + self.params.period_s)
            if coming_up:
                coming_up = self._initial_configuration_pending(coming_up, give_up_at)
            forecasts = self.link_ahead.forecasts() if self.link_ahead else None
            with self.lock:
                self.engine.set_link_forecast(forecasts)
                before = self.engine.mapping()
                starting, acting = self.actions.busy()
                result = self.engine.tick(dict(self.reports), time.monotonic(),
                                          moves_allowed=not coming_up, starting=starting,
                                          acting=acting)
                self.violating = result.violating
                self.state = result.state
                link_up = dict(result.state.link_up)
                self.actions.link_up = link_up
            if self.link_ahead:
                self.link_ahead.observe_links(link_up)
            self._dispatch(result, before)
            self._save_state()
            self.costs_out.publish()
            self._resubscribe_if_silent()
            self.actions.send_watch_lists()
            self.actions.purge_ghosts()
            self.updater.update()

    # --- the link ahead (link_forecast_ros.py) ---------------------------------------------------
    def _link_ahead(self):
        """The link map and forecast, once a path topic is given (else None: the reactive rules
        alone, said once in the log). With ~link_forecast false the map is still learned and
        saved, but the engine does not use it."""
        p = self.params.engine.link_forecast
        if not p.path_topic:
            rospy.loginfo("anyscale decision: no ~path_topic: no link map, no forecast; the "
                          "reactive rules decide")
            return None
        link_ahead = LinkForecastRos(p, [s for s in self.ch.scale_names if s != self.master],
                                     self.model.network.max_bandwidth_mbps)
        rospy.on_shutdown(link_ahead.save)
        # The engine's latest Anticipation: an immutable object, read without the lock.
        self.updater.add("link ahead", lambda stat: link_ahead.diagnose(
            stat, self.engine.anticipation.last, self.ch.node_names))
        return link_ahead

    # --- across a restart of this node (STATE_PARAM) --------------------------------------------
    def _restore_state(self):
        """The holds of the decision node that ran before this one, if any: a line in the log
        either way, a warning for a state that cannot be read (then a fresh start)."""
        try:
            text = rospy.get_param(STATE_PARAM, None)
        except MASTER_CALL_ERRORS as e:
            rospy.logwarn("anyscale decision: cannot read %s (%s); starting fresh",
                          rospy.resolve_name(STATE_PARAM), e)
            return
        if text is None:
            return                              # the first decision node of this roscore
        readable, line = self.engine.restore_saved_state(text, time.time(), time.monotonic())
        (rospy.loginfo if readable else rospy.logwarn)("anyscale decision: %s: %s",
                                                       rospy.resolve_name(STATE_PARAM), line)

    def _save_state(self):
        now = time.monotonic()
        with self.lock:
            state = self.engine.restart_state(now)
        out = any(s != self.master for s in state.mapping.values())
        if not worth_writing(state, self.state_written, out, now - self.state_written_at,
                             STATE_REFRESH_S):
            return
        self.state_written, self.state_written_at = state, now
        self.state_worker.submit(lambda text=encode(state, time.time(), now):
                                 self._write_state(text), key="state")

    @staticmethod
    def _write_state(text: str):
        try:
            rospy.set_param(STATE_PARAM, text)
        except MASTER_CALL_ERRORS as e:
            rospy.logwarn_throttle(30.0, "anyscale decision: cannot save %s (%s): a restart of "
                                   "this node meanwhile would forget its holds" %
                                   (rospy.resolve_name(STATE_PARAM), e))

    def _resubscribe_if_silent(self):
        """A new status connection for a scale silent RESUBSCRIBE_AFTER_S while the robot's
        uplink is up, or never heard from (silent_scales): TCP's retransmission backoff can hold
        the old one silent for minutes after an outage, with no error rospy would see."""
        now = time.monotonic()
        if now - self.resubscribed_at < RESUBSCRIBE_AFTER_S:
            return
        with self.lock:
            master = self.reports.get(self.master)
            received = {s: r.received_at for s, r in self.reports.items()}
        silent = silent_scales([s for s in self.ch.scale_names if s != self.master], received,
                               self.resubscribed_at, now, RESUBSCRIBE_AFTER_S)
        if not silent or master is None or not master.link_up:
            self.resubscribe_logged = []
            return
        # Once per silence in the log: an agent that is gone stays silent for as long as it is.
        if silent != self.resubscribe_logged:
            rospy.loginfo("anyscale decision: no status from %s for %.0f s while the uplink is "
                          "up: subscribing to /anyscale/status again, and every %.0f s until it "
                          "comes", ", ".join(silent), RESUBSCRIBE_AFTER_S, RESUBSCRIBE_AFTER_S)
            self.resubscribe_logged = silent
        self.status_sub.unregister()
        self.status_sub = rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_status,
                                           queue_size=20)
        self.resubscribed_at = now

    def _wait_for_tick(self, due: float) -> float:
        """Sleeps until `due` or an early wake-up; returns the time this tick counts from."""
        if self.wake.wait(max(0.0, due - time.monotonic())):
            self.wake.clear()
            return time.monotonic()
        # A tick that took longer than a period does not make the next ones come in a burst.
        return max(due, time.monotonic() - self.params.period_s)

    def _initial_configuration_pending(self, pending, give_up_at):
        """The initial starts not yet reported RUNNING (none once give_up_at has passed)."""
        pending = {(n, s) for n, s in pending if not self.actions.reports_running(s, n)}
        if pending and time.monotonic() < give_up_at:
            return pending
        if pending:
            rospy.logwarn("anyscale decision: %s not running after %.0f s; deciding anyway",
                          ", ".join(sorted(n for n, _ in pending)), REGISTER_TIMEOUT_S)
        else:
            rospy.loginfo("anyscale decision: initial configuration running; deciding")
        return set()

    def _wait_for_agents(self):
        """The master's agent must answer before anything can start; the others get
        ~adopt_wait_s to report what they already run, so a restart adopts it."""
        last_log = time.monotonic()
        while not rospy.is_shutdown() and self.master not in self.reports:
            if time.monotonic() - last_log > 5.0:
                rospy.logwarn("anyscale decision: waiting for the agent of the master scale "
                              "'%s' (/anyscale/status)", self.master)
                last_log = time.monotonic()
            rospy.sleep(0.1)
        end = time.monotonic() + self.params.adopt_wait_s
        while not rospy.is_shutdown() and time.monotonic() < end and \
                len(self.reports) < len(self.ch.scale_names):
            rospy.sleep(0.1)
        missing = sorted(set(self.ch.scale_names) - set(self.reports))
        if missing:
            rospy.logwarn("anyscale decision: no status from %s within %.1f s; starting without",
                          ", ".join(missing), self.params.adopt_wait_s)

    def _dispatch(self, result, before, initial=False):
        now_stamp = rospy.Time.now()
        decided = time.monotonic()
        self.actions.dispatch(result.actions, {e.node: e for e in result.events}, now_stamp,
                              decided)
        started = {a.node for a in result.actions if isinstance(a, StartNode)}
        for note in result.notes:                       # a failed move backed off, or reset
            rospy.loginfo("anyscale decision: %s", note)
        for e in result.events:
            if e.kind == "restart":
                rospy.logwarn("anyscale decision: %s ended (%s); starting it again", e.node,
                              e.reason)
            elif e.node not in started:
                # Adopted in place (at most a duplicate stopped): nothing to wait for.
                self._publish_event(e.kind, e.node, e.from_scale, e.to_scale, e.reason,
                                    now_stamp, 0.0)
        after = self.engine.mapping()
        if initial or after != before:
            if not initial:
                rospy.loginfo("anyscale decision: %s", conv.describe_change(
                    before, after, {e.node: e.reason for e in result.events}))
            else:
                rospy.loginfo("anyscale decision: initial mapping %s", after)
            self._publish_mapping()
            self.actions.send_watch_lists(force=initial)

    # --- outputs ------------------------------------------------------------------------------
    def _publish_mapping(self):
        with self.lock:
            mapping = self.engine.mapping()
            msg = conv.mapping_msg(mapping, perf(self.ch, self.engine.assign),
                                   self.engine.objective.total(time.monotonic()),
                                   self.params.allocator, rospy.Time.now())
        self.mapping_pub.publish(msg)

    def _publish_event(self, kind, node, from_scale, to_scale, reason, stamp, duration, ok=True):
        self.event_pub.publish(conv.event_msg(kind, node, from_scale, to_scale, reason, stamp,
                                              duration, ok))
        if kind != "start":
            rospy.loginfo("anyscale decision: event %s %s %s -> %s (%s) %.2f s", kind, node,
                          from_scale or "-", to_scale, reason, duration)

    def _diag_mapping(self, stat):
        with self.lock:
            mapping = self.engine.mapping()
        remote = sum(1 for s in mapping.values() if s != self.master)
        stat.summary(DiagnosticStatus.OK, f"{remote} of {len(mapping)} nodes off {self.master}")
        for node, scale in mapping.items():
            stat.add(node, scale)
        return stat

    def _diag_connections(self, stat):
        with self.lock:
            violating = list(self.violating)
        if violating:
            stat.summary(DiagnosticStatus.WARN, "spending a tolerance (below freq_min or silent): "
                         + ", ".join(violating))
        else:
            stat.summary(DiagnosticStatus.OK, "every judged connection within its tolerance")
        return stat

    def _diag_link_and_load(self, stat):
        """What the allocator judged the last tick on: why a node does or does not move out."""
        with self.lock:
            state = self.state
            held = self.engine.hold_after_loss_left(time.monotonic())
        if state is None:
            stat.summary(DiagnosticStatus.OK, "no decision yet")
            return stat
        # state.bandwidth_mbps is what the allocator may place: the estimate less the stay
        # margin, 0 on a weak link (LinkCapacity.usable).
        stat.summary(DiagnosticStatus.OK, f"link usable {state.bandwidth_mbps:.1f} Mbit/s, "
                     f"{state.admit_bandwidth_mbps:.1f} held for moves out" +
                     ("; home after a link loss: " + ", ".join(
                         f"{n} {s:.0f} s more" for n, s in sorted(held.items())) if held else ""))
        for s in self.ch.scale_names:
            stat.add(f"{s} background load [%]", f"{state.scale_load.get(s, 0.0):.0f}")
            if s != self.master:
                stat.add(f"{s} link", "up" if state.link_up.get(s, True) else "down")
        return stat

    def _diag_scales(self, stat):
        now = time.monotonic()
        with self.lock:
            ages = {s: now - r.received_at for s, r in self.reports.items()}
        stale = [s for s in self.ch.scale_names
                 if ages.get(s, math.inf) > self.params.engine.status_timeout_s]
        level = DiagnosticStatus.WARN if stale else DiagnosticStatus.OK
        stat.summary(level, "silent: " + ", ".join(stale) if stale else "all scales reporting")
        for s in self.ch.scale_names:
            stat.add(s, f"last status {ages[s]:.1f} s ago" if s in ages else "never seen")
        return stat


def raise_control_priority(nice: int):
    """On a robot held at its CPU quota, a decision taken late is a node's output silent for
    longer (a return after a link loss waits for this node's tick and calls): its work is
    small, so a raised priority costs the nodes little and takes its ticks ahead of them."""
    if nice == 0:
        return
    error = set_own_nice(nice)
    if error:
        rospy.logwarn("anyscale decision: cannot run at nice %d (%s: raising a priority needs "
                      "CAP_SYS_NICE); it runs at the nodes' priority", nice, error)


def main(argv=None) -> int:
    """Entry point of nodes/decision_node: exit 1 with one FATAL line on bad params or model."""
    rospy.init_node("anyscale_decision", argv=argv)
    try:
        node = DecisionNode(read_params(rospy.get_param))
    except (ParamError, ModelError) as e:
        rospy.logfatal("anyscale decision: %s", e)
        return 1
    raise_control_priority(node.params.control_nice)
    node.run()
    return 0
