"""How long each node ran on each scale (scale_times.py) and the end table's lines of it: shown
on three scales, and the two-scale table as it was. Synthetic records, no ROS."""
from anyscale_testbed.scale_times import scale_time_lines, time_per_scale
from anyscale_testbed.testbed_figures import format_summary
from anyscale_testbed.testbed_record import TestbedRecord

THREE = ["robot", "laptop", "server"]


def on(amcl="robot", ar="robot"):
    return {"amcl": amcl, "ar_recognition": ar, "navigation": "robot"}


def record(scales, mappings, finished_t=200.0):
    return TestbedRecord(world="office_floor", link="coverage", finished_t=finished_t,
                         mappings=[(t, m, 100.0, 0.0) for t, m in mappings],
                         outputs={"amcl": "/amcl_pose", "ar_recognition": "/ar_markers"},
                         tolerances={"/amcl_pose": 2.0, "/ar_markers": 1.0},
                         scales=list(scales))


MOVES = [(10.0, on()), (40.0, on(amcl="server")), (55.0, on(amcl="server", ar="laptop")),
         (55.0, on(amcl="server", ar="laptop")),          # published again, nothing moved
         (120.0, on(ar="laptop")), (150.0, on())]


def test_each_node_s_seconds_on_each_scale_from_the_first_mapping_to_the_end():
    times = time_per_scale(record(THREE, MOVES), 200.0)
    assert times["amcl"] == {"robot": 30.0 + 80.0, "server": 80.0}
    assert times["ar_recognition"] == {"robot": 45.0 + 50.0, "laptop": 95.0}
    assert times["navigation"] == {"robot": 190.0}
    assert all(sum(per.values()) == 190.0 for per in times.values())


def test_mappings_after_the_end_do_not_count_and_the_last_runs_to_it():
    times = time_per_scale(record(THREE, MOVES + [(250.0, on(amcl="laptop"))]), 200.0)
    assert "laptop" not in times["amcl"]
    assert time_per_scale(record(THREE, MOVES), 130.0)["amcl"] == {"robot": 40.0, "server": 80.0}
    assert time_per_scale(record(THREE, []), 200.0) == {}


def test_the_end_table_shows_a_row_per_moving_node_and_a_column_per_scale():
    lines = scale_time_lines(record(THREE, MOVES), 200.0)
    assert lines == [
        "time per scale (the decision node's mapping, t=10.0 to 200.0 s):",
        "  node                 robot    laptop    server",
        "  amcl                 110 s         -      80 s",
        "  ar_recognition        95 s      95 s         -"]
    assert "\n".join(lines) in format_summary(record(THREE, MOVES), {}, {})


def test_a_node_that_never_left_the_robot_still_has_its_row_if_it_may_move():
    lines = scale_time_lines(record(THREE, [(10.0, on(amcl="laptop"))]), 200.0)
    assert [line.split()[0] for line in lines[2:]] == ["amcl", "ar_recognition"]
    assert lines[3].split()[1:] == ["190", "s", "-", "-"]


def test_two_scales_and_older_records_keep_the_table_as_it_was():
    two = [(10.0, on()), (40.0, on(amcl="laptop")), (150.0, on())]
    assert scale_time_lines(record(["robot", "laptop"], two), 200.0) == []
    assert scale_time_lines(record([], two), 200.0) == []
    assert scale_time_lines(record(THREE, []), 200.0) == []
    table = format_summary(record(["robot", "laptop"], two), {}, {})
    assert "time per scale" not in table
    assert table == format_summary(record([], two), {}, {})


def test_the_record_keeps_its_scales(tmp_path):
    path = str(tmp_path / "record.json")
    record(THREE, MOVES).save(path)
    assert TestbedRecord.load(path).scales == THREE
