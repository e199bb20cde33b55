"""config/testbed_three_scales.yaml is testbed.yaml with a server added (issue 39): the same
robot, laptop, network, nodes and connections; a server whose column of cpu_usage follows the
laptop's derivation; and a server that holds AMCL or AR recognition, not both, so that every
allocator uses both remote scales."""
import os

import pytest
import yaml

from anyscale_core.allocators import AllocationContext, make_allocator
from anyscale_core.characterisation import characterise
from anyscale_core.constraints import DynamicState, violations
from anyscale_core.model_loader import load_model

CONFIG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "config")
TWO, THREE = (os.path.join(CONFIG, f) for f in ("testbed.yaml", "testbed_three_scales.yaml"))


def raw(path):
    with open(path) as f:
        return yaml.safe_load(f)


def test_it_is_the_two_scale_model_with_a_server_added():
    two, three = raw(TWO), raw(THREE)
    assert three["scales"][:2] == two["scales"] and three["scales"][2]["name"] == "server"
    assert three["network"] == two["network"] and three["connections"] == two["connections"]
    assert len(three["nodes"]) == len(two["nodes"])
    for a, b in zip(two["nodes"], three["nodes"]):
        without_server = dict(b, cpu_usage={s: v for s, v in b["cpu_usage"].items()
                                            if s != "server"})
        assert without_server == a, a["name"]
        assert ("server" in b["cpu_usage"]) == ("laptop" in a["cpu_usage"]), a["name"]


def test_the_servers_figures_follow_the_laptops_derivation():
    model = load_model(THREE)
    server, laptop = model.scale("server"), model.scale("laptop")
    assert server.alpha == pytest.approx(server.cores * server.cpu_ghz / (2 * 1.6))
    assert server.cpu_ghz > laptop.cpu_ghz        # the paper's allocator tries it first
    # AMCL: 50 % x (5 Hz / 2 Hz) / alpha; AR recognition: 33 % / alpha x 1.3.
    amcl, ar = model.node("amcl").cpu_usage, model.node("ar_recognition").cpu_usage
    assert amcl["server"] == round(50 * 5 / 2 / server.alpha)
    assert ar["server"] == round(33 / server.alpha * 1.3)
    assert amcl["server"] <= 100 and amcl["server"] + ar["server"] > 100


@pytest.mark.parametrize("solver", ["paper", "paper_local", "optimal"])
def test_every_allocator_uses_both_remote_scales_on_a_full_link(solver):
    model = load_model(THREE)
    ch = characterise(model)
    state = DynamicState.nominal(model)
    decision = make_allocator(solver).decide(ch, ch.initial_mapping(), state,
                                             AllocationContext())
    mapping = ch.as_dict(decision.assign)
    assert {mapping["amcl"], mapping["ar_recognition"]} == {"laptop", "server"}
    assert violations(ch, decision.assign, state) == []
    if solver == "paper":               # fastest remote scale first: the server takes AMCL
        assert mapping["amcl"] == "server"
