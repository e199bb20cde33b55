"""The test-bed record's figures: gaps around a move, reaction to a link loss, link changes."""
import math

import pytest

from anyscale_core.testbed_record import (EventRecord, TestbedRecord, first_after, format_summary,
                                          gap_during, link_transitions, longest_gap, move_figures,
                                          reaction_s)


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
    text = format_summary(rec, {"amcl": "/amcl_pose"}, {"/amcl_pose": 2.0})
    assert "migrations: 1 out, 1 back, 0 failed" in text
    assert "restarted amcl at t=30.0 s: signal 11 on laptop" in text
