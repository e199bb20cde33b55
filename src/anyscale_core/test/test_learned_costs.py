"""What the decision node learned, written back: its learned-costs file read again, and
`anyscale profile MODEL --from-run FILE` putting the figures into the model's cpu_usage in
place (every other byte kept), skipping what was learned from too few reports, writing a need
above the scale's capacity as 100, and refusing bad input with one line and exit status 2."""
import datetime
import json
import math
import shutil

import pytest

from anyscale_core.cli import main
from anyscale_core.cost_estimate import CostRow
from anyscale_core.learned_costs import FILE_NAME, dump_learned, load_learned
from anyscale_core.model_loader import load_model

WHEN = datetime.datetime(2026, 11, 29, 10, 3, 12)
ROWS = [CostRow("amcl", "laptop", 36.0, 152.34, 152.34, 40, True, 0.9),
        CostRow("amcl", "robot", 50.0, 50.0, 22.5, 300, False, 0.34),
        CostRow("ar_recognition", "laptop", 12.0, 12.0, 37.0, 4, False, 0.9),
        CostRow("ar_recognition", "robot", 33.0, 33.0, math.nan, 0, False, math.nan)]


@pytest.fixture
def learned(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / FILE_NAME).write_text(dump_learned(ROWS, "/m/testbed.yaml", WHEN))
    return run


@pytest.fixture
def model(testbed_path, tmp_path):
    path = tmp_path / "testbed.yaml"
    shutil.copy(testbed_path, path)
    return path


def test_the_file_keeps_what_was_learned(learned):
    written, costs = load_learned(str(learned / FILE_NAME))
    assert written == "2026-11-29T10:03:12"
    assert [(c.node, c.scale, c.measured_percent, c.samples, c.lower_bound, c.capacity_cores)
            for c in costs] == [("amcl", "laptop", 152.34, 40, True, 0.9),
                                ("amcl", "robot", 22.5, 300, False, 0.34),
                                ("ar_recognition", "laptop", 37.0, 4, False, 0.9)]
    assert (learned / FILE_NAME).read_text().startswith("# CPU costs the AnyScale decision")


def test_from_run_writes_cpu_usage_in_place(model, learned, capsys):
    before = model.read_text()
    assert main(["profile", str(model), "--from-run", str(learned)]) == 0
    out = capsys.readouterr()
    after = model.read_text()
    m = load_model(str(model))
    assert m.node("amcl").cpu_usage == {"robot": 22.5, "laptop": 100.0}
    assert m.node("ar_recognition").cpu_usage == {"robot": 33, "laptop": 12}   # 4 samples
    assert "at least 152.3 % learned from 40 reports on a saturated scale; more than the " \
           "scale has, written as the model's most, 100 %" in out.out
    assert "4 samples, fewer than 10" in out.out
    assert "cpu_usage written for 2 node and scale pairs" in out.err
    # Only the figures and amcl's comment block changed.
    changed = [line for line in after.splitlines() if line not in before.splitlines()]
    assert all(line.lstrip().startswith(("# profile:", "cpu_usage: {robot: 22.5, laptop: 100}"))
               for line in changed), changed
    assert "--from-run" in after and "the model said 36" in after
    # A second run replaces its block rather than adding one.
    assert main(["profile", str(model), "--from-run", str(learned / FILE_NAME)]) == 0
    assert model.read_text().count("by `anyscale profile --from-run") == 1


def test_from_run_dry_run_json_and_filters(model, learned, capsys):
    before = model.read_text()
    assert main(["profile", str(model), "--from-run", str(learned), "--dry-run", "--json",
                 "--nodes", "ar_recognition", "--min-samples", "3"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert model.read_text() == before and result["written"] is False
    assert [(c["node"], c["scale"], c["cpu_usage"]) for c in result["costs"]] == \
        [("ar_recognition", "laptop", 37.0)]


@pytest.mark.parametrize("content,message", [
    (None, "no learned-costs file there"),
    ("costs: 3\n", "costs: expected a learned-costs file"),
    ("costs: [{node: amcl, scale: laptop, model_percent: 36, measured_percent: -1, "
     "samples: 3, lower_bound: false}]\n", "costs[0].measured_percent: missing or invalid"),
    ("costs: [{node: amcl, scale: laptop, model_percent: 36, measured_percent: 40, "
     "samples: many, lower_bound: false}]\n", "costs[0].samples: missing or invalid"),
    ("costs: [\n", "invalid YAML"),
])
def test_bad_learned_files_are_one_line_and_exit_2(model, tmp_path, capsys, content, message):
    path = tmp_path / "learned.yaml"
    if content is not None:
        path.write_text(content)
    assert main(["profile", str(model), "--from-run", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("anyscale profile: error: ") and message in err[0]


def test_bad_options_of_from_run_exit_2(model, learned, capsys):
    assert main(["profile", str(model), "--from-run", str(learned), "--min-samples", "0"]) == 2
    assert main(["profile", str(model), "--from-run", str(learned), "--nodes", "amlc"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "--min-samples: expected a count >= 1, got 0" in err[0]
    assert "--nodes: not in" in err[1] and "amlc" in err[1]


def test_names_the_model_lacks_are_skipped_saying_so(model, tmp_path, capsys):
    path = tmp_path / "learned.yaml"
    path.write_text(dump_learned([CostRow("lidar", "laptop", 5, 5, 7, 50, False, 0.9),
                                  CostRow("laser", "laptop", 4, 4, 9, 50, False, 0.9)],
                                 "/m.yaml", WHEN))
    before = model.read_text()
    assert main(["profile", str(model), "--from-run", str(path)]) == 0
    out = capsys.readouterr()
    assert "no node lidar in" in out.out and "laser has no cpu_usage for laptop" in out.out
    assert "nothing learned enough to write" in out.err and model.read_text() == before
