"""The evaluation lap by lap (evaluation_laps.py): lap windows from navigation's status, each
lap's time, bound, returns by kind (after a link loss, planned before a hole, other), worst
output gap per kind of move and violations; the share of the bound's gain against the
baseline's same lap; the table and CSV. And the record's kinds of move, which tell a link-loss
return from a planned one."""
import csv
import math
import os

import pytest

from anyscale_testbed.evaluation_laps import (LapFigures, lap_figures, lap_rows, lap_share,
                                              lap_windows, write_lap_report)
from anyscale_testbed.evaluation_figures import RunFigures
from anyscale_testbed.testbed_figures import format_summary, tolerance_violations
from anyscale_testbed.testbed_record import (LINK_AHEAD_RETURN, LINK_LOSS_RETURN, MOVE_OUT,
                                             OTHER_RETURN, EventRecord, TestbedRecord,
                                             kind_of_move)
from anyscale_testbed.tolerance_report import RunRow

AMCL_MBPS = 0.22


def move(t, kind, node, reason, to="laptop"):
    source = "robot" if kind == "migrate" else "laptop"
    target = "laptop" if kind == "migrate" else "robot"
    return EventRecord(t, kind, node, source, target, reason, 0.4, True, t)


def two_laps():
    """Lap 1 from 10 to 60 s (4 goals of 8), lap 2 to 110 s; AMCL's pose at 5 Hz with a 1.4 s
    gap after a link-loss return at 30 s, 0.4 s after a planned one at 75 s, and 3 s of silence
    from 95 s (a violation of its 2 s)."""
    times = [round(0.1 * k, 1) for k in range(1201)]
    silent = ((29.9, 31.2), (74.9, 75.2), (95.0, 98.0))
    amcl = [round(0.2 * k, 1) for k in range(601)]
    amcl = [t for t in amcl if not any(a < t < b for a, b in silent)]
    rec = TestbedRecord(
        world="small_loop", link="coverage", finished_t=120.0,
        truth=[(t, 0.3 * t, 0.0) for t in times], bandwidth=[(0.0, 10.0)],
        mappings=[(5.0, {"amcl": "robot"}, 0.0, 0.0)],
        navigation_status=[(10.0, "drive 0/8"), (35.0, "wait_marker 2/8"), (60.0, "drive 4/8"),
                           (110.0, "done 8/8")],
        events=[move(20.0, "migrate", "amcl", "laptop can take it"),
                move(30.0, "migrate_back", "amcl", "link to laptop down"),
                move(40.0, "migrate", "amcl", "laptop can take it"),
                move(65.0, "migrate", "amcl", "laptop can take it; link ahead carries it 14 s"),
                move(75.0, "migrate_back", "amcl", "link ahead: 0.0 Mbit/s in 2.8 s"),
                move(90.0, "migrate_back", "ar_recognition",
                     "bandwidth 4.5 Mbit/s, below weak_link_mbps 5.5: home before the link is "
                     "lost")],
        receipts={"/amcl_pose": amcl}, outputs={"amcl": "/amcl_pose"},
        tolerances={"/amcl_pose": 2.0})
    rec.violations = tolerance_violations(rec)
    return rec


def test_each_move_is_told_apart_by_its_reason():
    rec = two_laps()
    assert [kind_of_move(e) for e in rec.events] == [
        MOVE_OUT, LINK_LOSS_RETURN, MOVE_OUT, MOVE_OUT, LINK_AHEAD_RETURN, OTHER_RETURN]
    assert kind_of_move(EventRecord(0, "start", "amcl", "", "robot", "", 0, True, 0)) == ""
    assert "returns: 1 after a link loss, 1 planned before a hole (link ahead), 1 other " \
           "planned" in format_summary(rec, rec.outputs, rec.tolerances)


def test_laps_end_when_their_share_of_the_goals_is_done():
    rec = two_laps()
    assert lap_windows(rec, 2) == [(10.0, 60.0), (60.0, 110.0)]
    assert lap_windows(rec, 1) == [(10.0, 110.0)]
    assert lap_windows(rec, 3)[0][0] == 10.0 and all(math.isnan(e) for _, e in
                                                     lap_windows(rec, 3))   # 8 goals: not 3 laps
    rec.navigation_status = rec.navigation_status[:3]                      # lap 2 not done
    assert lap_windows(rec, 2)[0] == (10.0, 60.0) and math.isnan(lap_windows(rec, 2)[1][1])
    assert lap_windows(TestbedRecord(), 2) == []


def test_each_lap_has_its_time_bound_returns_gaps_and_violations():
    first, second = lap_figures(two_laps(), 2, AMCL_MBPS)
    assert (first.lap, first.time_s, second.time_s) == (1, 50.0, 50.0)
    assert math.isfinite(first.bound_time_s) and first.bound_time_s <= 50.0
    assert first.returns == {LINK_LOSS_RETURN: 1, LINK_AHEAD_RETURN: 0, OTHER_RETURN: 0}
    assert second.returns == {LINK_LOSS_RETURN: 0, LINK_AHEAD_RETURN: 1, OTHER_RETURN: 1}
    assert second.amcl_returns == {LINK_LOSS_RETURN: 0, LINK_AHEAD_RETURN: 1, OTHER_RETURN: 0}
    assert first.worst_gap_s[LINK_LOSS_RETURN] == pytest.approx(1.4)
    assert second.worst_gap_s[LINK_AHEAD_RETURN] == pytest.approx(0.4)
    assert math.isnan(first.worst_gap_s[LINK_AHEAD_RETURN])
    assert (first.violations, second.violations) == (0, 1)


def test_the_share_of_the_bounds_gain_is_against_the_baselines_same_lap():
    lap = LapFigures(2, 80.0, 60.0)
    assert lap_share(lap, 100.0) == pytest.approx(0.5)        # 20 of the 40 s reachable
    assert math.isnan(lap_share(lap, 60.0))                   # nothing to reach
    assert math.isnan(lap_share(LapFigures(2, math.nan, 60.0), 100.0))
    base = [LapFigures(1, 100.0, math.nan), LapFigures(2, 90.0, math.nan)]
    other = [LapFigures(1, 120.0, math.nan), LapFigures(2, 110.0, math.nan)]
    test = [LapFigures(1, 95.0, 80.0), LapFigures(2, 85.0, 70.0)]
    rows = lap_rows([("b1", "baseline", 1, base), ("b2", "baseline", 2, other),
                     ("t1", "paper", 1, test), ("t3", "paper", 3, test)])
    assert [(r.run, r.figures.lap, r.baseline_s) for r in rows] == [
        ("t1", 1, 100.0), ("t1", 2, 90.0), ("t3", 1, 110.0), ("t3", 2, 100.0)]


def test_the_lap_table_is_appended_to_the_evaluation_and_written_as_csv(tmp_path):
    rec = two_laps()
    laps = lap_figures(rec, 2, AMCL_MBPS)
    base = RunFigures("base", "baseline", 0, RunRow(0, 0, 0), pair=1,
                      laps=[LapFigures(1, 70.0, math.nan), LapFigures(2, 70.0, math.nan)])
    test = RunFigures("pair 1: AnyScale", "paper", 1, RunRow(0, 0, 0), pair=1, laps=laps)
    for name in ("evaluation.txt", "evaluation.md"):
        (tmp_path / name).write_text("the table\n")
    lines = write_lap_report(str(tmp_path), [base, test])
    assert any(line.split()[:4] == ["pair", "1:", "AnyScale", "2"] for line in lines), lines
    assert (tmp_path / "evaluation.txt").read_text().startswith("the table\n\nlap by lap")
    assert "## Lap by lap" in (tmp_path / "evaluation.md").read_text()
    with open(tmp_path / "evaluation_laps.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["lap"], r["time_s"], r["baseline_lap_s"]) for r in rows] == [
        ("1", "50.0000", "70.0000"), ("2", "50.0000", "70.0000")]
    assert rows[0][f"returns {LINK_LOSS_RETURN}"] == "1"
    assert rows[1][f"amcl_returns {LINK_AHEAD_RETURN}"] == "1"
    assert rows[1]["violations"] == "1"
    assert write_lap_report(str(tmp_path / "none"), [RunFigures("x", "paper", 1,
                                                                RunRow(0, 0, 0))]) == []
    assert not os.path.exists(tmp_path / "none")
