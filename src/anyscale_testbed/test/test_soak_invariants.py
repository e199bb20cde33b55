"""The fault soak's verdicts (soak_invariants.py) on synthetic runs: recovery time, each
invariant caught when broken and quiet when kept, violations charged to the right fault,
growth of memory and descriptors, the leak of processes, the table and its copies."""
import csv
import math

import pytest

from anyscale_testbed import fault_schedule as fs
from anyscale_testbed.soak_growth import ResourceSample, growth, unjudged_growth
from anyscale_testbed.soak_invariants import (CensusSample, InjectedFault, SoakModel,
                                              fixed_node_violations, judge_faults, process_leak)
from anyscale_testbed.soak_silences import critical_violations, startup_silences, unchecked
from anyscale_testbed.soak_report import (format_markdown, format_table, kind_rows, verdict_ok,
                                          write_csv)
from anyscale_testbed.testbed_record import EventRecord, ProcessSample, TestbedRecord

NODES = ["amcl", "ekf"]
MODEL = SoakModel("robot", NODES, {"ekf"},
                  {(n, s): f"/{n}" if s == "robot" else f"/{n}__{s}"
                   for n in NODES for s in ("robot", "laptop")}, lease_s=3.0)
ALL_UP = {"agent_robot": 1, "agent_laptop": 1, "decision": 1, "master": 1}
END = 100.0


def record(amcl_at="laptop", silent=(), unlisted=(), ghost=()):
    """AMCL (Δ 2 s) publishing at 5 Hz except in the `silent` (start, end) spans, the master
    listing its instance except in the `unlisted` spans, and its instance on the other scale
    too in the `ghost` spans; the mapping places it `amcl_at`."""
    rec = TestbedRecord()
    rec.outputs = {"amcl": "/amcl_pose"}
    rec.tolerances = {"/amcl_pose": 2.0}
    times = [i * 0.2 for i in range(int(END / 0.2))]
    rec.receipts = {"/amcl_pose": [t for t in times
                                   if not any(a <= t < b for a, b in silent)]}
    rec.mappings = [(0.0, {"amcl": amcl_at, "ekf": "robot"}, 0.0, 0.0)]
    name = MODEL.instance_names[("amcl", amcl_at)]
    other = MODEL.instance_names[("amcl", "robot" if amcl_at == "laptop" else "laptop")]
    rec.master_publishers = [(t, {"/amcl_pose": ([] if any(a <= t < b for a, b in unlisted)
                                                 else [name])
                                  + ([other] if any(a <= t < b for a, b in ghost) else [])})
                             for t in times[::5]]
    return rec


def census(amcl=lambda t: ["laptop"], supervisors=lambda t: ALL_UP, processes=lambda t: 20,
           standbys=lambda t: None):
    return [CensusSample(t, {"amcl": amcl(t), "ekf": ["robot"]}, dict(supervisors(t)),
                         processes(t), standbys=standbys(t))
            for t in (i * 0.5 for i in range(int(END / 0.5)))]


def fault(kind, t, hold=0.0, **kw):
    return InjectedFault(fs.Fault(0.0, kind, hold_s=hold, **kw), t, t + hold)


def test_a_decision_node_killed_and_back_after_2_s_recovers_in_2_s_with_no_violation():
    decision_down = census(supervisors=lambda t: dict(ALL_UP, decision=0) if 20 <= t < 22
                           else ALL_UP)
    [o] = judge_faults([fault(fs.KILL_DECISION, 20.0)], decision_down, record(), MODEL, END)
    assert o.recovery_s == pytest.approx(2.0, abs=0.51)
    assert o.violations == []
    assert verdict_ok([o], [], [])


def test_two_instances_within_a_lease_are_allowed_and_longer_is_a_violation():
    for overlap, violations in ((3.0, 0), (9.0, 1)):
        twice = census(amcl=lambda t: ["laptop", "robot"] if 30 <= t < 30 + overlap
                       else ["laptop"])
        [o] = judge_faults([fault(fs.LINK_FLAP, 29.0, hold=2.0)], twice, record(), MODEL, END)
        assert len(o.violations) == violations, o.violations
        if violations:
            assert "amcl on [laptop, robot]" in o.violations[0]


def test_a_planned_moves_overlap_is_no_violation():
    twice = census(amcl=lambda t: ["laptop", "robot"] if 30 <= t < 38 else ["laptop"])
    rec = record()
    rec.events = [EventRecord(30.0, "migrate", "amcl", "robot", "laptop", "laptop can take it",
                              2.0, True, 30.0)]
    [o] = judge_faults([fault(fs.BANDWIDTH_STEP, 29.0, mbps=12.0)], twice, rec, MODEL, END)
    assert o.violations == []


def test_an_instance_left_where_the_mapping_does_not_place_it_is_a_violation():
    stays = census(amcl=lambda t: ["laptop"])
    [o] = judge_faults([fault(fs.STOP_LAPTOP_AGENT, 40.0, hold=3.0)], stays,
                       record(amcl_at="robot"), MODEL, END)
    assert any("mapped to robot" in v for v in o.violations), o.violations
    assert math.isinf(o.recovery_s)


def test_a_publisher_the_master_lists_where_the_mapping_does_not_place_it_is_a_violation():
    # The census sees one instance, on the laptop, as mapped; the master still lists the
    # robot's /amcl as a publisher of /amcl_pose: 10 s is longer than a lease, 3 s is not.
    kill = [fault(fs.KILL_LAPTOP_AGENT, 30.0)]
    [o] = judge_faults(kill, census(), record(ghost=[(31.0, 41.0)]), MODEL, END)
    assert len(o.violations) == 1 and o.violations[0].startswith(
        "the master listed /amcl of /amcl_pose (not where the mapping places it) for 9.0 s")
    [ok] = judge_faults(kill, census(), record(ghost=[(31.0, 34.0)]), MODEL, END)
    assert ok.violations == []


def test_an_instance_paused_at_home_is_listed_by_design_and_no_violation():
    rec = record(ghost=[(31.0, 41.0)])
    rec.processes = [ProcessSample(t, True, {"amcl": ["laptop"]},
                                   ["/amcl"] if 31.0 <= t < 41.0 else [])
                     for t, _ in rec.master_publishers]
    [o] = judge_faults([fault(fs.KILL_LAPTOP_AGENT, 30.0)], census(), rec, MODEL, END)
    assert o.violations == []


def test_a_publisher_listed_twice_during_a_planned_moves_overlap_is_no_violation():
    rec = record(ghost=[(30.0, 38.0)])
    rec.events = [EventRecord(30.0, "migrate", "amcl", "robot", "laptop", "laptop can take it",
                              2.0, True, 30.0)]
    [o] = judge_faults([fault(fs.BANDWIDTH_STEP, 29.0, mbps=12.0)], census(), rec, MODEL, END)
    assert o.violations == []


def test_an_output_silent_longer_than_its_tolerance_is_charged_to_the_fault_before_it():
    rec = record(silent=[(50.1, 53.5)])
    faults = [fault(fs.SEGV_NODE, 20.0, target="amcl"), fault(fs.SEGV_NODE, 50.5, target="amcl"),
              fault(fs.KILL_DECISION, 70.0)]
    outcomes = judge_faults(faults, census(), rec, MODEL, END)
    assert [len(o.violations) for o in outcomes] == [0, 1, 0]
    assert "/amcl_pose silent 3.60 s > Δ 2 s" in outcomes[1].violations[0]
    assert outcomes[1].worst_silence == ("/amcl_pose", pytest.approx(3.6), 2.0)
    row = [r for r in kind_rows(outcomes) if r.kind == fs.SEGV_NODE][0]
    assert (row.faults, row.violations) == (2, 1)


def with_critical_odom(rec, silent=()):
    """The record with /odom, a critical connection's topic (freq_min 5 Hz), at 10 Hz except
    in the `silent` spans, as a monitor with ~record_critical records it."""
    rec.critical_freq_min = {"/odom": 5.0}
    rec.receipts["/odom"] = [t for t in (i * 0.1 for i in range(int(END / 0.1)))
                             if not any(a <= t < b for a, b in silent)]
    return rec


def test_a_critical_topic_silent_for_more_than_a_period_at_its_freq_min_is_a_violation():
    # 5 Hz minimum: a period of 0.2 s, and 0.1 s for the CPU quota's period on top.
    faults = [fault(fs.SEGV_NODE, 20.0, target="amcl"), fault(fs.LINK_FLAP, 50.0, hold=2.0)]
    outcomes = judge_faults(faults, census(), with_critical_odom(record(), [(50.05, 50.5)]),
                            MODEL, END)
    assert [len(o.violations) for o in outcomes] == [0, 1]
    assert outcomes[1].violations[0].startswith("/odom (critical, Δ 0) silent 0.50 s > 0.30 s")
    # A message late by less than the quota's period is within its minimum rate.
    quiet = judge_faults(faults, census(), with_critical_odom(record(), [(50.05, 50.15)]),
                         MODEL, END)
    assert [o.violations for o in quiet] == [[], []]


def test_the_sensors_stopping_together_at_the_end_is_no_critical_silence():
    rec = with_critical_odom(record(), [(END - 0.7, END)])     # the teardown's tail
    rec.critical_freq_min["/scan"] = 5.0
    rec.receipts["/scan"] = list(rec.receipts["/odom"])
    rec.finished_t = END
    assert critical_violations(rec) == []
    # One that stops alone while the others go on is counted up to their last message.
    rec.receipts["/scan"] = [t for t in rec.receipts["/scan"] if t < END - 2.0]
    assert [(v.topic, round(v.silence_s, 1)) for v in critical_violations(rec)] == [("/scan", 1.3)]


def test_a_critical_silence_says_whether_its_data_or_its_messages_came_late():
    rec = with_critical_odom(record(), [(50.05, 50.5)])     # received at 50.0, then at 50.5
    rec.critical_freq_min["/scan"] = 2.0                    # its 0.5 s silence is no violation
    rec.receipts["/scan"] = with_critical_odom(TestbedRecord()).receipts["/odom"]
    odom = rec.receipts["/odom"]
    after = next(i for i, t in enumerate(odom) if t > 50.3)
    # Made on time, queued, delivered in a burst: the stamps are 0.1 s apart.
    rec.stamps["/odom"] = [(t, t) for t in odom]
    rec.stamps["/odom"][after] = (odom[after], odom[after - 1] + 0.1)
    [v] = critical_violations(rec)
    assert "stamped 0.10 s apart, the first after it received 0.40 s after its stamp: its data " \
           "on time, late from its publisher to the monitor" in v.cause and "either" not in v.cause
    # Made late: the stamps are as far apart as the receipts; /scan stalled with it.
    rec.stamps["/odom"] = [(t, t) for t in odom]
    rec.receipts["/scan"] = [t for t in rec.receipts["/scan"] if not 50.05 < t < 50.45]
    [v] = critical_violations(rec)
    assert "stamped 0.50 s apart: its data came late to its publisher" in v.cause
    assert "nothing received of /scan either" in v.cause
    # Without stamps (a message with no header, an older record) the cause says neither.
    rec.stamps = {}
    assert "stamped" not in critical_violations(rec)[0].cause


def test_an_output_is_judged_up_to_the_teardown_not_to_the_records_end():
    # The soak's system test, run 2: /ar_markers' last message came 0.51 s before the sensors
    # stopped together for the teardown, the monitor recorded 0.68 s longer, and the tail was
    # judged "silent 1.19 s > Δ 1 s", charged to the roscore restart 20 s before it.
    faults = [fault(fs.RESTART_ROSCORE, 70.0, hold=1.2)]
    rec = with_critical_odom(record(silent=[(END - 2.8, END)]), [(END - 1.2, END)])
    rec.finished_t = END
    [o] = judge_faults(faults, census(), rec, MODEL, END)
    assert o.violations == []
    # One silent too long before the teardown still is a violation, counted up to there.
    rec = with_critical_odom(record(silent=[(END - 4.0, END)]), [(END - 1.2, END)])
    rec.finished_t = END
    [o] = judge_faults(faults, census(), rec, MODEL, END)
    assert len(o.violations) == 1 and "/amcl_pose silent 2.90 s > Δ 2 s" in o.violations[0]


def test_a_silence_just_over_its_limit_is_printed_so_that_it_reads_over():
    # Run 2 printed "/joint_states (critical, Δ 0) silent 0.20 s > 0.20 s": 0.204 s against
    # 0.200 s, rounded alike.
    rec = record()
    rec.critical_freq_min = {"/joint_states": 10.0}
    rec.receipts["/joint_states"] = [t for t in (i * 0.05 for i in range(int(END / 0.05)))
                                     if not 50.0 < t < 50.25] + [50.204]
    faults = [fault(fs.BANDWIDTH_STEP, 45.0, mbps=3.0)]
    [o] = judge_faults(faults, census(), rec, MODEL, END)
    assert len(o.violations) == 1
    assert o.violations[0].startswith("/joint_states (critical, Δ 0) silent 0.204 s > 0.200 s")
    rec = record(silent=[(50.1, 52.2)])     # /amcl_pose: 2.004 s against its Δ of 2 s
    rec.receipts["/amcl_pose"] = sorted(rec.receipts["/amcl_pose"] + [52.004])
    [o] = judge_faults(faults, census(), rec, MODEL, END)
    assert "/amcl_pose silent 2.004 s > Δ 2 s" in o.violations[0]


def test_a_record_without_the_critical_topics_says_their_check_was_not_made():
    assert unchecked(with_critical_odom(record())) == []
    [missing] = unchecked(record())
    assert "critical connections' Δ 0" in missing
    table = format_table([], [], [], [missing])
    assert "NOT CHECKED the critical connections' Δ 0" in table
    assert table.splitlines()[-1].endswith("1 NOT CHECKED")


def test_a_silence_before_the_first_fault_is_the_start_ups_not_a_faults():
    [o] = judge_faults([fault(fs.KILL_DECISION, 30.0)], census(), record(silent=[(5.0, 12.0)]),
                       MODEL, END)
    assert o.violations == []


def test_a_critical_silence_already_too_long_when_a_fault_struck_is_not_that_faults():
    # The first CI soak charged /odom's silence at t≈16 s to the link flap after it: a silence
    # that began up to 1 s (AR's period) before a fault was the fault's, but /odom's limit is
    # 0.3 s, so a silence older than that was a violation before the fault struck.
    faults = [fault(fs.SEGV_NODE, 20.0, target="amcl"), fault(fs.LINK_FLAP, 50.0, hold=2.0)]
    before = with_critical_odom(record(), [(49.45, 50.2)])     # last message at 49.4
    outcomes = judge_faults(faults, census(), before, MODEL, END)
    assert outcomes[1].violations == []
    assert outcomes[0].violations[0].startswith("/odom (critical, Δ 0) silent 0.80 s")
    # One the fault may have made: begun within its limit before the fault, or after it.
    for silent, words in [((49.85, 50.6), "began 0.20 s before the fault struck"),
                          ((50.45, 51.0), "began 0.40 s after the fault struck")]:
        outcomes = judge_faults(faults, census(), with_critical_odom(record(), [silent]), MODEL,
                                END)
        assert outcomes[0].violations == [] and words in outcomes[1].violations[0]


def test_a_silence_too_long_before_the_first_fault_is_named_as_the_start_ups():
    faults = [fault(fs.LINK_FLAP, 16.5, hold=2.0)]
    rec = with_critical_odom(record(silent=[(3.0, 8.0)]), [(15.85, 16.6)])
    [o] = judge_faults(faults, census(), rec, MODEL, END)
    assert o.violations == []
    assert startup_silences(faults, rec) == [
        "/amcl_pose silent 5.20 s > Δ 2 s from t=2.8 s: before the first fault (the "
        "start-up's, not judged as a fault's)",
        "/odom (critical, Δ 0) silent 0.80 s > 0.30 s (a period at its freq_min 5 Hz + 0.1 s) "
        "from t=15.8 s: before the first fault (the start-up's, not judged as a fault's)"]


def test_a_master_that_lists_no_publisher_after_its_restart_is_never_recovered_from():
    rec = record(unlisted=[(60.0, END)])
    restarted = fault(fs.RESTART_ROSCORE, 58.0, hold=2.0)
    [o] = judge_faults([restarted], census(), rec, MODEL, END)
    assert math.isinf(o.recovery_s)
    assert "the master lists no publisher /amcl__laptop of /amcl_pose" in o.violations[0]
    # The same restart after which the node registers again is recovered from.
    [ok] = judge_faults([restarted], census(), record(unlisted=[(60.0, 64.0)]), MODEL, END)
    assert ok.recovery_s == pytest.approx(6.0, abs=1.1) and ok.violations == []


def test_a_supervisor_that_never_comes_back_is_named():
    gone = census(supervisors=lambda t: dict(ALL_UP, agent_robot=0) if t >= 10 else ALL_UP)
    [o] = judge_faults([fault(fs.KILL_ROBOT_AGENT, 10.0)], gone, record(), MODEL, END)
    assert "agent_robot x0" in o.violations[0]


def test_a_node_that_may_not_move_is_caught_in_the_mapping_an_event_and_the_census():
    rec = record()
    rec.mappings.append((40.0, {"amcl": "laptop", "ekf": "laptop"}, 0.0, 0.0))
    rec.events = [EventRecord(40.0, "migrate", "ekf", "robot", "laptop", "x", 1.0, True, 40.0)]
    moved = [CensusSample(t, {"amcl": ["laptop"], "ekf": ["laptop" if t >= 41 else "robot"]},
                          ALL_UP) for t in (39.0, 41.0, 42.0)]
    found = fixed_node_violations(moved, rec, MODEL)
    assert len(found) == 3 and all("ekf" in text for _, text in found)
    assert fixed_node_violations(census(), record(), MODEL) == []


def test_a_fault_that_could_not_be_injected_is_not_judged_but_fails_the_verdict():
    missing = InjectedFault(fs.Fault(0.0, fs.KILL_LAPTOP_AGENT), 30.0, 30.0,
                            error="no agent_laptop process to signal")
    outcomes = judge_faults([missing], census(), record(), MODEL, END)
    assert outcomes[0].violations == [] and not verdict_ok(outcomes, [], [])
    assert "NOT INJECTED" in format_table(outcomes, [], [])


def series(role, pid, rss, fds, span=300.0, step=5.0):
    return [ResourceSample(i * step, role, pid, rss(i * step), fds(i * step))
            for i in range(int(span / step))]


def test_growth_of_memory_and_of_descriptors_is_found_and_steady_use_is_not():
    steady = series("decision", 10, lambda t: 60.0 + (t % 10) * 0.1, lambda t: 30)
    leaking = series("agent_robot", 11, lambda t: 20.0 + t * 0.05, lambda t: 12 + int(t / 20))
    short = series("agent_laptop", 12, lambda t: 20.0 + t, lambda t: 10 + t, span=30.0)
    found = {g.role: g for g in growth(steady + leaking + short)}
    assert found["decision"].grew == []
    assert [w.split()[0] for w in found["agent_robot"].grew] == ["memory", "file"]
    assert "agent_laptop" not in found           # too short to judge
    assert "GREW" in format_table([], [], list(found.values()))


def test_connections_that_follow_the_graph_are_no_growth_and_a_leaked_socket_is():
    # The decision node's descriptors in a soak: 22-33 as instances came and went, all of the
    # swing established connections. One whose count of other descriptors climbs is judged.
    def swinging(pid, held):
        return [ResourceSample(i * 5.0, "decision", pid, 60.0, held(i) + c, c)
                for i, c in enumerate([3, 3, 4, 9, 10, 11, 9, 12, 11, 10, 11, 12] * 5)]
    found = {g.pid: g for g in growth(swinging(30, lambda i: 18) +
                                      swinging(31, lambda i: 18 + i // 6))}
    assert found[30].grew == []
    assert found[31].grew and found[31].grew[0].startswith("file descriptors")


def test_a_process_respawned_late_is_judged_over_its_own_life_and_a_brief_one_is_named():
    # An agent killed and started again 55 s before the soak ended: 35 s after its warm-up,
    # at 2 Hz, leaking 0.5 MB/s and a descriptor every 3 s.
    late = series("agent_laptop", 21, lambda t: 18.0 + 0.5 * t, lambda t: 11 + int(t / 3),
                  span=55.0, step=0.5)
    brief = series("decision", 22, lambda t: 60.0, lambda t: 30, span=30.0, step=0.5)
    [found] = growth(late + brief)
    assert (found.pid, [w.split()[0] for w in found.grew]) == (21, ["memory", "file"])
    [named] = unjudged_growth(late + brief)
    assert named == "growth of decision pid 22: sampled 10 s after its 20 s warm-up, judged " \
                    "from 30 s"
    assert "NOT CHECKED growth of decision pid 22" in format_table([], [], [found], [named])


def test_more_processes_at_the_end_with_the_same_placement_is_a_leak():
    leaking = census(processes=lambda t: 20 if t < 50 else 21)
    assert process_leak(leaking, record(), MODEL, 0.0)
    assert process_leak(census(), record(), MODEL, 0.0) == []


def test_processes_started_before_the_first_fault_are_no_leak():
    # The agents prepare their warm standbys after the nodes start: 2 more processes at 6.5 s.
    settling = census(processes=lambda t: 18 if t < 6.5 else 20)
    assert process_leak(settling, record(), MODEL, 0.0)      # counted from the start: a leak
    assert process_leak(settling, record(), MODEL, 10.0) == []


def test_a_standby_prepared_since_is_no_leak_but_a_second_one_of_an_instance_is():
    # The soak of 2026-11-27 (seed 2): the laptop's AMCL standby prepared after its first
    # sample at this placement, 30 processes at the end against 29.
    prepared = census(processes=lambda t: 29 if t < 50 else 30,
                      standbys=lambda t: ["amcl /robot"] + (["amcl__laptop /laptop"] if t >= 50
                                                            else []))
    assert process_leak(prepared, record(), MODEL, 0.0) == []
    doubled = census(processes=lambda t: 29 if t < 50 else 30,
                     standbys=lambda t: ["amcl /robot"] * (2 if t >= 50 else 1))
    [leak] = process_leak(doubled, record(), MODEL, 0.0)
    assert "two or more of amcl /robot" in leak
    # A node process more, standbys alike: still a leak.
    grown = census(processes=lambda t: 29 if t < 50 else 30, standbys=lambda t: ["amcl /robot"])
    [leak] = process_leak(grown, record(), MODEL, 0.0)
    assert leak.startswith("29 processes of the ROS system besides warm standbys")
    # A soak that recorded no standbys (before 2026-11-27) is judged on every process.
    [leak] = process_leak(census(processes=lambda t: 29 if t < 50 else 30), record(), MODEL, 0.0)
    assert leak.startswith("30 processes of the ROS system at")


def test_the_table_and_its_copies(tmp_path):
    faults = [fault(fs.LINK_FLAP, 20.0, hold=2.0, mbps=27.0),
              fault(fs.RESTART_ROSCORE, 58.0, hold=2.0)]
    outcomes = judge_faults(faults, census(), record(unlisted=[(60.0, END)]), MODEL, END)
    text = format_table(outcomes, ["namespace anyscale_robot"], [])
    lines = text.splitlines()
    assert lines[0].split()[:2] == ["fault", "kind"]
    assert len([line for line in lines if line.split()[0] in fs.KINDS]) == len(fs.KINDS)
    assert "never" in text and "LEAK namespace anyscale_robot" in text
    assert lines[-1] == "total: 2 faults, 1 violations, 1 leaks, 0 processes grew"
    write_csv(str(tmp_path / "soak.csv"), outcomes)
    rows = list(csv.reader(open(tmp_path / "soak.csv")))
    kinds = [r for r in rows if r and r[0] == "kind"]
    assert [r[1] for r in kinds] == list(fs.KINDS)
    assert [r for r in rows if r and r[0] == "fault"][1][7] == "inf"
    md = format_markdown(outcomes, [], [], "Fault soak")
    assert md.startswith("# Fault soak") and "| restart_roscore |" in md
