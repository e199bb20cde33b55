"""The decision node's logic without ROS: agent reports in, start/stop/renew actions out.

Each tick turns the latest report of every scale into the dynamic state (paper III-B-2), asks
the connection judge which remote nodes spend a tolerance (connection_judge.py), runs the
allocator once (one iteration of Algorithm 1 per period, as the paper's loop sleeps between
iterations) and turns its moves into actions for the agents. The rospy wrapper only converts
messages and calls services.
"""
from dataclasses import replace
import math
from typing import AbstractSet, Dict, FrozenSet, List, Mapping, Optional, Tuple

import numpy as np

from .allocators import AllocationContext
from .characterisation import Characterisation
from .connection_judge import ConnectionJudge
from .constraints import DynamicState, required_bandwidth
from .cost import ObjectiveIntegrator, perf
from .decision_types import (DecisionParams, Event, RenewLeases, ScaleReport, StartNode, StopNode,
                             TickResult)
from .link_anticipation import LinkAnticipation
from .link_capacity import BandwidthHold, LinkCapacity
from .placement_learning import PlacementLearning
from .restart_backoff import RestartBackoff
from .restart_state import RestartState, RestartStateError, decode, encode


class DecisionEngine:
    def __init__(self, ch: Characterisation, allocator, params: DecisionParams = DecisionParams(),
                 start_time: float = 0.0):
        self.ch = ch
        self.allocator = allocator
        self.params = params
        self.assign = ch.initial_mapping()
        self.migrated_back_at: Dict[int, float] = {}
        self.handoff: Dict[str, Mapping[str, float]] = {}
        self.objective = ObjectiveIntegrator(start_time, perf(ch, self.assign))
        self.judge = ConnectionJudge(ch, params)
        self.load_filter: Dict[str, Tuple[float, float]] = {}   # scale -> (report time, load)
        self.backoff = [RestartBackoff(params.restart) for _ in ch.node_names]
        self.link = LinkCapacity(BandwidthHold(params.bandwidth_hold_s, params.bandwidth_margin),
                                 params.bandwidth_stay_margin, params.weak_link_mbps)
        self.start_acked_at: Dict[int, float] = {}   # node -> when its latest start was answered
        self.stop_answered_at: Dict[int, float] = {}  # node -> when its latest stop ended
        # node -> the remote scale it ran on under the decision node before a restart (restored)
        self.out_before_restart: Dict[int, str] = {}
        # Live cost estimates and failed moves' back-off (issue 40): placement_learning.py.
        self.learning = PlacementLearning(ch, params)
        self.anticipation = LinkAnticipation(ch, params)    # the link ahead (issue 36)
        self.last_state = DynamicState.nominal(ch.model)      # refusals between ticks

    # --- across a restart of the decision node (restart_state.py) -----------------------------
    def holds_last_s(self) -> float:
        """The longest hold a saved state can feed: older state holds nothing."""
        return max(self.params.hysteresis_s, self.params.longest_hold_after_loss())

    def restart_state(self, now: float) -> RestartState:
        """What a decision node restarted after this one needs to keep its holds: the returns
        still inside T, the latest loss still inside a node's hold after a loss, and the
        mapping."""
        back = {self.ch.node_names[i]: t for i, t in sorted(self.migrated_back_at.items())
                if now - t < self.params.hysteresis_s}
        lost = self.link.hold.lost_at
        return RestartState(now, self.mapping(), back,
                            lost if now - lost < self.params.longest_hold_after_loss() else None)

    def saved_state(self, wall_now: float, now: float) -> str:
        """restart_state as the text the rospy wrapper stores (wall-clock times)."""
        return encode(self.restart_state(now), wall_now, now)

    def restore_saved_state(self, text, wall_now: float, now: float) -> Tuple[bool, str]:
        """Before adopt_or_start: take over the holds of the decision node that ran before
        (text: what its saved_state returned). Returns whether the state could be read (False:
        malformed, worth a warning) and a line for the log. Malformed or stale state changes
        nothing: the engine starts fresh, as it always did."""
        try:
            state = decode(text, wall_now, now)
        except RestartStateError as e:
            return False, f"saved state unreadable ({e}); starting fresh"
        age = now - state.saved_at
        if age > self.holds_last_s():
            return True, (f"saved state {age:.1f} s old, older than the longest hold it could "
                          f"feed ({self.holds_last_s():g} s); starting fresh")
        back = {}
        for name, t in state.migrated_back_at.items():
            if name in self.ch.node_names and now - t < self.params.hysteresis_s:
                back[self.ch.node_index(name)] = t
        master = self.ch.scale_names[self.ch.master]
        out = {self.ch.node_index(n): s for n, s in state.mapping.items()
               if n in self.ch.node_names and s in self.ch.scale_names and s != master}
        lost = state.link_lost_at
        if lost is not None and not now - lost < self.params.longest_hold_after_loss():
            lost = None
        self.migrated_back_at.update(back)
        self.out_before_restart = out
        if lost is not None:
            self.link.hold.restore_loss(lost)
        parts = [f"{self.ch.node_names[i]} brought home {now - t:.1f} s ago"
                 for i, t in sorted(back.items())]
        if lost is not None:
            parts.append(f"link lost {now - lost:.1f} s ago")
        parts += [f"{self.ch.node_names[i]} was on {s}" for i, s in sorted(out.items())]
        return True, (f"saved state of {age:.1f} s ago: " +
                      ("; ".join(parts) if parts else "no hold running"))

    # --- start-up -----------------------------------------------------------------------------
    def adopt_or_start(self, reports: Mapping[str, ScaleReport], now: float) -> TickResult:
        """The first decision: keep what the agents already run (a restarted decision node),
        start the rest where the paper starts them (the master, or a pinned node's scale)."""
        actions, events = [], []
        for i, name in enumerate(self.ch.node_names):
            where = [s for s, r in reports.items() if name in r.running]
            home = self.ch.scale_names[self.assign[i]]
            if where:
                keep = home if home in where else where[0]
                if not self.ch.allowed[i, self.ch.scale_index(keep)]:
                    keep = home
                self.assign[i] = self.ch.scale_index(keep)
                events.append(Event("adopt", name, keep, keep, "already running"))
                actions += [StopNode(name, s) for s in where if s != keep]
                if keep not in where:
                    actions.append(self._start(i, self.ch.scale_index(keep), now))
            else:
                actions.append(self._start(i, self.assign[i], now))
                events.append(Event("start", name, "", home, "initial configuration"))
            if i in self.out_before_restart and self.assign[i] == self.ch.master:
                # It ran on a remote scale under the decision node before this one, and is
                # home now (its lease ran out while nobody renewed it): brought home, held for T.
                self.migrated_back_at[i] = now
                events[-1] = replace(events[-1], reason=(
                    f"{events[-1].reason}; on {self.out_before_restart[i]} before the decision "
                    f"node restarted: home for {self.params.hysteresis_s:g} s"))
            self.judge.moved(i, now)
        self.out_before_restart = {}
        self.objective.change(now, perf(self.ch, self.assign))
        self.last_state = self.dynamic_state(reports, now)
        return TickResult(actions, events, self.last_state, [])

    # --- every period -------------------------------------------------------------------------
    def tick(self, reports: Mapping[str, ScaleReport], now: float,
             moves_allowed: bool = True, starting: AbstractSet[str] = frozenset(),
             acting: AbstractSet[str] = frozenset()) -> TickResult:
        """One period. With moves_allowed False (the initial configuration is still coming up:
        its rates mean nothing yet) only the leases are renewed, nodes that ended started
        again and stray instances stopped. `starting`: nodes whose start has not been answered
        yet; `acting`: nodes with an action of the wrapper queued or under way (their strays
        may be what that action ends)."""
        state = self.last_state = self.dynamic_state(reports, now)
        self.learning.observe(reports, self.assign, now, lambda i: self._settled(i, now))  # learn
        up = state.up_vector(self.ch)
        remote_up = any(up[k] for k in range(self.ch.num_scales) if k != self.ch.master)
        measured = self._measured_bandwidth(reports, now)
        streams = required_bandwidth(self.ch, self.assign)
        self.link.observe(now, measured, remote_up, streams)
        state = replace(state, admit_bandwidth_mbps=self.link.admissible(now))
        strays = self._strays(reports, up, now, starting | acting)
        if not moves_allowed:
            restarts, restart_events = self._restarts(reports, up, now, starting, acting=acting)
            return TickResult(restarts + strays + self._renewals(up), restart_events, state, [])
        violating = self.judge.violating(self.assign, reports, now)
        ctx = AllocationContext(now, self.params.hysteresis_s, dict(self.migrated_back_at),
                                violating, self._held_after_loss(now),
                                self.learning.blocked(self.assign, state, now))   # learn
        weak = self.link.is_weak(measured, now, streams)
        # The link ahead (issue 36): holds lifted for nodes it carries, returns before a hole;
        # without a forecast, state and ctx as they are.
        state, ctx = self.anticipation.adjust(self.assign, state, ctx, measured, weak, up)
        decision = self.allocator.step(self.learning.planning(now), self.assign, state, ctx)
        actions, events, notes = [], [], []
        for move in decision.moves:
            name = self.ch.node_names[move.node]
            source, target = self.ch.scale_names[move.source], self.ch.scale_names[move.target]
            back = move.target == self.ch.master
            # Make before break: instances on different scales run under different names (the
            # agents' instance names), so the new one can start while the old one still
            # publishes, and the old one is stopped once the new one has published. An old
            # instance that cannot be reached ends by itself when its lease runs out.
            actions.append(self._start(move.node, move.target, now))
            if up[move.source]:
                pause = move.source == self.ch.master and \
                    self.ch.model.node(name).launch.pause_at_home
                actions.append(StopNode(name, source, after_output_on=target, pause=pause))
            elif self._carrier_up(reports):
                actions.append(StopNode(name, source, best_effort=True))
            reason = self.anticipation.reason(move, self._reason(move, measured, streams, weak))
            if move.source != self.ch.master:                                   # learn
                failed = self.learning.left(move.node, move.source, now, self.assign, state,
                                            violating, self.judge.slow_rate)
                if failed:
                    reason, notes = f"{reason}; {failed[0]}", notes + [failed[1]]
            events.append(Event("migrate_back" if back else "migrate", name, source, target,
                                reason))
            if back:
                self.migrated_back_at[move.node] = now
            self.judge.moved(move.node, now)
        self.anticipation.moved(decision.moves, [e.reason for e in events], now)
        if decision.moves:
            self.link.mapping_changed(now, streams)
            self.assign = decision.assign.copy()
            self.objective.change(now, perf(self.ch, self.assign))
        moved = {m.node for m in decision.moves}
        restarts, restart_events = self._restarts(reports, up, now, starting, moved=moved,
                                                  acting=acting)
        actions += restarts + [a for a in strays if self.ch.node_index(a.node) not in moved]
        actions += self._renewals(up)
        events += restart_events
        notes += self.learning.settle(self.assign, now)                         # learn
        return TickResult(actions, events, state,
                          [self.ch.node_names[i] for i in sorted(violating)], notes)

    def _settled(self, i: int, now: float) -> bool:
        """Node i's latest start is over (startup_grace_s): its CPU is its work, not imports."""
        return now - self.judge.moved_at.get(i, -math.inf) >= self.params.startup_grace_s

    def hold_after_loss_left(self, now: float) -> Dict[str, float]:
        """The nodes at home that the latest link loss still holds there, with the seconds left
        (DecisionParams.hold_after_loss): at the edge of coverage the link comes and goes, and
        a node moved out on its first good seconds comes home again by a link-loss return; for
        a node whose return comes close to its tolerance, that is the move to avoid. A node
        out is not held (it would be brought home)."""
        since = now - self.link.hold.lost_at
        return {name: self.params.hold_after_loss(name) - since
                for i, name in enumerate(self.ch.node_names)
                if self.assign[i] == self.ch.master and not self.ch.pinned[i]
                and since < self.params.hold_after_loss(name)}

    def _held_after_loss(self, now: float) -> FrozenSet[int]:
        return frozenset(self.ch.node_index(n) for n in self.hold_after_loss_left(now))

    def silence_alarm(self, report: ScaleReport, now: float) -> bool:
        """Whether `report` shows a judged connection silent for act_at_silence of its
        tolerance (ConnectionJudge.silence_alarm): the wrapper then ticks at once."""
        return self.judge.silence_alarm(self.assign, report, now)

    def output_seen(self, node: str, now: float):
        """The new instance of a moved `node` has published (the wrapper's handover watch saw
        it): from now its connections' silences are judged again, inside the start-up grace
        (ConnectionJudge)."""
        self.judge.output_seen(self.ch.node_index(node), now)

    def start_acknowledged(self, node: str, now: float):
        """The agent answered a start of `node`: reports received before now may still show the
        instance it replaces as ended."""
        self.start_acked_at[self.ch.node_index(node)] = now

    def stop_answered(self, node: str, now: float):
        """A stop or pause of `node` ended, answered or not: reports received before now may
        still show the instance it ended as running."""
        self.stop_answered_at[self.ch.node_index(node)] = now

    def move_failed(self, node: str, source: str, target: str, now: float) -> Optional[Event]:
        """A make-before-break move whose new instance on `target` never published: the node
        stays on `source`, whose instance still runs, and is not moved again for T."""
        i = self.ch.node_index(node)
        if self.ch.scale_names[self.assign[i]] != target:
            return None                 # moved again meanwhile: that decision stands
        self.assign[i] = self.ch.scale_index(source)
        self.migrated_back_at[i] = now
        self.judge.moved(i, now)
        self.objective.change(now, perf(self.ch, self.assign))
        return Event("migrate_back" if self.assign[i] == self.ch.master else "migrate", node,
                     target, source, f"the instance on {target} did not publish in time")

    def capacity_refused(self, node: str, scale: str, cpu_free: float, memory_free: float,
                         now: float) -> List[str]:
        """A shared scale's ledger refused a start of `node` on `scale` (it had room for
        cpu_free % and memory_free MB): the nodes that do not fit that are not tried there
        until its reports show room, or a back-off passes (PlacementLearning.refused). Call it
        before move_failed or action_failed puts the node back. The back-offs' log lines."""
        i, k = self.ch.node_index(node), self.ch.scale_index(scale)
        if self.assign[i] != k:
            return []                   # moved again meanwhile: that decision stands
        elsewhere = self.assign.copy()
        elsewhere[i] = self.ch.master
        return self.learning.refused(i, k, now, elsewhere, self.last_state, cpu_free,
                                     memory_free)

    def action_failed(self, node: str, scale: str, now: float) -> Optional[Event]:
        """A start on a remote scale did not happen: the node is on the master again (the
        wrapper has started it there) and is held back for T like any return."""
        i = self.ch.node_index(node)
        if self.ch.scale_names[self.assign[i]] != scale or self.assign[i] == self.ch.master:
            return None
        self.assign[i] = self.ch.master
        self.migrated_back_at[i] = now
        self.judge.moved(i, now)
        self.objective.change(now, perf(self.ch, self.assign))
        return Event("migrate_back", node, scale, self.ch.scale_names[self.ch.master],
                     "start on the remote scale failed")

    def set_link_forecast(self, forecasts):
        """The link ahead per remote scale for the next tick (link_forecast.LinkForecast), or
        None: no map, path or pose, and the reactive rules alone (issue 36)."""
        self.anticipation.update(forecasts)

    def observe_handoff(self, node: str, params: Mapping[str, float]):
        """The latest state of a node that hands its state over (e.g. its last pose)."""
        self.handoff[node] = dict(params)

    def _reason(self, move, measured: float, streams: float, weak: bool) -> str:
        """The allocator's reason, in the link's measured terms for a bandwidth return."""
        if move.target != self.ch.master or not move.reason.startswith("bandwidth"):
            return move.reason
        if weak:
            return (f"bandwidth {measured:.1f} Mbit/s, below weak_link_mbps "
                    f"{self.params.weak_link_mbps:g}: home before the link is lost")
        return (f"bandwidth {measured:.1f} Mbit/s < {streams:.2f} Mbit/s of streams + "
                f"{100 * self.params.bandwidth_stay_margin:.0f} %")

    def mapping(self) -> Dict[str, str]:
        return self.ch.as_dict(self.assign)

    # --- inside -------------------------------------------------------------------------------
    def dynamic_state(self, reports: Mapping[str, ScaleReport], now: float) -> DynamicState:
        master = self.ch.scale_names[self.ch.master]
        link_up, loads = {}, {}
        # The master's uplink without carrier cuts every remote scale off at once; their own
        # reports would only say so after status_timeout_s of silence.
        master_report = reports.get(master)
        uplink = master_report is None or master_report.link_up
        for k, scale in enumerate(self.ch.scale_names):
            report = reports.get(scale)
            fresh = report is not None and now - report.received_at <= self.params.status_timeout_s
            if scale != master:
                link_up[scale] = bool(fresh and report.link_up and uplink)
            if report is not None:
                load = self._smoothed(scale, report.received_at, self._background_load(report))
                # On a shared scale, other robots' reservations count whether or not their
                # nodes' CPU shows yet; their CPU is in the background load once it does.
                if load is not None or report.cpu_held > 0:
                    loads[scale] = max(load or 0.0, report.cpu_held)
        # Until a link is measured, the paper's nominal figure: nothing that is out comes back
        # for want of a measurement (a move out needs one, see BandwidthHold).
        measured = self._measured_bandwidth(reports, now)
        bandwidth = self.link.usable(measured, now, required_bandwidth(self.ch, self.assign)) \
            if math.isfinite(measured) else self.ch.model.network.max_bandwidth_mbps
        return DynamicState(bandwidth, loads, link_up)

    def _measured_bandwidth(self, reports: Mapping[str, ScaleReport], now: float) -> float:
        """The least fresh estimate of the remote scales' links; NaN if none has one."""
        fresh = [r.bandwidth_mbps for s, r in reports.items()
                 if s != self.ch.scale_names[self.ch.master]
                 and now - r.received_at <= self.params.status_timeout_s
                 and math.isfinite(r.bandwidth_mbps)]
        return min(fresh) if fresh else math.nan

    def _carrier_up(self, reports: Mapping[str, ScaleReport]) -> bool:
        master = reports.get(self.ch.scale_names[self.ch.master])
        return master is not None and master.link_up

    def _background_load(self, report: ScaleReport) -> float:
        """Scale CPU not explained by the model's nodes running there (% of the scale). Warm
        standbys do not count: their imports run in SCHED_IDLE (where the agent may), yielding
        to any other work, and last seconds; as load they would keep nodes away from a scale
        whose agent just prepared their standbys."""
        ours = sum(report.running.get(n, 0.0) for n in self.ch.node_names) + report.standby_cpu
        load = report.cpu_percent - ours / max(report.capacity_cores, 1e-9)
        return float(np.clip(load, 0.0, 100.0))

    def _smoothed(self, scale: str, at: float, load: float) -> Optional[float]:
        """Exponential smoothing of a scale's background load over report time: a node that
        starts or stops spends a burst of CPU (imports, shutdown) that is no lasting load, and
        acting on one 0.2 s sample would move nodes out and back for nothing. A load that is
        no number changes nothing (None if there is none yet): NaN would stay in the filter
        for good (the decision node's wrapper refuses such a status, status_check.py)."""
        last = self.load_filter.get(scale)
        if not math.isfinite(load):
            return None if last is None else last[1]
        if last is not None and at <= last[0]:
            return last[1]                      # the same report again
        if last is None or self.params.cpu_smoothing_s <= 0:
            value = load
        else:
            weight = 1.0 - math.exp(-(at - last[0]) / self.params.cpu_smoothing_s)
            value = last[1] + weight * (load - last[1])
        self.load_filter[scale] = (at, value)
        return value

    def _restarts(self, reports, up, now, starting, moved: AbstractSet[int] = frozenset(),
                  acting: AbstractSet[str] = frozenset()) -> Tuple[List[StartNode], List[Event]]:
        """Nodes that do not run on the scale they are assigned to, started there (again):
        - ended there unasked or by its lease, as their back-off allows (roslaunch's respawn): a
          crash, a node that exits when an input is missing at its start, a clean exit the
          master asked for; a node paused at home comes home instead
          (_crashed_out_comes_home);
        - not listed there at all, as their back-off allows: the agent's successor after a
          graceful shutdown, which stopped every node, lists none;
        - paused there (a stop_node{pause} that nobody undid): resumed, which a start does.
        A node with an action under way (`acting`) is judged once that is over, unless it ended.
        Only reports sampled after the node's latest start was answered count: an earlier one
        may still show the instance that start replaced, also when it arrives late
        (ScaleReport.sampled_at: a laptop status queued through a 10 s link loss showed the
        instance its move back had stopped, signal 9, and it arrived just after AMCL's next
        move out was answered)."""
        actions, events = [], []
        for i, name in enumerate(self.ch.node_names):
            k = int(self.assign[i])
            scale = self.ch.scale_names[k]
            report = reports.get(scale)
            if (i in moved or report is None or not up[k] or name in starting
                    or now - report.received_at > self.params.status_timeout_s
                    or report.sample_time() <= self.start_acked_at.get(i, -math.inf)):
                continue
            why = self._not_running(name, scale, report, acting)
            if why is None or (why[0] != "paused" and not self.backoff[i].due(now)):
                continue
            kind, how = why
            if kind != "paused":
                self.backoff[i].restarted(now)
            self.judge.moved(i, now)
            if kind != "paused" and k != self.ch.master and \
                    self.ch.model.node(name).launch.pause_at_home:
                actions.append(self._start(i, self.ch.master, now))
                events.append(self._crashed_out_comes_home(i, scale, how, now))
                continue
            actions.append(self._start(i, k, now))
            events.append(Event("restart", name, scale, scale, how))
        return actions, events

    @staticmethod
    def _not_running(name: str, scale: str, report: ScaleReport,
                     acting: AbstractSet[str]) -> Optional[Tuple[str, str]]:
        """Why `name`, due to run on `scale`, does not run there by `report`: ("ended" |
        "paused" | "missing", the reason); None if it runs, or if an action under way for it
        may be what the report shows (judged once that is over, unless the node ended)."""
        if name in report.ended:
            return "ended", f"ended on {scale}: {report.ended[name]}"
        if name in acting or name in report.running:
            return None
        if name in report.paused:
            return "paused", f"paused on {scale}, where it is due to run: resumed"
        if report.listed is not None and name not in report.listed:
            return "missing", (f"not listed by the agent of {scale} (a new agent: the one before "
                               f"it stopped it)")
        return None

    def _strays(self, reports, up, now, busy: AbstractSet[str]) -> List[StopNode]:
        """Stops (pauses, at home, for pause_at_home) for instances running where the mapping
        does not place their node and nothing under way for it explains them: a stop that did
        not get through. Only reports sampled after the node's latest start and stop were
        answered count (docs/design/decision_node.md, Strays)."""
        stops = []
        for i, name in enumerate(self.ch.node_names):
            if name in busy:
                continue
            settled = max(self.start_acked_at.get(i, -math.inf),
                          self.stop_answered_at.get(i, -math.inf))
            for scale, report in sorted(reports.items()):
                k = self.ch.scale_index(scale)
                if (k == self.assign[i] or not up[k] or name not in report.running
                        or report.sample_time() <= settled
                        or now - report.received_at > self.params.status_timeout_s):
                    continue
                pause = k == self.ch.master and self.ch.model.node(name).launch.pause_at_home
                stops.append(StopNode(name, scale, pause=pause, stray=True))
        return stops

    def _crashed_out_comes_home(self, i: int, scale: str, how: str, now: float) -> Event:
        """Brings home, held for T, a node with a paused instance at home that ended unasked
        on a remote scale: resuming it is faster than a restart out there, whose master calls
        cross the link (docs/design/decision_node.md, Restarts); the hold stops a bounce."""
        self.assign[i] = self.ch.master
        self.migrated_back_at[i] = now
        self.objective.change(now, perf(self.ch, self.assign))
        home = self.ch.scale_names[self.ch.master]
        return Event("migrate_back", self.ch.node_names[i], scale, home,
                     f"{how}; its paused instance at home resumed, held "
                     f"there for {self.params.hysteresis_s:g} s")

    def handoff_overrides(self, name: str) -> Tuple[Tuple[str, float], ...]:
        """The parameters a new instance of `name` starts with: its latest handed-over state."""
        if self.ch.model.node(name).state_handoff is None:
            return ()
        return tuple(sorted(self.handoff.get(name, {}).items()))

    def _start(self, i: int, k: int, now: float) -> StartNode:
        """Node i's start on scale k, with what it is expected to use there: a shared scale's
        ledger admits it against that (the live estimate the allocators planned with)."""
        name = self.ch.node_names[i]
        lease = 0.0 if k == self.ch.master else self.params.lease_s
        return StartNode(name, self.ch.scale_names[k], self.handoff_overrides(name), lease,
                         self.learning.cost(i, k, now), float(self.ch.memory[i]))

    def _renewals(self, up) -> List[RenewLeases]:
        renewals = []
        for k, scale in enumerate(self.ch.scale_names):
            nodes = tuple(self.ch.node_names[i] for i in np.flatnonzero(self.assign == k))
            if k != self.ch.master and up[k] and nodes:
                renewals.append(RenewLeases(scale, nodes, self.params.lease_s))
        return renewals
