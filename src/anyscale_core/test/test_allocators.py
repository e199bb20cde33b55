"""Allocators: Algorithm 1 step by step on the test bed, and properties of every allocator on
random systems (feasible results, critical nodes stay, the optimum is optimal)."""
from hypothesis import given, strategies as st
import numpy as np
import pytest

from anyscale_core.allocators import (ALLOCATORS, BUDGETED, DEFAULT_TIME_BUDGET_S,
                                      AllocationContext, OptimalAllocator, PaperAllocator,
                                      PaperLocalAllocator, make_allocator)
from anyscale_core.characterisation import characterise, enumerate_mappings
from anyscale_core.constraints import DynamicState, is_feasible
from anyscale_core.cost import perf
from anyscale_core.model_loader import parse_model

from core_test_data import random_systems

GOOD = DynamicState(54.0)


def where(ch, assign, node):
    return ch.scale_names[assign[ch.node_index(node)]]


def test_paper_moves_amcl_first_then_ar(testbed_ch):
    alloc, ctx = PaperAllocator(), AllocationContext()
    first = alloc.step(testbed_ch, testbed_ch.initial_mapping(), GOOD, ctx)
    assert [testbed_ch.node_names[m.node] for m in first.moves] == ["amcl"]
    second = alloc.step(testbed_ch, first.assign, GOOD, ctx)
    assert [testbed_ch.node_names[m.node] for m in second.moves] == ["ar_recognition"]
    assert alloc.step(testbed_ch, second.assign, GOOD, ctx).moves == []


def test_paper_low_bandwidth_sends_ar_back_and_keeps_amcl(testbed_ch):
    both = PaperAllocator().decide(testbed_ch, testbed_ch.initial_mapping(), GOOD,
                                   AllocationContext()).assign
    d = PaperAllocator().step(testbed_ch, both, DynamicState(3.0), AllocationContext())
    assert [(testbed_ch.node_names[m.node], testbed_ch.scale_names[m.target])
            for m in d.moves] == [("ar_recognition", "robot")]
    assert "bandwidth" in d.moves[0].reason
    assert where(testbed_ch, d.assign, "amcl") == "laptop"


def test_paper_link_down_brings_everything_back_in_one_step(testbed_ch):
    both = PaperAllocator().decide(testbed_ch, testbed_ch.initial_mapping(), GOOD,
                                   AllocationContext()).assign
    d = PaperAllocator().step(testbed_ch, both, DynamicState(54, link_up={"laptop": False}),
                              AllocationContext())
    assert (d.assign == testbed_ch.master).all()
    assert all("link to laptop down" in m.reason for m in d.moves) and len(d.moves) == 2


def test_paper_hysteresis_holds_a_node_back_for_t(testbed_ch):
    alloc = PaperAllocator()
    amcl = testbed_ch.node_index("amcl")
    held = AllocationContext(now=5.0, hysteresis_s=10.0, migrated_back_at={amcl: 0.0})
    d = alloc.step(testbed_ch, testbed_ch.initial_mapping(), GOOD, held)
    assert [testbed_ch.node_names[m.node] for m in d.moves] == ["ar_recognition"]
    later = AllocationContext(now=10.5, hysteresis_s=10.0, migrated_back_at={amcl: 0.0})
    d = alloc.step(testbed_ch, testbed_ch.initial_mapping(), GOOD, later)
    assert [testbed_ch.node_names[m.node] for m in d.moves] == ["amcl"]


@pytest.mark.parametrize("name", sorted(ALLOCATORS))
def test_a_node_held_after_a_loss_stays_home_through_a_whole_decision(testbed_ch, name):
    """AMCL (out) must come home and AR is held home after a loss: no allocator moves AR out,
    also not paper_local's decide(), which steps on with a context of its own."""
    amcl, ar = testbed_ch.node_index("amcl"), testbed_ch.node_index("ar_recognition")
    amcl_out = testbed_ch.initial_mapping()
    amcl_out[amcl] = testbed_ch.scale_index("laptop")
    ctx = AllocationContext(now=10.0, hysteresis_s=10.0, violating={amcl: "silent"},
                            held_after_loss=frozenset({ar}))
    d = make_allocator(name).decide(testbed_ch, amcl_out, GOOD, ctx)
    assert (d.assign == testbed_ch.master).all(), [testbed_ch.node_names[m.node] for m in d.moves]


def test_paper_violating_connection_sends_node_back(testbed_ch):
    both = PaperAllocator().decide(testbed_ch, testbed_ch.initial_mapping(), GOOD,
                                   AllocationContext()).assign
    amcl = testbed_ch.node_index("amcl")
    why = "laser->amcl (/scan) 3.0 Hz on laptop < 5 Hz for 1.0 s of 2 s"
    d = PaperAllocator().step(testbed_ch, both, GOOD, AllocationContext(violating={amcl: why}))
    assert [m.node for m in d.moves] == [amcl]
    assert d.moves[0].reason.endswith(why)      # the reason names the connection
    assert where(testbed_ch, d.assign, "ar_recognition") == "laptop"


def test_paper_overloaded_remote_scale_returns_its_heaviest_node(testbed_ch):
    both = PaperAllocator().decide(testbed_ch, testbed_ch.initial_mapping(), GOOD,
                                   AllocationContext()).assign
    d = PaperAllocator().step(testbed_ch, both, DynamicState(54, {"laptop": 60}),
                              AllocationContext())
    assert [testbed_ch.node_names[m.node] for m in d.moves] == ["amcl"]   # 60 + 12 fits


def test_paper_moves_a_node_out_only_short_of_saturating_the_scale(testbed_ch):
    # AMCL takes 36 % of the laptop: onto 54 % of load it fills it to 90 %, onto 55 % past it.
    at_54 = PaperAllocator().step(testbed_ch, testbed_ch.initial_mapping(),
                                  DynamicState(54, {"laptop": 54}), AllocationContext())
    assert [testbed_ch.node_names[m.node] for m in at_54.moves] == ["amcl"]
    at_55 = PaperAllocator().step(testbed_ch, testbed_ch.initial_mapping(),
                                  DynamicState(54, {"laptop": 55}), AllocationContext())
    assert "amcl" not in [testbed_ch.node_names[m.node] for m in at_55.moves]
    # Once there, the laptop at 95 % is saturated but not over capacity: AMCL stays.
    stay = PaperAllocator().step(testbed_ch, at_54.assign, DynamicState(54, {"laptop": 59}),
                                 AllocationContext())
    assert stay.moves == []


def test_paper_prefers_the_fastest_remote_scale(testbed_dict):
    testbed_dict["scales"].append({"name": "server", "cpu_ghz": 3.5, "cores": 8,
                                   "memory_mb": 8192, "alpha": 8.75})
    for node in testbed_dict["nodes"]:
        if node["name"] in ("amcl", "ar_recognition"):
            node["cpu_usage"]["server"] = 10
    ch = characterise(parse_model(testbed_dict, "three.yaml"))
    d = PaperAllocator().step(ch, ch.initial_mapping(), GOOD, AllocationContext())
    assert ch.scale_names[d.moves[0].target] == "server"


def test_optimal_on_testbed(testbed_ch):
    opt = OptimalAllocator()
    assert where(testbed_ch, opt.decide(testbed_ch, testbed_ch.initial_mapping(),
                                        DynamicState(3.0), AllocationContext()).assign,
                 "ar_recognition") == "robot"
    d = opt.decide(testbed_ch, testbed_ch.initial_mapping(), GOOD, AllocationContext())
    assert perf(testbed_ch, d.assign) == pytest.approx(125 - 83 + 36 * 3.5 + 12 * 3.5)


def test_optimal_unchanged_situation_moves_nothing(testbed_ch):
    opt = OptimalAllocator()
    d = opt.decide(testbed_ch, testbed_ch.initial_mapping(), GOOD, AllocationContext())
    assert opt.decide(testbed_ch, d.assign, GOOD, AllocationContext()).moves == []


def test_unknown_allocator_names_the_known_ones():
    with pytest.raises(ValueError, match="known: optimal, paper"):
        make_allocator("simulated_annealing")


@st.composite
def states(draw, ch):
    return DynamicState(
        bandwidth_mbps=draw(st.floats(0, 30)),
        scale_load={s: draw(st.floats(0, 95)) for s in ch.scale_names},
        link_up={s: draw(st.booleans()) for j, s in enumerate(ch.scale_names) if j != ch.master})


@st.composite
def systems_and_states(draw):
    ch = draw(random_systems())
    return ch, draw(states(ch))


@given(systems_and_states())
def test_optimal_beats_every_feasible_mapping(case):
    ch, state = case
    best = OptimalAllocator().decide(ch, ch.initial_mapping(), state, AllocationContext())
    assert is_feasible(ch, best.assign, state)
    feasible = [a for a in enumerate_mappings(ch, ch.allowed) if is_feasible(ch, a, state)]
    assert perf(ch, best.assign) >= max(perf(ch, a) for a in feasible) - 1e-6


@given(systems_and_states())
def test_milp_matches_enumeration(case):
    ch, state = case
    enumerated = OptimalAllocator().decide(ch, ch.initial_mapping(), state, AllocationContext())
    solved = OptimalAllocator(enumeration_limit=0, time_budget_s=None)
    milp = solved.decide(ch, ch.initial_mapping(), state, AllocationContext())
    assert solved.last_method == "milp"
    assert is_feasible(ch, milp.assign, state)
    assert perf(ch, milp.assign) == pytest.approx(perf(ch, enumerated.assign), abs=1e-4)


@pytest.mark.parametrize("name", sorted(ALLOCATORS))
@given(case=systems_and_states(), seed=st.integers(0, 2 ** 16))
def test_allocators_return_feasible_mappings_and_keep_critical_nodes(name, case, seed):
    ch, state = case
    rng = np.random.default_rng(seed)
    # From the all-on-master start and from any placement the model allows.
    start = np.array([rng.choice(np.flatnonzero(row)) for row in ch.allowed])
    for current in (ch.initial_mapping(), start):
        d = make_allocator(name).decide(ch, current, state, AllocationContext())
        assert is_feasible(ch, d.assign, state)
        assert (d.assign[ch.critical] == ch.master).all()
        assert (d.assign[ch.pinned] == current[ch.pinned]).all()


class TickingClock:
    """A clock that advances one tick each time it is read: a time budget in ticks bounds the
    number of checks, so budgeted searches are deterministic."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        self.t += 1.0
        return self.t


@given(systems_and_states())
def test_a_time_budgeted_search_returns_a_feasible_mapping_never_below_its_start(case):
    """paper_local is anytime: with any budget its decision keeps every constraint, is at least
    the paper's decision it starts from, and is no worse for a longer budget."""
    ch, state = case
    start, ctx = ch.initial_mapping(), AllocationContext()
    paper = perf(ch, PaperAllocator().decide(ch, start, state, ctx).assign)
    last = -np.inf
    for ticks in (0, 1, 2, 3, 5, 8, 13, 40, None):
        alloc = PaperLocalAllocator(time_budget_s=ticks, clock=TickingClock())
        d = alloc.decide(ch, start, state, ctx)
        assert is_feasible(ch, d.assign, state)
        assert perf(ch, d.assign) >= max(paper, last) - 1e-9
        last = perf(ch, d.assign)


@given(systems_and_states())
def test_a_search_with_no_time_left_returns_the_paper_decision(case):
    ch, state = case
    start, ctx = ch.initial_mapping(), AllocationContext()
    paper = PaperAllocator().decide(ch, start, state, ctx).assign
    assert (PaperLocalAllocator(time_budget_s=0.0).decide(ch, start, state, ctx).assign
            == paper).all()
    # The MILP gets no time either: the optimum falls back on its incumbent, paper_local's.
    optimal = OptimalAllocator(enumeration_limit=0, time_budget_s=0.0)
    assert (optimal.decide(ch, start, state, ctx).assign == paper).all()
    assert optimal.last_method == "local search"


def test_searching_allocators_take_the_time_budget_and_the_paper_step_none():
    for name in BUDGETED:
        assert make_allocator(name).time_budget_s == DEFAULT_TIME_BUDGET_S
        assert make_allocator(name, 0.02).time_budget_s == 0.02
    assert not hasattr(make_allocator("paper", 0.02), "time_budget_s")
