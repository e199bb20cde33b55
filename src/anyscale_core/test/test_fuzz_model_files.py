"""Fuzzing (hypothesis) of the files a user hands to `anyscale check` / `anyscale plan` and to the
decision node: every hostile model or state file ends in exit 2 and one error line, never a
traceback (issue 15, item 2)."""
import contextlib
import copy
import io
import math
import os
import subprocess
import sys
import tempfile

from hypothesis import given, settings, strategies as st
import pytest
import yaml

from anyscale_core.cli import main
from anyscale_core.decision_params import ParamError, prepare_decision
from anyscale_core.model import ModelError

from core_test_data import TESTBED

with open(TESTBED, "rb") as _f:
    TESTBED_BYTES = _f.read()
with open(TESTBED) as _f:
    TESTBED_TREE = yaml.safe_load(_f)

FUZZ = settings(max_examples=40, deadline=None)

# Values a hostile or careless file puts where a number, a name or a map belongs.
HOSTILE = st.one_of(
    st.none(), st.booleans(), st.just(math.nan), st.just(math.inf), st.just(-math.inf),
    st.just(1e308), st.just(10 ** 400), st.just(-10 ** 30), st.integers(-5, 5),
    st.text(max_size=12), st.just("\u202e\u0000\ud7ff nodé"), st.just(""),
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


def _write(data: bytes) -> str:
    fd, path = tempfile.mkstemp(suffix=".yaml", prefix="anyscale_fuzz_")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    return path


def _run_cli(argv):
    """main() as the script runs it; any exception escaping it is a traceback for the user."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _assert_clean(code, err, command):
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith(f"anyscale {command}: error: "), err
        assert "Traceback" not in err


def _check_model_bytes(data: bytes):
    path = _write(data)
    try:
        for command in ("check", "plan"):
            code, _, err = _run_cli([command, path])
            _assert_clean(code, err, command)
        try:
            prepare_decision(path, "paper")
        except (ModelError, ParamError) as e:
            assert str(e).startswith(path), e   # the decision node's FATAL line names the file
    finally:
        os.remove(path)


def _set_at(tree, path, value):
    node = tree
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value


def _paths(tree, prefix=()):
    """Every key path in the model tree: where a mutation can land."""
    if isinstance(tree, dict):
        items = tree.items()
    elif isinstance(tree, list):
        items = enumerate(tree)
    else:
        return []
    out = []
    for k, v in items:
        out.append(prefix + (k,))
        out.extend(_paths(v, prefix + (k,)))
    return out


MODEL_PATHS = _paths(TESTBED_TREE)


@FUZZ
@given(st.data())
def test_mutated_bytes_of_the_testbed_model(data):
    raw = bytearray(TESTBED_BYTES)
    for _ in range(data.draw(st.integers(1, 4))):
        pos = data.draw(st.integers(0, len(raw) - 1))
        raw[pos] = data.draw(st.integers(0, 255))
    if data.draw(st.booleans()):
        raw = raw[:data.draw(st.integers(0, len(raw)))]   # truncated
    _check_model_bytes(bytes(raw))


@FUZZ
@given(st.binary(max_size=300))
def test_random_bytes_as_model(raw):
    _check_model_bytes(raw)


@FUZZ
@given(st.sampled_from(MODEL_PATHS), HOSTILE)
def test_hostile_value_anywhere_in_the_model(path, value):
    tree = copy.deepcopy(TESTBED_TREE)
    _set_at(tree, path, value)
    _check_model_bytes(yaml.safe_dump(tree, allow_unicode=True).encode("utf-8"))


@pytest.mark.parametrize("edit", ["duplicate_node", "self_connection", "duplicate_scale",
                                  "deep_nesting", "alias_bomb", "huge_integer", "nul_byte",
                                  "params_alias_bomb", "params_null"])
def test_structural_attacks_on_the_model(edit):
    tree = copy.deepcopy(TESTBED_TREE)
    if edit == "duplicate_node":
        tree["nodes"].append(copy.deepcopy(tree["nodes"][0]))
    elif edit == "duplicate_scale":
        tree["scales"].append(copy.deepcopy(tree["scales"][0]))
    elif edit == "self_connection":
        c = tree["connections"][0]
        c["subscriber"] = c["publisher"]
    elif edit == "huge_integer":
        tree["connections"][0]["freq_min"] = 10 ** 400   # math.isfinite raised OverflowError
    elif edit == "params_alias_bomb":
        # 9**9 values behind a few aliases: passed `anyscale check`, and the agent expanded
        # them into parameters at every start of the node.
        bomb = ["x"] * 9
        for _ in range(8):
            bomb = [bomb] * 9
        tree["nodes"][9]["launch"]["params"] = {"bomb": bomb}
    elif edit == "params_null":
        tree["nodes"][9]["launch"]["params"] = {"empty": None}   # no ROS parameter is null
    if edit == "deep_nesting":
        text = b"nodes: " + b"[" * 20000 + b"]" * 20000 + b"\n"
    elif edit == "alias_bomb":
        text = b"a: &a [x, x, x, x, x, x, x, x, x]\n" + b"".join(
            b"%c: &%c [*%c, *%c, *%c, *%c, *%c, *%c, *%c, *%c, *%c]\n"
            % ((ord("b") + i, ord("b") + i) + (ord("a") + i,) * 9)
            for i in range(8)) + b"nodes: *i\n"
    elif edit == "nul_byte":
        text = TESTBED_BYTES.replace(b"robot", b"rob\x00t", 1)   # was a two-line message
    else:
        text = yaml.safe_dump(tree).encode()
    path = _write(text)
    try:
        for command in ("check", "plan"):
            code, _, err = _run_cli([command, path])
            assert code == 2, (edit, command, err)
            _assert_clean(code, err, command)
    finally:
        os.remove(path)


STATE_VALUES = st.one_of(HOSTILE, st.dictionaries(st.sampled_from(["robot", "laptop", "x"]),
                                                  HOSTILE, max_size=3))


@FUZZ
@given(st.dictionaries(st.sampled_from(["bandwidth_mbps", "scale_load", "link_up", "junk"]),
                       STATE_VALUES, max_size=3) | HOSTILE)
def test_hostile_state_files(state):
    path = _write(yaml.safe_dump(state, allow_unicode=True).encode("utf-8"))
    try:
        code, _, err = _run_cli(["plan", TESTBED, "--state", path])
        _assert_clean(code, err, "plan")
    finally:
        os.remove(path)


def test_huge_integer_in_a_state_file():
    path = _write(b"bandwidth_mbps: 1" + b"0" * 400 + b"\n")
    try:
        code, _, err = _run_cli(["plan", TESTBED, "--state", path])
        assert code == 2 and "bandwidth_mbps" in err, err
    finally:
        os.remove(path)


@FUZZ
@given(st.binary(max_size=200))
def test_random_bytes_as_state(raw):
    path = _write(raw)
    try:
        code, _, err = _run_cli(["plan", TESTBED, "--state", path])
        _assert_clean(code, err, "plan")
    finally:
        os.remove(path)


def test_script_on_a_model_that_is_not_utf8(tmp_path):
    """Issue 15's finding: 61 of 120 mutated models were not UTF-8 and ended in a traceback."""
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes(TESTBED_BYTES.replace(b"robot", b"rob\xf6t", 1))
    script = os.path.join(os.path.dirname(__file__), "..", "scripts", "anyscale")
    for command in ("check", "plan"):
        proc = subprocess.run([sys.executable, script, command, str(bad)], capture_output=True,
                              text=True, timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert str(bad) in proc.stderr and "UTF-8" in proc.stderr, proc.stderr
