"""The tolerance bench's rows, table, CSV and Markdown, from synthetic test-bed records."""
import csv
import math

from anyscale_testbed.testbed_figures import tolerance_violations
from anyscale_testbed.testbed_record import EventRecord, TestbedRecord
from anyscale_testbed.tolerance_report import (format_markdown, format_table, path_time,
                                               rate_all_on_one_scale, run_row, write_csv)


def ticks(start, end, period=0.2):
    return [round(start + i * period, 3) for i in range(int(round((end - start) / period)) + 1)]


def move(decided_t, kind="migrate", node="amcl", reason="laptop can take it"):
    return EventRecord(t=decided_t + 1.0, kind=kind, node=node, from_scale="robot",
                       to_scale="laptop", reason=reason, duration_s=1.0, success=True,
                       decided_t=decided_t)


def record(amcl_times, events=(), done_t=300.0):
    rec = TestbedRecord(
        events=list(events), finished_t=310.0,
        receipts={"/amcl_pose": amcl_times, "/ar_markers": ticks(12.0, 310.0, 0.1)},
        bandwidth=[(0.0, 10.0), (100.0, 0.0), (101.0, 10.0)],
        navigation_status=[(15.0, "drive 0/5"), (80.0, "drive 1/5")]
        + ([(done_t, "done 5/5")] if done_t else []),
        outputs={"amcl": "/amcl_pose", "ar_recognition": "/ar_markers"},
        tolerances={"/amcl_pose": 2.0, "/ar_markers": 1.0})
    rec.violations = tolerance_violations(rec)      # as the monitor keeps them
    return rec


def two_runs():
    clean = record(ticks(10.0, 310.0), [move(50.0), move(100.2, "migrate_back")])
    broken = record(ticks(10.0, 100.0) + ticks(103.5, 310.0),
                    [move(100.2, "migrate_back", reason="link to laptop down"),
                     move(120.0, "restart")], done_t=None)
    return [run_row(1, 0, 0, clean, seed=11), run_row(2, 1, 0, broken, seed=12),
            run_row(3, 2, 1, None, seed=13)]


def test_a_row_has_the_run_figures_and_the_record_violations():
    clean, broken, failed = two_runs()
    assert clean.path_time_s == 285.0 and clean.migrations == 2 and clean.restarts == 0
    assert clean.longest_s["/amcl_pose"] < 0.3 and clean.violations == []
    assert math.isnan(broken.path_time_s) and broken.note == "the loop was not completed"
    assert broken.migrations == 1 and broken.restarts == 1
    assert broken.longest_s["/amcl_pose"] == 3.5
    (v,) = broken.violations
    assert (v.topic, v.start_t, v.end_t, v.tolerance_s) == ("/amcl_pose", 100.0, 103.5, 2.0)
    assert "link down at t=100.0 s" in v.cause
    assert failed.note == "no record" and failed.exit_code == 1


def test_path_time_is_first_status_to_done():
    assert path_time(record(ticks(10.0, 20.0), done_t=200.0)) == 185.0
    assert math.isnan(path_time(TestbedRecord()))


def test_the_table_flags_each_violation_with_its_cause_and_ends_with_a_total():
    text = format_table(two_runs())
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["run", "start", "goal"]
    assert "3.50/2 s !" in lines[2] and "0.20/2 s" in lines[1]
    assert [line for line in lines if line.startswith("VIOLATION")] == [
        "VIOLATION run 2: /amcl_pose silent 3.50 s > tolerance 2 s from t=100.0 s: link down at "
        "t=100.0 s; migrate_back amcl robot -> laptop at t=100.2 s (link to laptop down); link "
        "back at t=101.0 s"]
    assert lines[-1] == ("total: 3 runs, 1 violations in 1 runs, 1 loops done (median path "
                         "time 285 s), 3 migrations, 1 restarts")


def test_csv_and_markdown_copies(tmp_path):
    rows = two_runs()
    write_csv(str(tmp_path / "t.csv"), rows)
    with open(tmp_path / "t.csv") as f:
        read = list(csv.DictReader(f))
    assert [r["violations"] for r in read] == ["0", "1", "0"]
    assert [r["seed"] for r in read] == ["11", "12", "13"]
    assert read[1]["longest_silence_s /amcl_pose"] == "3.500"
    assert read[1]["tolerance_s /ar_markers"] == "1.000"
    assert read[1]["violation_details"].startswith("run 2: /amcl_pose silent 3.50 s")
    assert read[2]["path_time_s"] == "" and read[2]["note"] == "no record"
    md = format_markdown(rows, "Tolerance bench")
    assert md.startswith("# Tolerance bench\n\n| run | start goal |")
    assert "| 2 | 1 | 12 | 0 | - | 1 | 1 | 3.50/2 s ! |" in md
    assert "- run 2: /amcl_pose silent 3.50 s" in md
    assert md.rstrip().endswith("1 restarts")


def test_the_rate_with_every_node_on_one_scale_skips_each_spans_settling_and_short_spans():
    home = {"amcl": "robot", "laser": "robot"}
    out = {"amcl": "laptop", "laser": "robot"}
    rec = TestbedRecord(mappings=[(0.0, home, 0, 0), (100.0, out, 0, 0), (200.0, home, 0, 0),
                                  (205.0, out, 0, 0), (300.0, home, 0, 0)],
                        receipts={"/amcl_pose": ticks(0.0, 100.0, 0.5) + ticks(100.0, 200.0, 0.2)
                                  + ticks(200.0, 400.0, 0.5)})
    # At home 5-100 s (2 Hz) and 305-400 s (2 Hz); 200-205 s is too short; out is 5 Hz.
    assert abs(rate_all_on_one_scale(rec, "/amcl_pose", 400.0) - 2.0) < 0.02
    assert math.isnan(rate_all_on_one_scale(TestbedRecord(), "/amcl_pose", 10.0))


def test_a_row_gives_the_home_rate_and_the_host_speed_of_a_normalised_run(tmp_path):
    rec = record(ticks(10.0, 310.0))
    rec.mappings = [(5.0, {"amcl": "robot"}, 0, 0)]      # home from 10 s, its first pose
    rec.cpu_normalisation = [(5.0, 0.34, 0.9, 14.0), (10.0, 0.36, 0.9, 15.0),
                             (15.0, 0.35, 0.9, 16.0)]
    row = run_row(1, 0, 0, rec, seed=11)
    assert abs(row.home_hz["/amcl_pose"] - 5.0) < 0.05 and row.host_ms == 15.0
    line = format_table([row]).splitlines()[1]
    assert "5.00" in line and "15.0" in line
    write_csv(str(tmp_path / "t.csv"), [row])
    with open(tmp_path / "t.csv") as f:
        (read,) = list(csv.DictReader(f))
    assert read["host_ms"] == "15.000" and read["hz_all_on_one_scale /amcl_pose"].startswith("5.0")
