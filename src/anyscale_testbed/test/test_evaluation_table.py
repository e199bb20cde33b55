"""The evaluation's figures and table, from synthetic test-bed records: the coverage bound,
Fig. 5's configurations, mean |w|, the gains against the baseline and against each test's
paired baseline, the premise flag, the paper beside them."""
import csv
import math

import pytest

from anyscale_testbed.evaluation_figures import (AMCL_ON_LAPTOP, AR_ON_LAPTOP, BOTH_ON_LAPTOP,
                                                 BOTH_ON_ROBOT, configuration_of,
                                                 configuration_shares, coverage_bound,
                                                 mean_abs_omega_deg_s, own_speed_share,
                                                 run_figures,
                                                 turning_per_metre_deg)
from anyscale_testbed.path_steps import configurations_along_path
from anyscale_testbed.evaluation_table import (baseline_of, bound_share, format_markdown,
                                               format_table, gain, paired_baseline,
                                               paired_bound_share, paired_gain,
                                               paired_gain_spread, paper_comparison,
                                               spread_of, table_lines, write_csv)
from anyscale_testbed.testbed_figures import tolerance_violations
from anyscale_testbed.testbed_record import TestbedRecord, mapping_at

AMCL_MBPS = 0.22


def on(amcl="robot", ar="robot"):
    return {"amcl": amcl, "ar_recognition": ar, "navigation": "robot"}


def record(done_t=110.0, speed=0.3, yaw_rate=0.05, link_until=60.0, mappings=None,
           amcl_gap=None, out_speed=None, amcl_hz=5.0):
    """Navigation from t=10 to done_t; the robot drives east at `speed` (at `out_speed` while
    AMCL is on the laptop, if given) turning at `yaw_rate` rad/s; AMCL's pose at `amcl_hz`;
    the link up at 10 Mbit/s until `link_until`, then down."""
    times = [round(0.1 * k, 1) for k in range(0, 2501)]
    amcl = [t for t in (round(k / amcl_hz, 3) for k in range(int(250 * amcl_hz) + 1))
            if amcl_gap is None or not amcl_gap[0] < t < amcl_gap[1]]
    mappings = mappings if mappings is not None else [
        (5.0, on(), 0.0, 0.0), (30.0, on(amcl="laptop"), 0.0, 0.0), (60.0, on(), 0.0, 0.0)]
    x = [0.0]
    for t in times[:-1]:
        amcl_out = mapping_at(TestbedRecord(mappings=mappings), t).get("amcl") == "laptop"
        x.append(x[-1] + 0.1 * (out_speed if out_speed is not None and amcl_out else speed))
    rec = TestbedRecord(
        world="small_loop", link="coverage", finished_t=250.0,
        truth=[(t, xt, 0.0) for t, xt in zip(times, x)],
        truth_yaw=[(t, yaw_rate * t) for t in times],
        estimate=[(t, xt + 0.1, 0.0) for t, xt in zip(times[::5], x[::5])],
        bandwidth=[(0.0, 10.0), (link_until, 0.0)], mappings=mappings,
        navigation_status=[(10.0, "drive 0/4")] + ([(done_t, "done 4/4")] if done_t else []),
        receipts={"/amcl_pose": amcl}, outputs={"amcl": "/amcl_pose"},
        tolerances={"/amcl_pose": 2.0}, markers_seen=[0, 1, 2, 3])
    rec.violations = tolerance_violations(rec)
    return rec


def test_fig5_configurations_by_where_amcl_and_ar_run():
    assert configuration_of(on(amcl="laptop")) == AMCL_ON_LAPTOP
    assert configuration_of(on()) == BOTH_ON_ROBOT
    assert configuration_of(on("laptop", "laptop")) == BOTH_ON_LAPTOP
    assert configuration_of(on(ar="laptop")) == AR_ON_LAPTOP
    assert configuration_of({}) == BOTH_ON_ROBOT


def test_time_shares_of_the_configurations_over_the_mission():
    shares = configuration_shares(record())
    assert shares[BOTH_ON_ROBOT] == pytest.approx(0.7)      # 10-30 and 60-110 of 10-110
    assert shares[AMCL_ON_LAPTOP] == pytest.approx(0.3)
    assert shares[BOTH_ON_LAPTOP] == shares[AR_ON_LAPTOP] == 0.0
    along = configurations_along_path(record())
    assert along[0] == BOTH_ON_ROBOT and along[250] == AMCL_ON_LAPTOP and len(along) == 1001


def test_coverage_bound_has_amcl_out_wherever_the_link_carries_it_at_the_runs_own_speeds():
    # AMCL out 30-60 s at 0.4 m/s, home at 0.2 m/s; the link carries it until 60 s.
    bound = coverage_bound(record(speed=0.2, out_speed=0.4), AMCL_MBPS)
    assert (bound.home_mps, bound.out_mps) == (pytest.approx(0.2), pytest.approx(0.4))
    assert bound.path_m == pytest.approx(4 + 12 + 10)      # 10-30 s, 30-60 s, 60-110 s
    assert bound.carried_share == pytest.approx(16 / 26)
    assert bound.time_s == pytest.approx(100 - 10)          # 10-30 s: 4 m at 0.4 m/s, not 0.2
    # AMCL out until 70 s, 10 s past the link: the bound has it home there, at 0.2 m/s.
    late = [(5.0, on(), 0.0, 0.0), (30.0, on(amcl="laptop"), 0.0, 0.0), (70.0, on(), 0.0, 0.0)]
    assert coverage_bound(record(speed=0.2, out_speed=0.4, mappings=late),
                          AMCL_MBPS).time_s == pytest.approx(100 - 10 + 10)
    # A link too thin for AMCL's traffic is no better than none.
    assert coverage_bound(record(speed=0.2, out_speed=0.4), 12.0).time_s == \
        pytest.approx(100 + 30 * 0.4 / 0.2 - 30)
    # The run's own speeds: one that drove home as fast as out gains nothing from the bound.
    assert coverage_bound(record(), AMCL_MBPS).time_s == pytest.approx(100)
    # A case the run did not drive in has the premise's speed (0.4 m/s with AMCL out).
    never_out = coverage_bound(record(speed=0.2, mappings=[(5.0, on(), 0.0, 0.0)]), AMCL_MBPS)
    assert never_out.out_mps == 0.4 and never_out.time_s == pytest.approx(100 - 50 * 0.2 / 0.4)
    assert math.isnan(coverage_bound(TestbedRecord(), AMCL_MBPS).time_s)
    assert math.isnan(coverage_bound(record(done_t=None), AMCL_MBPS).time_s)


def test_the_share_at_the_runs_own_speeds_needs_no_baseline():
    # 100 s; AMCL out 30-60 s at 0.4 m/s (12 m), which at home's 0.2 m/s takes 60 s: 130 s with
    # AMCL home throughout; the bound 90 s. A baseline run on a slower or faster host moves the
    # share against it, not this one.
    bound = coverage_bound(record(speed=0.2, out_speed=0.4), AMCL_MBPS)
    assert (bound.taken_s, bound.home_time_s) == (pytest.approx(100), pytest.approx(130))
    assert own_speed_share(bound) == pytest.approx(30 / 40)
    never_out = coverage_bound(record(speed=0.2, mappings=[(5.0, on(), 0.0, 0.0)]), AMCL_MBPS)
    assert never_out.home_time_s == pytest.approx(100) and own_speed_share(never_out) == 0.0
    # Driving home as fast as out, there is nothing to gain: no share.
    assert math.isnan(own_speed_share(coverage_bound(record(), AMCL_MBPS)))
    assert math.isnan(own_speed_share(coverage_bound(record(done_t=None), AMCL_MBPS)))


def test_mean_abs_omega_and_turning_per_metre_over_the_mission_and_nan_without_heading():
    assert mean_abs_omega_deg_s(record(yaw_rate=-0.05)) == pytest.approx(0.05 * 180 / math.pi)
    # 0.05 rad/s at 0.3 m/s; twice as fast at the same yaw rate turns half as much per metre.
    assert turning_per_metre_deg(record()) == pytest.approx(0.05 / 0.3 * 180 / math.pi)
    assert turning_per_metre_deg(record(speed=0.6)) == pytest.approx(0.05 / 0.6 * 180 / math.pi)
    old = record()
    old.truth_yaw = []
    assert math.isnan(mean_abs_omega_deg_s(old)) and math.isnan(turning_per_metre_deg(old))


def campaign():
    baseline = run_figures("baseline", "baseline", 0, 0,
                           record(done_t=210.0, mappings=[]), AMCL_MBPS)
    # The link carries AMCL over the first half of each test's path; the robot drives twice as
    # fast with AMCL out (30-60 s) as at home.
    tests = [run_figures(f"AnyScale seed {s}", "paper", s, 0,
                         record(done_t=160.0 + s, link_until=10.0 + (150.0 + s) / 2,
                                out_speed=0.6), AMCL_MBPS) for s in (1, 2)]
    broken = run_figures("optimal seed 1", "optimal", 1, 0,
                         record(done_t=None, amcl_gap=(40.0, 45.0)), AMCL_MBPS)
    missing = run_figures("optimal seed 2", "optimal", 2, 1, None, AMCL_MBPS)
    best = run_figures("best case", "best_case", 0, 0, record(done_t=110.0, link_until=1e9),
                       AMCL_MBPS)
    return [baseline] + tests + [broken, missing, best]


def test_gains_against_the_baseline_and_the_share_of_the_bound():
    figures = campaign()
    baseline = baseline_of(figures)
    _, one, two, broken, missing, best = figures
    assert gain(one, baseline) == pytest.approx(1 - 151 / 200)
    assert gain(best, baseline) == pytest.approx(0.5)
    assert math.isnan(gain(broken, baseline)) and math.isnan(gain(missing, baseline))
    assert broken.row.note == "the loop was not completed" and len(broken.row.violations) == 1
    assert missing.row.note == "no record" and missing.row.exit_code == 1
    lines = table_lines(campaign())
    head = lines[0]
    row = dict(zip(head, lines[2]))
    assert row["time to complete"] == "151 s" and row["gain vs baseline"] == "24.5 %"
    # Home but carried 10-30 s and 60-85.5 s: 45.5 s at 0.3 m/s would have taken 22.75 s.
    assert row["coverage bound"] == "128 s (35.9 %)"         # 151 - 22.75 s against 200 s
    assert row["share of bound's gain"] == "68.3 %"
    assert row["mean |w|"] == "2.86 °/s" and row["|w| / baseline"] == "1.000"
    assert row["markers"] == "4" and row["AMCL RMS error"] == "0.100 m"
    assert row["AMCL on laptop time"] == "19.9 %" and row["both on robot time"] == "80.1 %"
    assert row["/amcl_pose longest/Δ"] == "0.20/2 s" and row["migrations"] == "0"
    means = {line[0]: dict(zip(head, line)) for line in lines[7:]}
    assert set(means) == {"mean AnyScale (paper), 2 tests", "mean AnyScale (optimal), 2 tests"}
    paper = means["mean AnyScale (paper), 2 tests"]
    assert paper["time to complete"] == "152 s" and paper["gain vs baseline"] == "24.2 %"
    optimal = means["mean AnyScale (optimal), 2 tests"]
    assert optimal["violations"] == "1" and optimal["time to complete"] == "-"


def test_gains_are_measured_against_the_mean_of_the_baseline_runs_that_completed():
    slow = run_figures("baseline, run 2", "baseline", 0, 0, record(done_t=230.0, mappings=[]),
                       AMCL_MBPS)
    unfinished = run_figures("baseline, run 3", "baseline", 0, 0,
                             record(done_t=None, mappings=[]), AMCL_MBPS)
    figures = campaign() + [slow, unfinished]
    baseline = baseline_of(figures)
    assert (baseline.runs, baseline.path_time_s) == (2, pytest.approx(210.0))
    assert (baseline.shortest_s, baseline.longest_s) == (pytest.approx(200.0), pytest.approx(220.0))
    assert gain(figures[1], baseline) == pytest.approx(1 - 151 / 210)
    rows = {line[0]: line for line in table_lines(figures)}
    assert rows["baseline, run 2"][3] == "-4.8 %"           # 220 s against the mean's 210 s
    assert paper_comparison(figures)[0] == ("baseline: 2 runs, mean time to complete 210 s "
                                            "(200-220 s)")
    assert baseline_of([f for f in figures if f.kind != "baseline"]) is None


def test_the_paper_beside_ours():
    lines = paper_comparison(campaign())[1:]
    assert lines[0] == "mean gain of the AnyScale tests: paper 28.0 % over 4 tests; here 24.2 % " \
                       "over 2"
    # No test of the campaign is in a pair.
    assert lines[1] == ("paired gain of the AnyScale tests (each against the baseline run just "
                        "before it): no pair with both runs complete")
    assert lines[2] == "best case (the network everywhere): paper 50.0 %; here 50.0 %"
    assert lines[3].startswith("share of the coverage bound's gain reached: here 56.7 % at "
                               "each test's own speeds; against the baselines 67.9 %, against "
                               "the paired baselines - (the paper has no bound)")
    # The tests' robot drives faster with AMCL out, turning at the same rate: less per metre.
    assert lines[4] == ("mean |w| against the baseline: paper about 5.0 % above; here 0.0 % "
                        "above; turning per metre driven -16.5 % below (the same loop driven "
                        "faster turns faster at the same corners)")
    assert lines[5] == "highest mean |w|: limit of safe behaviour 4 °/s; here 2.86 °/s"


def test_text_markdown_and_csv_copies(tmp_path):
    figures = campaign()
    text = format_table(figures)
    assert "VIOLATION optimal seed 1: /amcl_pose silent 5.0" in text
    assert "\npaper vs here:\n" in text
    assert "left of the coverage bound, by cause:\n  AnyScale seed 1: " in text
    md = format_markdown(figures, "Evaluation")
    assert md.startswith("# Evaluation\n\n| run | exit | time to complete |")
    assert "| AnyScale seed 1 | 0 | 151 s | 24.5 % |" in md
    assert "## The paper beside this test bed" in md
    write_csv(str(tmp_path / "e.csv"), figures)
    with open(tmp_path / "e.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["kind"] for r in rows] == ["baseline", "paper", "paper", "optimal", "optimal",
                                         "best_case"]
    assert float(rows[1]["gain_vs_baseline"]) == pytest.approx(1 - 151 / 200)
    assert rows[1]["bound_gain"] == "0.3587" and rows[4]["time_to_complete_s"] == ""
    assert rows[1]["time_share AMCL on laptop"] == "0.1987" and rows[1]["markers"] == "4"


def pairs():
    """Interleaved pairs (baseline, then its test) beside a grouped baseline of another day
    (300 s): pair 1 200 s then 151 s, pair 2 180 s then 165 s, pair 3's baseline did not
    complete, pair 4's baseline is not recorded, pair 5's test is not recorded (230 s)."""
    def base(pair, done_t):
        return run_figures(f"pair {pair}: baseline", "baseline", 0, 0,
                           record(done_t=done_t, mappings=[]), AMCL_MBPS, pair=pair)

    def test(pair, done_t):
        return run_figures(f"pair {pair}: AnyScale", "paper", pair, 0,
                           record(done_t=done_t, link_until=10.0 + (150.0 + pair) / 2,
                                  out_speed=0.6), AMCL_MBPS, pair=pair)
    old = run_figures("baseline", "baseline", 0, 0, record(done_t=310.0, mappings=[]),
                      AMCL_MBPS)
    return [old, base(1, 210.0), test(1, 161.0), base(2, 190.0), test(2, 175.0),
            base(3, None), test(3, 160.0), test(4, 160.0), base(5, 240.0)]


def test_each_test_is_measured_against_its_own_paired_baseline():
    figures = pairs()
    _, b1, t1, b2, t2, b3, t3, t4, b5 = figures
    assert paired_baseline(t1, figures).path_time_s == pytest.approx(200.0)
    assert paired_gain(t1, figures) == pytest.approx(1 - 151 / 200)
    assert paired_gain(t2, figures) == pytest.approx(1 - 165 / 180)
    # Against the mean of every baseline that completed (300, 200, 180, 230 s: 227.5 s).
    assert gain(t2, baseline_of(figures)) == pytest.approx(1 - 165 / 227.5)
    # A baseline that did not complete, one not recorded: no paired gain, not 0.
    assert paired_baseline(t3, figures) is None and math.isnan(paired_gain(t3, figures))
    assert paired_baseline(t4, figures) is None and math.isnan(paired_gain(t4, figures))
    # A baseline has no paired gain of its own, nor has a run outside any pair.
    assert math.isnan(paired_gain(b1, figures)) and math.isnan(paired_gain(figures[0], figures))
    # The share of the coverage bound uses the paired baseline for both gains.
    assert paired_bound_share(t1, figures) == pytest.approx(
        bound_share(t1, baseline_of([b1])))
    assert paired_bound_share(t1, figures) == pytest.approx(
        (1 - 151 / 200) / (1 - (151 - 22.75) / 200))
    assert not paired_bound_share(t1, figures) == pytest.approx(
        bound_share(t1, baseline_of(figures)))


def test_the_paired_gains_mean_and_spread_count_only_complete_pairs():
    figures = pairs()
    tests = [f for f in figures if f.kind == "paper"]
    spread = paired_gain_spread(tests, figures)
    one, two = 1 - 151 / 200, 1 - 165 / 180
    assert spread.count == 2
    assert spread.mean == pytest.approx((one + two) / 2)
    assert spread.sd == pytest.approx(abs(one - two) / math.sqrt(2))
    assert (spread.lowest, spread.highest) == (pytest.approx(two), pytest.approx(one))
    lone = spread_of([0.1, math.nan])
    assert lone.count == 1 and lone.mean == pytest.approx(0.1) and math.isnan(lone.sd)
    assert spread_of([]).count == 0 and math.isnan(spread_of([]).mean)


def test_the_table_and_csv_show_the_paired_gain_beside_the_gain_against_the_mean(tmp_path):
    figures = pairs()
    lines = table_lines(figures)
    head = lines[0]
    rows = {line[0]: dict(zip(head, line)) for line in lines[1:]}
    t1 = rows["pair 1: AnyScale"]
    assert (t1["gain vs baseline"], t1["gain vs paired baseline"]) == ("33.6 %", "24.5 %")
    assert t1["share of bound's gain vs paired"] == "68.3 %"
    assert rows["pair 3: AnyScale"]["gain vs paired baseline"] == "-"
    assert rows["pair 1: baseline"]["gain vs paired baseline"] == "-"
    mean = rows["mean AnyScale (paper), 4 tests"]
    assert mean["gain vs paired baseline"] == "16.4 % (sd 11.4 %, 8.3 to 24.5 %, 2 pairs)"
    assert paper_comparison(figures)[2] == (
        "paired gain of the AnyScale tests (each against the baseline run just before it): "
        "16.4 % (sd 11.4 %, 8.3 to 24.5 %, 2 pairs)")
    write_csv(str(tmp_path / "e.csv"), figures)
    with open(tmp_path / "e.csv") as f:
        csv_rows = {r["run"]: r for r in csv.DictReader(f)}
    assert csv_rows["pair 1: AnyScale"]["pair"] == "1" and csv_rows["baseline"]["pair"] == "0"
    assert csv_rows["pair 1: AnyScale"]["gain_vs_paired_baseline"] == "0.2450"
    assert csv_rows["pair 1: AnyScale"]["gain_vs_baseline"] == "0.3363"
    assert csv_rows["pair 1: AnyScale"]["share_of_bound_gain_vs_paired"] == "0.6829"
    assert csv_rows["pair 4: AnyScale"]["gain_vs_paired_baseline"] == ""


def test_a_run_off_the_premise_at_home_is_flagged_in_the_table_and_the_csv(tmp_path):
    home = [(0.0, on(), 0.0, 0.0)]
    fast = run_figures("baseline, run 2", "baseline", 0, 0,
                       record(done_t=210.0, mappings=home, amcl_hz=3.0), AMCL_MBPS)
    calibrated = run_figures("baseline, run 3", "baseline", 0, 0,
                             record(done_t=210.0, mappings=home, amcl_hz=2.0), AMCL_MBPS)
    assert fast.amcl_hz_home == pytest.approx(3.0, abs=0.01)
    assert fast.cruise_mps_home == pytest.approx(0.3, abs=0.01)
    out = run_figures("always out", "best_case", 0, 0,
                      record(mappings=[(0.0, on("laptop", "laptop"), 0.0, 0.0)]), AMCL_MBPS)
    figures = campaign() + [fast, calibrated, out]
    lines = table_lines(figures)
    rows = {line[0]: dict(zip(lines[0], line)) for line in lines[1:]}
    assert rows["baseline, run 2"]["AMCL at home"] == "3.00 Hz"
    assert rows["baseline, run 2"]["cruise at home"] == "0.30 m/s"
    assert rows["baseline, run 2"]["note"] == "premise off: AMCL 3.0 Hz at home"
    assert rows["baseline, run 3"]["AMCL at home"] == "2.00 Hz"
    assert rows["baseline, run 3"]["note"] == ""
    # A run without every node home has nothing to check: no flag.
    assert rows["always out"]["AMCL at home"] == "-" and rows["always out"]["note"] == ""
    # A note of the run's own stays, the flag joins it.
    broken = rows["optimal seed 1"]
    assert broken["note"] == "the loop was not completed; premise off: AMCL 5.0 Hz at home"
    assert "| baseline, run 2 |" in format_markdown(figures, "E")
    assert "premise off: AMCL 3.0 Hz at home" in format_markdown(figures, "E")
    write_csv(str(tmp_path / "e.csv"), figures)
    with open(tmp_path / "e.csv") as f:
        csv_rows = {r["run"]: r for r in csv.DictReader(f)}
    assert csv_rows["baseline, run 2"]["premise_off"] == "1"
    assert csv_rows["baseline, run 3"]["premise_off"] == "0"
    assert csv_rows["always out"]["premise_off"] == ""
    assert csv_rows["baseline, run 2"]["amcl_hz_every_node_home"] == "3.0000"
