"""The decision engine on a scale that robots share (docs/design/shared_scales.md): a start
carries what the node is expected to use there, other robots' reservations count as load, and a
start the scale's ledger refuses for capacity backs off every node that does not fit what was
free, until the scale's reports show room or the back-off passes."""
import dataclasses

from anyscale_core.decision_types import StartNode

from decision_reports import remote, reports


def held(t, cpu_held, **kw):
    """reports() whose laptop's ledger holds cpu_held % for other robots."""
    out = reports(t, **kw)
    out["laptop"] = dataclasses.replace(out["laptop"], cpu_held=cpu_held)
    return out


def starts(result):
    return {(a.node, a.scale): a for a in result.actions if isinstance(a, StartNode)}


def node_scale(engine, node):
    return engine.ch.node_index(node), engine.ch.scale_index("laptop")


def test_a_start_carries_the_live_cost_and_the_models_memory(engine, testbed):
    amcl = starts(engine.tick(reports(1.0), 1.0))["amcl", "laptop"]
    assert amcl.cpu_percent == testbed.node("amcl").cpu_usage["laptop"]   # nothing learned yet
    assert amcl.memory_mb == testbed.node("amcl").memory_mb
    # Once it ran there, the estimate it is planned with is what its next start asks for.
    for t in (2.0, 3.0, 4.0, 5.0, 6.0):
        engine.tick(reports(t, laptop_running=("amcl", "ar_recognition")), t)
    live = engine.learning.cost(*node_scale(engine, "amcl"), 6.0)
    assert live != testbed.node("amcl").cpu_usage["laptop"]
    assert engine._start(*node_scale(engine, "amcl"), 6.0).cpu_percent == live


def test_other_robots_reservations_count_as_the_scales_load(engine):
    state = engine.dynamic_state(held(1.0, 70.0, laptop_load=20.0), 1.0)
    assert state.scale_load["laptop"] == 70.0
    # Their nodes' CPU, once it shows, is the larger figure.
    assert engine.dynamic_state(held(5.0, 10.0, laptop_load=50.0), 5.0).scale_load["laptop"] > 40
    # 30 % left: AMCL (36 % there) stays home, AR recognition (12 %) goes.
    for t in (1.0, 2.0, 3.0, 4.0):
        engine.tick(held(t, 70.0), t)
    assert remote(engine) == ["ar_recognition"]


def refuse(engine, node, t, cpu_free, memory_free=1e6):
    """The ledger refuses the start of `node` on the laptop, as the wrapper reports it."""
    lines = engine.capacity_refused(node, "laptop", cpu_free, memory_free, t)
    engine.action_failed(node, "laptop", t)
    return lines


def blocked(engine, t):
    return {engine.ch.node_names[i] for i, _ in engine.learning.blocked(
        engine.assign, engine.last_state, t)}


def test_a_refusal_backs_off_every_node_that_does_not_fit_what_was_free(engine, testbed):
    assert set(starts(engine.tick(reports(1.0), 1.0))) == {("amcl", "laptop")}
    # Another robot won the race: 10 % were free.
    lines = refuse(engine, "amcl", 1.2, cpu_free=10.0)
    assert remote(engine) == []
    cost = {n.name: n.cpu_usage["laptop"] for n in testbed.nodes if "laptop" in n.cpu_usage}
    assert blocked(engine, 1.2) == {n for n, c in cost.items() if c > 10.0} == \
        {"amcl", "ar_recognition"}
    assert lines[0].startswith("amcl -> laptop backed off after its start refused for capacity "
                               "(1st in a row) (laptop full: 36 % > 10 % free)"), lines
    assert lines[1].startswith("ar_recognition -> laptop backed off after a start refused"), lines
    # The reports that came before the refusal show room: they are not believed.
    engine.tick(reports(1.0), 1.3)
    assert remote(engine) == [] and blocked(engine, 1.3) == {"amcl", "ar_recognition"}


def test_a_back_off_ends_once_the_scales_reports_show_room(engine):
    engine.tick(reports(1.0), 1.0)                     # AMCL: robot -> laptop
    refuse(engine, "amcl", 1.2, cpu_free=5.0)         # another robot holds 95 %
    t, free_at = 1.2, None
    while t < 9.0 and free_at is None:
        t += 0.5
        # Its node leaves the laptop at 5 s: room again, well before the back-offs (T) end.
        engine.tick(held(t, 95.0 if t < 5.0 else 0.0, laptop_running=()), t)
        if not blocked(engine, t):
            free_at = t
    assert free_at is not None and 5.0 <= free_at < 1.2 + engine.params.hysteresis_s


def test_a_refusal_for_memory_holds_until_the_back_off_passes_and_then_doubles(engine):
    engine.tick(reports(1.0), 1.0)
    refuse(engine, "amcl", 1.2, cpu_free=90.0, memory_free=100.0)   # AMCL: 120 MB
    first = engine.learning.backoff.retry_in(node_scale(engine, "amcl"), 1.2)
    assert first == engine.params.hysteresis_s

    def next_start(t, until):
        while t < until:
            t += 0.5
            if ("amcl", "laptop") in starts(engine.tick(reports(t), t)):
                return t
        return None
    t = next_start(1.2, 40.0)
    assert t is not None and 1.2 + first <= t < 1.2 + first + 1.0
    refuse(engine, "amcl", t, cpu_free=90.0, memory_free=100.0)
    # Held past its hold after a return (T): the back-off doubled.
    assert engine.learning.backoff.retry_in(node_scale(engine, "amcl"), t) == 2 * first
    again = next_start(t, t + 3 * first)
    assert again is not None and t + 2 * first <= again < t + 2 * first + 1.0


def test_a_refusal_after_the_node_moved_again_changes_nothing(engine):
    engine.tick(reports(1.0), 1.0)
    engine.action_failed("amcl", "laptop", 1.1)          # its move ended another way first
    assert engine.capacity_refused("amcl", "laptop", 0.0, 0.0, 1.2) == []
    assert not engine.learning.backoff.backoffs
