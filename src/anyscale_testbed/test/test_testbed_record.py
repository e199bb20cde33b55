"""The test-bed record's figures: gaps around a move, reaction to a link loss, link changes,
silences longer than a connection's tolerance."""
import json
import math

import pytest

from anyscale_testbed.testbed_figures import (colour_violations, first_after, format_summary,
                                              gap_during, link_transitions, longest_gap,
                                              move_figures, reaction_s, tolerance_violations)
from anyscale_testbed.testbed_record import EventRecord, TestbedRecord, store_cpu_normalisation


def event(decided_t, duration_s=0.5, kind="migrate", reason="laptop can take it"):
    return EventRecord(t=decided_t + duration_s, kind=kind, node="amcl", from_scale="robot",
                       to_scale="laptop", reason=reason, duration_s=duration_s, success=True,
                       decided_t=decided_t)


def test_gap_during_spans_from_the_last_message_before_to_the_first_after():
    times = [9.6, 9.8, 10.0, 11.4, 11.6]
    assert gap_during(times, 10.1, 11.0) == pytest.approx(1.4)
    assert gap_during(times, 10.1, 20.0) == math.inf          # never spoke after the window
    assert longest_gap(times, 9.6, 12.0) == pytest.approx(1.4)


def test_first_after_and_the_reaction_ignore_what_came_before():
    times = [9.9, 10.02, 10.9, 11.1]
    assert first_after(times, 10.0) == pytest.approx(0.02)
    # Link down at 10.0, decided at 10.05: the message at 10.02 was the laptop's, in flight.
    assert reaction_s(times, 10.0, 10.05) == pytest.approx(0.9)
    assert reaction_s(times, 10.0, 12.0) == math.inf


def test_a_move_the_run_did_not_see_to_its_end_has_no_gap():
    rec = TestbedRecord(events=[event(10.0), event(40.0)], finished_t=42.0,
                        receipts={"/amcl_pose": [9.8, 11.2, 11.6, 12.4, 13.2, 13.8, 39.9, 41.0]})
    early, late = move_figures(rec, {"amcl": "/amcl_pose"})
    assert early.output_gap_s == pytest.approx(1.4)
    assert early.first_output_s == pytest.approx(1.2)
    assert math.isnan(late.output_gap_s)            # window to 43.5 s, the run ended at 42 s
    assert late.first_output_s == pytest.approx(1.0)


def test_link_transitions_are_the_changes_between_up_and_down():
    bandwidth = [(0.0, 27.0), (5.0, 3.0), (10.0, 0.0), (10.2, 0.0), (16.0, 27.0)]
    assert link_transitions(bandwidth) == [(10.0, False), (16.0, True)]


def test_the_summary_counts_the_moves_and_names_each_restart():
    rec = TestbedRecord(events=[event(10.0), event(20.0, kind="migrate_back", reason="link down"),
                                event(30.0, kind="restart", reason="signal 11 on laptop")],
                        finished_t=42.0, receipts={"/amcl_pose": [9.8, 11.2, 20.9, 30.8]})
    rec.senders = {"/amcl_pose": [(9.8, "/amcl"), (11.2, "/amcl_laptop"), (20.9, "/amcl")]}
    text = format_summary(rec, {"amcl": "/amcl_pose"}, {"/amcl_pose": 2.0})
    assert "migrations: 1 out, 1 back, 0 failed" in text
    assert "restarted amcl at t=30.0 s: signal 11 on laptop" in text
    # The move out: the handover is the silence from 9.8 s to the laptop's first message at
    # 11.2 s; its output gap, the longest in its window, the one from 11.2 to 20.9 s.
    row = next(line for line in text.splitlines() if line.strip().startswith("10.0"))
    assert row.split()[7:11] == ["9.70", "s", "1.40", "s"], row


def ticks(start, end, period=0.2):
    """Receive times every `period` s from start to end."""
    return [round(start + i * period, 3) for i in range(int(round((end - start) / period)) + 1)]


def issue_12_run():
    """The run of issue 12: the link drops at 72.9 s, AMCL is brought home and its instance is
    lost; it moves out again at 82.9 s and the first pose comes at 85.4 s. AR recognition's
    return after a link loss at 195.7 s takes 2.46 s. The record ends at 220 s."""
    back = EventRecord(t=74.0, kind="migrate_back", node="amcl", from_scale="laptop",
                       to_scale="robot", reason="link to laptop down", duration_s=1.05,
                       success=True, decided_t=72.95)
    events = [back, event(82.9, 0.8, reason="laptop can take it"),
              EventRecord(t=198.0, kind="migrate_back", node="ar_recognition",
                          from_scale="laptop", to_scale="robot", reason="link to laptop down",
                          duration_s=2.21, success=True, decided_t=195.75)]
    return TestbedRecord(
        events=events, finished_t=220.0,
        bandwidth=[(0.0, 12.0), (72.9, 0.0), (73.3, 8.0), (195.7, 0.0), (199.0, 6.0)],
        receipts={"/amcl_pose": ticks(10.0, 72.8) + ticks(85.4, 130.0) + ticks(131.5, 220.0),
                  "/ar_markers": ticks(10.0, 195.6, 0.1) + ticks(198.06, 220.0, 0.1)},
        outputs={"amcl": "/amcl_pose", "ar_recognition": "/ar_markers"},
        tolerances={"/amcl_pose": 2.0, "/ar_markers": 1.0})


def test_a_silence_counts_as_the_output_gap_of_one_move_only():
    back, out = move_figures(issue_12_run(), {"amcl": "/amcl_pose"})
    assert back.output_gap_s == pytest.approx(12.6)
    assert math.isnan(back.silent_since_t)
    # Decided while the output was still silent: that silence is the move back's, not its own.
    assert math.isnan(out.output_gap_s)
    assert out.silent_since_t == pytest.approx(72.8)
    assert out.first_output_s == pytest.approx(2.5)


def test_a_silence_that_began_well_before_a_move_is_not_its_gap():
    rec = TestbedRecord(events=[event(50.0)], finished_t=70.0,
                        receipts={"/amcl_pose": ticks(10.0, 40.0) + ticks(52.0, 70.0)})
    (move,) = move_figures(rec, {"amcl": "/amcl_pose"})
    assert math.isnan(move.output_gap_s) and move.silent_since_t == pytest.approx(40.0)


def test_violations_are_the_silences_longer_than_the_tolerance_with_their_cause():
    found = tolerance_violations(issue_12_run())
    assert [(v.topic, v.start_t, v.end_t, v.tolerance_s) for v in found] == [
        ("/amcl_pose", 72.8, 85.4, 2.0), ("/ar_markers", 195.6, 198.06, 1.0)]
    amcl, ar = found
    assert amcl.silence_s == pytest.approx(12.6)
    assert amcl.cause == ("link down at t=72.9 s; migrate_back amcl laptop -> robot at t=73.0 s "
                          "(link to laptop down); link back at t=73.3 s; migrate amcl robot -> "
                          "laptop at t=82.9 s (laptop can take it)")
    assert ar.silence_s == pytest.approx(2.46)
    assert "link down at t=195.7 s" in ar.cause and "migrate_back ar_recognition" in ar.cause
    # The 1.5 s silence of /amcl_pose at 130 s is within its 2 s.
    assert not [v for v in found if 129.0 < v.start_t < 132.0]


def test_a_silence_to_the_end_of_the_run_is_a_violation_and_critical_topics_have_none():
    rec = TestbedRecord(finished_t=30.0, receipts={"/amcl_pose": ticks(5.0, 20.0),
                                                   "/odom": ticks(5.0, 10.0)},
                        outputs={"amcl": "/amcl_pose"},
                        tolerances={"/amcl_pose": 2.0, "/odom": 0.0})
    (v,) = tolerance_violations(rec)
    assert (v.topic, v.start_t, v.end_t) == ("/amcl_pose", 20.0, 30.0)
    assert v.cause == "no move, restart or link change of amcl; silent until the run ended"


def test_the_record_keeps_its_violations(tmp_path):
    rec = issue_12_run()
    rec.violations = tolerance_violations(rec)
    rec.save(str(tmp_path / "record.json"))
    loaded = TestbedRecord.load(str(tmp_path / "record.json"))
    assert loaded.violations == rec.violations
    assert loaded.tolerances == {"/amcl_pose": 2.0, "/ar_markers": 1.0}


def test_the_quotas_history_survives_a_round_trip_and_old_records_load_without_it(tmp_path):
    path = str(tmp_path / "record.json")
    rec = issue_12_run()
    rec.cpu_normalisation = [(0.0, 0.34, 0.9, 15.5), (5.0, 0.36, 0.95, 16.4)]
    rec.reference_cpu_ms = 15.5
    rec.save(path)
    loaded = TestbedRecord.load(path)
    assert loaded.cpu_normalisation == [(0.0, 0.34, 0.9, 15.5), (5.0, 0.36, 0.95, 16.4)]
    assert loaded.reference_cpu_ms == 15.5
    # A record written before the field existed.
    with open(path) as f:
        old = json.load(f)
    del old["cpu_normalisation"], old["reference_cpu_ms"]
    with open(path, "w") as f:
        json.dump(old, f)
    loaded = TestbedRecord.load(path)
    assert loaded.cpu_normalisation == [] and loaded.reference_cpu_ms is None
    assert loaded.tolerances == {"/amcl_pose": 2.0, "/ar_markers": 1.0}


def test_the_quotas_history_is_stored_on_the_records_clock(tmp_path):
    path = str(tmp_path / "record.json")
    TestbedRecord(started_wall=1000.0, world="office_floor").save(path)
    store_cpu_normalisation(path, [(998.0, 0.34, 0.9, 15.5), (1005.0, 0.36, 0.95, 16.4)], 15.5)
    loaded = TestbedRecord.load(path)
    assert loaded.cpu_normalisation == [(-2.0, 0.34, 0.9, 15.5), (5.0, 0.36, 0.95, 16.4)]
    assert loaded.reference_cpu_ms == 15.5 and loaded.world == "office_floor"
    assert not (tmp_path / "record.json.tmp").exists()


def test_the_end_table_flags_each_violation_in_plain_words_and_red_on_a_terminal():
    rec = issue_12_run()
    text = format_summary(rec, rec.outputs, rec.tolerances)
    assert "\033[" not in text                      # a log file gets plain text
    assert "silences longer than their tolerance: 2" in text
    flagged = [line for line in text.splitlines() if "VIOLATION" in line]
    assert len(flagged) == 2
    assert "VIOLATION /amcl_pose: silent 12.60 s > tolerance 2 s from t=72.8 to 85.4 s: link " \
        "down at t=72.9 s" in flagged[0]
    assert "output silent since t=72.8 s, before this move" in text
    # The 12.60 s silence is the gap of one move, not of two.
    assert sum("12.60 s" in line for line in text.splitlines() if "amcl  " in line) == 1
    assert colour_violations(flagged[0], terminal=True) == f"\033[31m{flagged[0]}\033[0m"
    assert colour_violations(flagged[0], terminal=False) == flagged[0]
    assert colour_violations("migrations: 1 out", terminal=True) == "migrations: 1 out"


def test_a_silence_at_home_names_the_longest_gap_of_each_recorded_input():
    rec = TestbedRecord(finished_t=40.0, outputs={"amcl": "/amcl_pose"},
                        tolerances={"/amcl_pose": 2.0}, inputs=["/scan", "/odom"],
                        receipts={"/amcl_pose": ticks(5.0, 20.0) + ticks(23.0, 40.0),
                                  "/scan": ticks(5.0, 40.0),
                                  "/odom": ticks(5.0, 20.4) + ticks(21.8, 40.0)})
    (v,) = tolerance_violations(rec)
    assert v.cause.startswith("no move, restart or link change of amcl; ")
    # The scan kept coming (every 0.2 s); odometry stopped for 1.4 s from t=20.4 s.
    assert v.cause.endswith("longest input gaps at the monitor: /scan 0.20 s, "
                            "/odom 1.40 s from t=20.4 s")


def test_a_silence_names_how_busy_the_scale_that_ran_the_node_was(tmp_path):
    # AR at home and nothing moving, /ar_markers silent 1.09 s (the tolerance bench of
    # 2026-11-27, run 1, t=345.3 s): was the robot at its quota? The laptop's load is no answer.
    home = {"ar_recognition": "robot"}
    rec = TestbedRecord(finished_t=40.0, outputs={"ar_recognition": "/ar_markers"},
                        tolerances={"/ar_markers": 1.0}, mappings=[(0.0, home, 125.0, 0.0)],
                        receipts={"/ar_markers": ticks(5.0, 20.0) + ticks(21.2, 40.0)},
                        scale_cpu={"robot": [(19.5, 40.0), (20.2, 97.0), (20.7, 99.0),
                                             (21.3, 50.0)],
                                   "laptop": [(20.5, 10.0)]})
    (v,) = tolerance_violations(rec)
    assert v.cause == ("no move, restart or link change of ar_recognition; /ar_markers at "
                       "5.0 Hz on the robot in the 10 s before; robot CPU 98 % busy over the "
                       "silence (at its limit)")
    rec.scale_cpu["robot"] = [(20.5, 60.0)]
    (v,) = tolerance_violations(rec)
    assert v.cause.endswith("; robot CPU 60 % busy over the silence")
    # A node that moved in the 10 s before: its rate there says nothing of either scale.
    rec.mappings.append((15.0, {"ar_recognition": "laptop"}, 201.0, 0.0))
    rec.mappings.append((18.0, home, 125.0, 0.0))
    (v,) = tolerance_violations(rec)
    assert " Hz on the " not in v.cause
    # AMCL coming home as AR fell silent (run 7, t=351.7 s): its start loads the robot. A move
    # to the laptop does not, and is not named.
    rec.mappings = [(0.0, home, 125.0, 0.0)]
    rec.events = [EventRecord(19.6, "migrate_back", "amcl", "laptop", "robot",
                              "link to laptop down", 0.4, True, 19.2),
                  EventRecord(20.5, "migrate", "navigation", "robot", "laptop", "x", 0.4, True,
                              20.1)]
    (v,) = tolerance_violations(rec)
    assert v.cause.startswith("no move, restart or link change of ar_recognition; migrate_back "
                              "amcl laptop -> robot at t=19.2 s, starting on the robot as "
                              "ar_recognition fell silent; /ar_markers at 5.0 Hz")
    assert "navigation" not in v.cause
    path = str(tmp_path / "record.json")
    rec.save(path)
    assert TestbedRecord.load(path).scale_cpu == {"robot": [[20.5, 60.0]],
                                                  "laptop": [[20.5, 10.0]]}


def test_the_inputs_survive_a_round_trip_and_old_records_load_without_them(tmp_path):
    path = str(tmp_path / "record.json")
    TestbedRecord(inputs=["/scan"], receipts={"/scan": [1.0]}).save(path)
    assert TestbedRecord.load(path).inputs == ["/scan"]
    with open(path) as f:
        d = json.load(f)
    del d["inputs"]
    with open(path, "w") as f:
        json.dump(d, f)
    assert TestbedRecord.load(path).inputs == []


def start(node, done_t):
    return EventRecord(t=done_t, kind="start", node=node, from_scale="", to_scale="robot",
                       reason="initial configuration", duration_s=done_t - 5.0, success=True,
                       decided_t=5.0)


def test_an_output_is_judged_once_the_subscribers_of_its_connection_run():
    """Tolerance bench, run 1: AR published from t=16 s, navigation (its only subscriber) ran
    from 25.9 s, and /ar_markers was silent 1.1 s at 17 s while the node set came up."""
    markers = ticks(16.0, 17.0, 0.2) + ticks(18.1, 30.0, 0.2) + ticks(31.5, 40.0, 0.2)
    rec = TestbedRecord(events=[start("ar_recognition", 6.9), start("navigation", 25.9)],
                        finished_t=40.0, receipts={"/ar_markers": markers},
                        outputs={"ar_recognition": "/ar_markers"},
                        tolerances={"/ar_markers": 1.0},
                        subscribers={"/ar_markers": ["navigation"]})
    found = tolerance_violations(rec)
    assert [(round(v.start_t, 1), round(v.silence_s, 1)) for v in found] == [(29.9, 1.6)]
    text = format_summary(rec, rec.outputs, rec.tolerances)
    assert "/ar_markers: longest silence 1.60 s (tolerance 1 s) once its subscribers ran" in text
    # A record without the subscribers (older) is judged from the first message, as before; so
    # is one whose subscriber AnyScale never started (the static pipeline).
    for older in (dict(subscribers={}), dict(events=[start("ar_recognition", 6.9)])):
        rec_old = TestbedRecord(**{**dict(events=rec.events, finished_t=40.0,
                                          receipts=rec.receipts, outputs=rec.outputs,
                                          tolerances=rec.tolerances,
                                          subscribers=rec.subscribers), **older})
        assert [round(v.start_t, 1) for v in tolerance_violations(rec_old)] == [17.0, 29.9]
    # A silence under way when navigation started counts from that moment: silent 25.0-28.0 s,
    # 2.1 s of it after 25.9 s.
    under_way = ticks(16.0, 25.0, 0.2) + ticks(28.0, 40.0, 0.2)
    rec_late = TestbedRecord(**{**rec.__dict__, "receipts": {"/ar_markers": under_way}})
    assert [(round(v.start_t, 1), round(v.silence_s, 1))
            for v in tolerance_violations(rec_late)] == [(25.9, 2.1)]


def test_the_summary_lists_the_models_cpu_figures_beside_the_live_estimates(tmp_path):
    rec = TestbedRecord(finished_t=300.0, cost_estimates=[
        {"node": "amcl", "scale": "laptop", "model_percent": 36.0, "live_percent": 98.4,
         "measured_percent": 152.3, "samples": 40, "lower_bound": True, "failures": 1},
        {"node": "amcl", "scale": "robot", "model_percent": 50.0, "live_percent": 50.0,
         "measured_percent": float("nan"), "samples": 0, "lower_bound": False, "failures": 0}])
    path = str(tmp_path / "record.json")
    rec.save(path)
    text = format_summary(TestbedRecord.load(path), {}, {})
    lines = text.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("CPU cost per node and scale"))
    assert lines[head + 1].split() == ["amcl", "laptop", "model", "36", "live", "98", "learned",
                                       "≥152", "from", "40", "reports;", "1", "return(s)", "for",
                                       "rate", "or", "CPU", "in", "a", "row"]
    assert lines[head + 2].split() == ["amcl", "robot", "model", "50", "live", "50", "not",
                                       "learned"]
    assert "CPU cost" not in format_summary(TestbedRecord(finished_t=1.0), {}, {})
