"""move_gap_report on synthetic records: moves sorted by kind with their gaps, and the node's
own reference taken only where it ran at home with nothing moving nearby."""
import math

import pytest

from anyscale_testbed.move_gap_report import (LINK_LOSS, OUT, move_gap_lines, move_gaps,
                                              quiet_window_gaps)
from anyscale_testbed.testbed_record import EventRecord, TestbedRecord


def ticks(start, end, period):
    """Message times from start to end, every period."""
    return [round(start + period * k, 3) for k in range(int(round((end - start) / period)) + 1)]


def move(decided_t, kind="migrate", reason="laptop can take it", took=1.0):
    return EventRecord(t=decided_t + took, kind=kind, node="amcl", from_scale="robot",
                       to_scale="laptop" if kind == "migrate" else "robot", reason=reason,
                       duration_s=took, success=True, decided_t=decided_t)


def on(amcl):
    return {"amcl": amcl}


def record():
    """AMCL at 2 Hz at home, with one 1.0 s silence at t=40 (its own, nothing moves); out at
    t=100 with a 0.8 s gap; back at t=200 by a link loss with a 1.5 s gap."""
    times = ticks(10.0, 40.0, 0.5) + ticks(41.0, 100.0, 0.5) + ticks(100.8, 200.0, 0.2) + \
        ticks(201.5, 300.0, 0.5)
    return TestbedRecord(
        world="small_loop", link="coverage", finished_t=300.0,
        receipts={"/amcl_pose": times}, outputs={"amcl": "/amcl_pose"},
        tolerances={"/amcl_pose": 2.0},
        navigation_status=[(10.0, "drive 0/4"), (290.0, "done 4/4")],
        bandwidth=[(0.0, 20.0), (199.5, 0.0), (230.0, 20.0)],
        mappings=[(0.0, on("robot"), 0.0, 0.0), (100.0, on("laptop"), 0.0, 0.0),
                  (200.0, on("robot"), 0.0, 0.0)],
        events=[move(100.0), move(200.0, "migrate_back", "link to laptop lost")])


def test_each_move_has_its_kind_and_gap():
    gaps = move_gaps(1, record())
    assert [(g.kind, round(g.gap_s, 2)) for g in gaps] == [(OUT, 0.8), (LINK_LOSS, 1.5)]
    assert gaps[0].window_s == pytest.approx(1.0 + 3.0)     # registered, then MOVE_SETTLE_S


def test_the_reference_is_home_and_quiet_only():
    own = quiet_window_gaps(record(), "amcl", 4.0)
    assert max(own) == pytest.approx(1.0)                    # the node's own silence at t=40
    assert min(own) == pytest.approx(0.5)
    # Windows start every 2 s from 10 s; none on the laptop (100-200 s) or overlapping 3 s
    # around the move out (97-107 s), the return (197-207 s) and the link changes (196.5-202.5,
    # 227-233 s): starts 10-92 s, 208-222 s and 234-294 s.
    assert len(own) == 42 + 8 + 31


def test_the_handover_silence_is_the_one_before_the_new_senders_first_message():
    rec = record()
    # The laptop's instance from 100.8 s; the robot's spoke last at 100.0 s (a 0.8 s handover).
    rec.senders = {"/amcl_pose": [(10.0, "/amcl"), (100.8, "/amcl_laptop"), (201.5, "/amcl")]}
    gaps = move_gaps(1, rec)
    assert [round(g.handover_s, 2) for g in gaps] == [0.8, 1.5]
    assert "the silence before the new instance's first message: median 0.80 s" in \
        move_gap_lines([(1, rec)])[0]
    # Recorded before senders were kept: no handover figure, and no such words.
    assert all(math.isnan(g.handover_s) for g in move_gaps(1, record()))
    assert "new instance" not in move_gap_lines([(1, record())])[0]


def test_lines_name_the_worst_move_and_the_reference():
    lines = move_gap_lines([(1, record()), (2, record())])
    assert lines[0].startswith("amcl planned out: 2 moves, gap median 0.80 s")
    assert lines[1].startswith("amcl link-loss return: 2 moves")
    assert "worst 1.50 s (run 1" in lines[1]
    assert lines[2].startswith("amcl at home, nothing moving: longest silence per 4.0 s window")
    assert lines[2].endswith("worst 1.00 s")
