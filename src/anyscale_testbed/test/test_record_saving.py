"""The monitor's periodic save of a long record (testbed_record.save_record) holds the record's
lock only for a copy. The monitor's receive threads take that lock to note each message's
arrival; held for the whole save (0.4 s for a 12-minute record here), every message that came
meanwhile waited in its socket and was noted late: a silence of every recorded topic, every 5
s. /odom's limit is 0.3 s and /joint_states' 0.2 s: a 10-minute soak would have found them
silent, falsely."""
import threading

from anyscale_testbed.testbed_record import ProcessSample, TestbedRecord, save_record

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


def test_a_long_record_is_written_whole_with_the_lock_free(tmp_path, monkeypatch):
    rec, lock = long_record(12), threading.Lock()
    path = str(tmp_path / "record.json")
    held_while_writing = []
    write = TestbedRecord.save

    def save_noting_the_lock(self, where):
        held_while_writing.append(lock.locked())
        write(self, where)
    monkeypatch.setattr(TestbedRecord, "save", save_noting_the_lock)
    save_record(rec, lock, path)
    assert held_while_writing == [False]
    again = TestbedRecord.load(path)
    assert again.receipts == rec.receipts
    assert again.master_publishers == [list(p) for p in rec.master_publishers]
    assert len(again.processes) == len(rec.processes)


def test_the_copy_saved_is_the_record_at_the_moment_of_the_save(tmp_path):
    rec, lock = long_record(0.1), threading.Lock()
    path = str(tmp_path / "record.json")
    copy = rec.snapshot()
    rec.receipts["/odom"].append(99.0)
    rec.processes.append(ProcessSample(99.0, False, {}, []))
    assert copy.receipts["/odom"][-1] != 99.0 and len(copy.processes) == len(rec.processes) - 1
    save_record(rec, lock, path)
    assert TestbedRecord.load(path).receipts["/odom"][-1] == 99.0
