"""The monitor's periodic save of a long record (record_saver.py) is written by a child
process: the monitor's receive threads note each message's arrival, and a save in their own
process delayed their notes by a save's time (0.2-0.33 s in a 10-minute soak, more than
/joint_states' limit of 0.2 s). The copy saved is the record at the moment of the save, a save
never piles onto one still writing, and the last record is never replaced by a late save."""
import os
import threading
import time

from anyscale_testbed.record_saver import BackgroundSaver
from anyscale_testbed.testbed_record import ProcessSample, TestbedRecord

RATES = {"/joint_states": 40, "/scan": 10, "/odom": 10, "/odometry/filtered": 5,
         "/amcl_pose": 5, "/ar_markers": 20}


def long_record(minutes: float) -> TestbedRecord:
    """A record the size of a soak's after `minutes`."""
    span = minutes * 60
    rec = TestbedRecord(started_wall=1.0e9)
    rec.receipts = {t: [i / r for i in range(int(span * r))] for t, r in RATES.items()}
    rec.truth = [(i / 10, 1.0, 2.0) for i in range(int(span * 10))]
    rec.processes = [ProcessSample(i / 5, True, {"amcl": ["net:[1]"], "ekf": ["net:[1]"]}, [])
                     for i in range(int(span * 5))]
    rec.master_publishers = [(i / 5, {t: ["/a", "/b"] for t in RATES})
                             for i in range(int(span * 5))]
    return rec


def test_a_long_record_is_written_whole_by_a_child(tmp_path):
    rec = long_record(12)
    path = str(tmp_path / "record.json")
    saver = BackgroundSaver(path)
    assert saver.start(rec.snapshot())
    assert saver.child is not None and saver.child != os.getpid()
    saver.finish(rec)
    again = TestbedRecord.load(path)
    assert again.receipts == rec.receipts
    assert again.master_publishers == [list(p) for p in rec.master_publishers]
    assert len(again.processes) == len(rec.processes)
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]


def test_the_copy_saved_is_the_record_at_the_moment_of_the_save(tmp_path):
    rec, lock = long_record(0.1), threading.Lock()
    with lock:
        copy = rec.snapshot()
    rec.receipts["/odom"].append(99.0)
    rec.processes.append(ProcessSample(99.0, False, {}, []))
    assert copy.receipts["/odom"][-1] != 99.0 and len(copy.processes) == len(rec.processes) - 1
    saver = BackgroundSaver(str(tmp_path / "record.json"))
    saver.start(copy)
    while saver.busy():
        time.sleep(0.01)
    assert TestbedRecord.load(str(tmp_path / "record.json")).receipts["/odom"][-1] != 99.0


def test_a_save_waits_for_none_and_the_last_record_is_never_replaced(tmp_path, monkeypatch):
    path = str(tmp_path / "record.json")
    write = TestbedRecord.save

    def slow(self, where):
        time.sleep(1.0)             # in the child only: the parent writes its last record later
        write(self, where)
    monkeypatch.setattr(TestbedRecord, "save", slow)
    saver = BackgroundSaver(path)
    early = TestbedRecord(world="early")
    assert saver.start(early)
    assert not saver.start(TestbedRecord(world="skipped"))     # the first still writes
    monkeypatch.setattr(TestbedRecord, "save", write)
    saver.finish(TestbedRecord(world="last"))
    time.sleep(0.1)
    assert TestbedRecord.load(path).world == "last"
