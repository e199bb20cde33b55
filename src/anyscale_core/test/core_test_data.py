"""Test data for anyscale_core's tests: the paper's test bed (a model of their own, beside this
file) and random system models (hypothesis strategies)."""
import copy
import os

from hypothesis import strategies as st

from anyscale_core.characterisation import characterise
from anyscale_core.model_loader import parse_model

TESTBED = os.path.join(os.path.dirname(os.path.abspath(__file__)), "config", "paper_testbed.yaml")


def mutated(data, path, value):
    """A deep copy of a YAML tree with the value at path (keys and indices) replaced;
    value=DELETE removes the key."""
    data = copy.deepcopy(data)
    target = data
    for key in path[:-1]:
        target = target[key]
    if value is DELETE:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return data


DELETE = object()


@st.composite
def random_model_dicts(draw, max_nodes=7, max_scales=4):
    """Valid system models: a master, 1..max_scales-1 remote scales, critical, pinned and
    migratable nodes, random connections with tolerances and bandwidths."""
    k = draw(st.integers(2, max_scales))
    scales = [{"name": f"s{j}", "master": j == 0, "cpu_ghz": draw(st.floats(1.0, 4.0)),
               "cores": draw(st.integers(1, 16)), "memory_mb": draw(st.sampled_from([512, 4096])),
               "alpha": 1.0 if j == 0 else draw(st.floats(0.5, 6.0))} for j in range(k)]
    scales[0]["memory_mb"] = 1_000_000
    n = draw(st.integers(2, max_nodes))
    nodes = []
    for i in range(n):
        cpu = {"s0": draw(st.floats(0, 60))}
        for j in range(1, k):
            if draw(st.booleans()) or j == 1:
                cpu[f"s{j}"] = draw(st.floats(0, 60))
        node = {"name": f"n{i}", "launch": {"package": "pkg", "type": f"exe{i}"},
                "cpu_usage": cpu, "memory_mb": draw(st.sampled_from([10, 300, 1000]))}
        if draw(st.integers(0, 5)) == 0:
            node["pinned"] = "s0"
        nodes.append(node)
    connections = []
    for c in range(draw(st.integers(0, 2 * n))):
        p, s = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
        if p == s:
            continue
        fmin = draw(st.floats(0.5, 10))
        connections.append({"publisher": f"n{p}", "subscriber": f"n{s}", "topic": f"/t{c}",
                            "freq_min": fmin, "freq_opt": fmin * 2,
                            "tolerance": draw(st.sampled_from([0, 1, 2, 5])),
                            "bandwidth_mbps": draw(st.floats(0, 10))})
    return {"scales": scales, "network": {"technology": "wifi", "max_bandwidth_mbps": 54},
            "nodes": nodes, "connections": connections}


@st.composite
def random_systems(draw, **kwargs):
    """(Characterisation, DynamicState-like dict) for property tests."""
    model = parse_model(draw(random_model_dicts(**kwargs)), "<random>")
    return characterise(model)


def filled_draft(model: dict, critical_topics=()) -> dict:
    """A draft of `anyscale model draft` (its YAML tree) with every TODO replaced as a user
    would: a laptop, CPU shares, 1 Hz minimum rates, tolerance 0 on critical_topics, else 2 s."""
    values = {"cpu_ghz": 2.8, "cores": 4, "memory_mb": 4096, "alpha": 3.5,
              "technology": "802.11g", "max_bandwidth_mbps": 54, "pinned": "robot",
              "package": "my_pkg", "type": "tool", "freq_opt": 1, "tolerance": 2}

    def fill(tree, **overrides):
        for key, value in list(tree.items()):
            if isinstance(value, dict):
                fill(value)
            elif value == "TODO":
                tree[key] = overrides.get(key, values.get(key, 5))
    for entry in model["scales"]:
        fill(entry)
    for entry in model["nodes"]:
        fill(entry, memory_mb=60)
    fill(model["network"])
    for c in model["connections"]:
        fill(c, freq_min=min(1, c["freq_opt"]) if c["freq_opt"] != "TODO" else 1,
             tolerance=0 if c["topic"] in critical_topics else 2)
    return model
