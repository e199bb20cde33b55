"""A restarted decision node keeps the holds of the one before it (restart_state.py): a node
brought home is not moved out again for T, and after a link loss no node moves out before the
link has been up for its hold after a loss, although the new engine has seen the link good for its
bandwidth hold. State older than those holds, and state that cannot be read, change nothing.

Each engine runs on a clock of its own, as each process's monotonic clock does; the wall clock
is the same for both: `wall(t)` is the wall-clock time of the old engine's time t, and the new
engine's time is the old one's plus NEW_CLOCK."""
import dataclasses
import json
import math

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams
from anyscale_core import decision_ros
from anyscale_core import restart_state
from anyscale_core.restart_state import RestartState, RestartStateError, decode, encode

from decision_reports import remote, reports

WALL = 1.7e9            # the wall clock when the old engine's clock read 0
NEW_CLOCK = 5000.0      # the new process's monotonic clock reads the old one's plus this


def wall(t):
    return WALL + t


def new_reports(t, **kw):
    """reports() stamped on the new engine's clock, for the old engine's time t."""
    return reports(t + NEW_CLOCK, **kw)


def started(testbed_ch, params, t=0.0, **kw):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), params, t)
    e.adopt_or_start(reports(t, **kw), t)
    return e


def restarted(testbed_ch, params, saved, t, laptop_running=()):
    """A new engine, started at the old engine's time t from `saved`: (engine, restore's
    answer)."""
    e = DecisionEngine(testbed_ch, make_allocator("paper"), params, t + NEW_CLOCK)
    answer = e.restore_saved_state(saved, wall(t), t + NEW_CLOCK)
    e.adopt_or_start(new_reports(t, laptop_running=laptop_running), t + NEW_CLOCK)
    return e, answer


def first_move_out(e, start, end, step=0.5):
    """The first time (old engine's clock) in [start, end) at which e moves a node out, with a
    good link all along; None if none."""
    t = start
    while t < end:
        if any(ev.kind == "migrate" for ev in e.tick(new_reports(t), t + NEW_CLOCK).events):
            return t
        t += step
    return None


def brought_home_at_5(testbed_ch, params):
    """The old engine: AMCL and AR out at 1 s, home at 5 s when the laptop goes silent, and
    the link back at 6 s; its saved state at 6 s."""
    e = started(testbed_ch, params)
    for t in (1.0, 2.0, 3.0):
        e.tick(reports(t), t)
    assert remote(e) == ["amcl", "ar_recognition"]
    e.tick({"robot": reports(5.0)["robot"]}, 5.0)
    assert remote(e) == []
    e.tick(reports(6.0), 6.0)
    return e.saved_state(wall(6.0), 6.0)


HYSTERESIS = DecisionParams(bandwidth_hold_s=5.0, hysteresis_s=30.0, startup_grace_s=0.0)


def test_a_restarted_engine_does_not_move_a_node_out_before_t_plus_T(testbed_ch):
    # The old engine's first moves out needed no hold (it had watched the link since 0).
    params = dataclasses.replace(HYSTERESIS, bandwidth_hold_s=0.0)
    saved = brought_home_at_5(testbed_ch, params)
    # Restarted at 7 s with the 5 s bandwidth hold: the link is good from 6 s on, so the hold
    # alone would let AMCL out at 13 s (the test below); T keeps it home until 5 + 30 s.
    e, (readable, line) = restarted(testbed_ch, HYSTERESIS, saved, 7.0)
    assert readable
    assert "amcl brought home 2.0 s ago" in line
    assert first_move_out(e, 8.0, 40.0) == 35.0


def test_without_the_saved_state_the_restarted_engine_moves_out_after_the_bandwidth_hold(
        testbed_ch):
    """What the defect was: the hold alone (the test above, without restore)."""
    e = DecisionEngine(testbed_ch, make_allocator("paper"), HYSTERESIS, 7.0 + NEW_CLOCK)
    e.adopt_or_start(new_reports(7.0), 7.0 + NEW_CLOCK)
    assert first_move_out(e, 8.0, 40.0) == 13.0     # the link watched from the first tick


def test_a_restarted_engine_keeps_the_hold_after_a_loss(testbed_ch):
    params = DecisionParams(bandwidth_hold_s=5.0, hysteresis_s=0.0, hold_after_loss_s=20.0,
                            startup_grace_s=0.0)
    saved = brought_home_at_5(testbed_ch, dataclasses.replace(params, bandwidth_hold_s=0.0))
    e, (readable, line) = restarted(testbed_ch, params, saved, 7.0)
    assert readable and "link lost 2.0 s ago" in line
    # Lost last at 5 s: nothing out before 25 s, though the link is good from 6 s.
    assert first_move_out(e, 8.0, 40.0) == 25.0


def test_a_restarted_engine_keeps_each_nodes_own_hold_after_a_loss(testbed_ch):
    params = DecisionParams(bandwidth_hold_s=5.0, hysteresis_s=0.0, hold_after_loss_s=20.0,
                            node_hold_after_loss_s={"amcl": 0.0}, startup_grace_s=0.0)
    saved = brought_home_at_5(testbed_ch, dataclasses.replace(params, bandwidth_hold_s=0.0))
    e, (readable, line) = restarted(testbed_ch, params, saved, 7.0)
    assert readable and "link lost 2.0 s ago" in line
    # AMCL after the new engine's bandwidth hold (the link watched from its first tick, 8 s);
    # AR not before 25 s.
    assert first_move_out(e, 8.0, 40.0) == 13.0 and remote(e) == ["amcl"]
    assert first_move_out(e, 12.5, 40.0) == 25.0 and remote(e) == ["amcl", "ar_recognition"]


def test_a_node_whose_lease_ran_out_during_the_restart_is_held_home_for_T(testbed_ch):
    """Killed while AMCL and AR were out; the new engine comes after their leases ran out and
    starts them at home: brought home by the restart, held for T from then."""
    old = started(testbed_ch, dataclasses.replace(HYSTERESIS, bandwidth_hold_s=0.0))
    for t in (1.0, 2.0):
        old.tick(reports(t), t)
    assert remote(old) == ["amcl", "ar_recognition"]
    saved = old.saved_state(wall(2.0), 2.0)
    e, (readable, line) = restarted(testbed_ch, HYSTERESIS, saved, 8.0)
    assert readable and "amcl was on laptop" in line
    assert first_move_out(e, 9.0, 45.0) == 38.0


def test_a_node_still_out_after_the_restart_is_adopted_and_not_held(testbed_ch):
    old = started(testbed_ch, dataclasses.replace(HYSTERESIS, bandwidth_hold_s=0.0))
    for t in (1.0, 2.0):
        old.tick(reports(t), t)
    saved = old.saved_state(wall(2.0), 2.0)
    e, _ = restarted(testbed_ch, HYSTERESIS, saved, 3.0,
                     laptop_running=("amcl", "ar_recognition"))
    assert remote(e) == ["amcl", "ar_recognition"]
    assert e.migrated_back_at == {}


def test_stale_state_is_ignored(testbed_ch):
    params = dataclasses.replace(HYSTERESIS, bandwidth_hold_s=0.0)
    saved = brought_home_at_5(testbed_ch, params)     # saved at 6 s
    # Restarted 31 s after the save: longer than T (30 s) and hold_after_loss_s (0): a fresh
    # start, the bandwidth hold alone.
    e, (readable, line) = restarted(testbed_ch, HYSTERESIS, saved, 37.0)
    assert readable and "starting fresh" in line and "31.0 s old" in line
    assert e.migrated_back_at == {} and math.isinf(e.link.hold.lost_at)
    assert first_move_out(e, 38.0, 60.0) == 43.0


def test_each_hold_is_taken_over_only_while_it_runs(testbed_ch):
    params = DecisionParams(bandwidth_hold_s=0.0, hysteresis_s=30.0, hold_after_loss_s=3.0)
    saved = brought_home_at_5(testbed_ch, params)
    # At 9 s the loss (5 s) is 4 s old, past its 3 s hold; the return is still inside T.
    e, (readable, line) = restarted(testbed_ch, params, saved, 9.0)
    assert readable and "link lost" not in line
    assert math.isinf(e.link.hold.lost_at)
    assert e.migrated_back_at[testbed_ch.node_index("amcl")] == pytest.approx(5.0 + NEW_CLOCK)


def test_only_running_holds_are_saved(testbed_ch):
    params = DecisionParams(bandwidth_hold_s=0.0, hysteresis_s=30.0, hold_after_loss_s=3.0)
    saved = brought_home_at_5(testbed_ch, params)
    data = json.loads(saved)
    assert data["version"] == 1 and data["saved_at"] == wall(6.0)
    assert data["migrated_back_at"] == {"amcl": wall(5.0), "ar_recognition": wall(5.0)}
    assert data["link_lost_at"] == wall(5.0)
    assert set(data["mapping"].values()) == {"robot"}
    state = decode(saved, wall(40.0), 40.0)        # the same clock: the same times
    assert state.saved_at == 6.0 and state.link_lost_at == 5.0


def test_a_time_in_the_future_counts_as_now():
    """The wall clock stepped back between the save and the restore: the hold runs in full."""
    text = encode(RestartState(10.0, {}, {"amcl": 10.0}), wall(10.0), 10.0)
    state = decode(text, wall(10.0) - 100.0, 500.0)
    assert state.migrated_back_at["amcl"] == 500.0 and state.saved_at == 500.0


MALFORMED = [
    ("not json {", "not JSON"),
    ("[1, 2]", "expected a JSON object, got list"),
    ('{"version": 2, "saved_at": 1}', "version 2"),
    ('{"version": 1, "saved_at": "yesterday"}', "saved_at: expected a wall-clock time"),
    ('{"version": 1, "saved_at": NaN}', "saved_at: expected a wall-clock time"),
    ('{"version": 1, "saved_at": 1.7e9, "migrated_back_at": {"amcl": null}}',
     "migrated_back_at.amcl"),
    ('{"version": 1, "saved_at": 1.7e9, "migrated_back_at": [1]}', "migrated_back_at: expected"),
    ('{"version": 1, "saved_at": 1.7e9, "mapping": {"amcl": 3}}', "mapping: expected scale"),
    ('{"version": 1, "saved_at": 1.7e9, "link_lost_at": true}', "link_lost_at"),
    ({"version": 1}, "expected a JSON string, got dict"),
]


@pytest.mark.parametrize("text, why", MALFORMED)
def test_malformed_state_is_a_clear_line_and_a_fresh_start(testbed_ch, text, why):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), HYSTERESIS, 7.0)
    readable, line = e.restore_saved_state(text, WALL, 7.0)
    assert not readable
    assert why in line and line.endswith("starting fresh")
    assert e.migrated_back_at == {} and e.out_before_restart == {}
    assert math.isinf(e.link.hold.lost_at)
    with pytest.raises(RestartStateError):
        decode(text, WALL, 7.0)


# --- the rospy wrapper: reads the parameter once, writes it when it changes -------------------
class FakeRospy:
    def __init__(self, params=None, fail=None):
        self.params = dict(params or {})
        self.fail = fail
        self.logged = []

    def get_param(self, name, default=None):
        if self.fail:
            raise self.fail
        return self.params.get(name, default)

    def set_param(self, name, value):
        if self.fail:
            raise self.fail
        self.params[name] = value

    def resolve_name(self, name):
        return "/anyscale_decision/" + name.lstrip("~")

    def loginfo(self, fmt, *args):
        self.logged.append(("info", fmt % args))

    def logwarn(self, fmt, *args):
        self.logged.append(("warn", fmt % args))

    def logwarn_throttle(self, period, line):
        self.logged.append(("warn", line))


class Inline:
    def submit(self, job, key=None):
        job()


class Node:
    """What DecisionNode's state methods use of the node."""
    _restore_state = decision_ros.DecisionNode._restore_state
    _save_state = decision_ros.DecisionNode._save_state
    _write_state = staticmethod(decision_ros.DecisionNode._write_state)

    def __init__(self, engine):
        import threading
        self.engine, self.lock, self.master = engine, threading.Lock(), "robot"
        self.state_worker, self.state_written, self.state_written_at = Inline(), None, -math.inf


@pytest.mark.parametrize("fail", [None, ConnectionRefusedError(111, "Connection refused")])
def test_the_wrapper_logs_an_unreadable_state_and_starts_fresh(testbed_ch, monkeypatch, fail):
    fake = FakeRospy({decision_ros.STATE_PARAM: "not json {"}, fail)
    monkeypatch.setattr(decision_ros, "rospy", fake)
    node = Node(DecisionEngine(testbed_ch, make_allocator("paper"), HYSTERESIS, 0.0))
    node._restore_state()
    [(level, line)] = fake.logged
    assert level == "warn" and "/anyscale_decision/restart_state" in line
    assert "starting fresh" in line
    assert node.engine.migrated_back_at == {}


def test_the_wrapper_writes_on_change_and_refreshes_while_nodes_are_out(testbed_ch,
                                                                        monkeypatch):
    fake = FakeRospy()
    writes = []
    monkeypatch.setattr(decision_ros, "rospy", fake)
    monkeypatch.setattr(fake, "set_param", lambda name, value: writes.append(value))
    clock = [0.0]
    monkeypatch.setattr(decision_ros.time, "monotonic", lambda: clock[0])
    node = Node(started(testbed_ch, dataclasses.replace(HYSTERESIS, bandwidth_hold_s=0.0)))
    node._save_state()
    clock[0] = 1.0
    node._save_state()
    assert len(writes) == 1                          # all home, nothing changed: written once
    node.engine.tick(reports(1.0), 1.0)             # AMCL and AR out
    node._save_state()
    assert len(writes) == 2 and json.loads(writes[-1])["mapping"]["amcl"] == "laptop"
    clock[0] = 2.0
    node._save_state()
    assert len(writes) == 2
    clock[0] = 1.0 + decision_ros.STATE_REFRESH_S
    node._save_state()
    assert len(writes) == 3                          # out: saved_at kept current


def test_a_loss_time_moving_on_while_the_link_stays_down_is_written_every_refresh_only():
    home = RestartState(0.0, {"amcl": "robot"}, {}, None)
    down = dataclasses.replace(home, link_lost_at=10.0)
    refresh = decision_ros.STATE_REFRESH_S
    assert restart_state.worth_writing(home, None, False, 0.0, refresh)
    assert restart_state.worth_writing(down, home, False, 0.3, refresh)       # the loss
    later = dataclasses.replace(down, saved_at=0.3, link_lost_at=10.3)        # a tick on
    assert not restart_state.worth_writing(later, down, False, 0.3, refresh)
    assert restart_state.worth_writing(dataclasses.replace(later, link_lost_at=10.0 + refresh),
                                       down, False, refresh, refresh)
    assert restart_state.worth_writing(home, down, False, 0.3, refresh)       # hold over
    back = dataclasses.replace(later, migrated_back_at={"amcl": 10.3})
    assert restart_state.worth_writing(back, down, False, 0.3, refresh)       # other change
    out = dataclasses.replace(home, mapping={"amcl": "laptop"})
    assert not restart_state.worth_writing(out, out, True, 1.0, refresh)
    assert restart_state.worth_writing(out, out, True, refresh, refresh)      # kept current


def test_the_wrapper_survives_a_master_that_is_gone(testbed_ch, monkeypatch):
    fake = FakeRospy(fail=ConnectionRefusedError(111, "Connection refused"))
    monkeypatch.setattr(decision_ros, "rospy", fake)
    node = Node(started(testbed_ch, HYSTERESIS))
    node._save_state()
    assert [level for level, _ in fake.logged] == ["warn"]
    assert "cannot save /anyscale_decision/restart_state" in fake.logged[0][1]
