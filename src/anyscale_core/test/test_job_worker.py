"""JobWorker: submit() never waits for a job; jobs run one at a time in the order submitted; a
keyed job replaces the pending job of its key (only the latest lease renewal, watch list or
AMCL pose is sent); a failed job is reported and the next one still runs; close() runs what is
pending and ends the thread. No ROS.

No sleep times anything: a first job holds the thread on an Event while the test submits the
rest, so they are all pending; the timeouts only keep a broken worker from hanging the run."""
import os
import subprocess
import sys
import threading

import pytest

from anyscale_core.job_worker import JobWorker

WAIT_S = 10.0


def never_fails(e, key):
    raise AssertionError(f"unexpected job error {e!r} (key {key!r})")


class Held:
    """A first job that holds the worker's thread until release()."""

    def __init__(self, worker, done):
        self.started, self._release, self._done = threading.Event(), threading.Event(), done
        worker.submit(self._run)
        assert self.started.wait(WAIT_S), "the worker never started the first job"

    def _run(self):
        self.started.set()
        assert self._release.wait(WAIT_S)
        self._done.append("held")

    def release(self):
        self._release.set()


def test_jobs_run_in_the_order_submitted_and_unkeyed_jobs_never_replace_each_other():
    done = []
    worker = JobWorker("test_order", never_fails)
    held = Held(worker, done)
    for i in range(5):
        worker.submit(lambda i=i: done.append(i))
    assert worker.pending() == 5
    held.release()
    assert worker.close(WAIT_S)
    assert done == ["held", 0, 1, 2, 3, 4]


def test_submit_returns_while_a_job_is_still_running():
    done = []
    worker = JobWorker("test_no_wait", never_fails)
    held = Held(worker, done)
    worker.submit(lambda: done.append("next"))     # returns although "held" has not ended
    assert done == []
    held.release()
    assert worker.close(WAIT_S)
    assert done == ["held", "next"]


def test_a_keyed_job_replaces_the_pending_job_of_its_key_and_goes_to_the_back():
    done = []
    worker = JobWorker("test_keys", never_fails)
    held = Held(worker, done)
    worker.submit(lambda: done.append("renew laptop 1"), key="laptop")
    worker.submit(lambda: done.append("renew server 1"), key="server")
    worker.submit(lambda: done.append("move"))
    worker.submit(lambda: done.append("renew laptop 2"), key="laptop")
    worker.submit(lambda: done.append("renew laptop 3"), key="laptop")
    assert worker.pending() == 3
    held.release()
    assert worker.close(WAIT_S)
    assert done == ["held", "renew server 1", "move", "renew laptop 3"]


def test_a_running_keyed_job_is_not_replaced_only_the_latest_pending_one_runs_after_it():
    """AMCL's pose saver: poses offered while one is being written; the written one is not
    undone, of the ones offered meanwhile only the latest is written."""
    written, started, release = [], threading.Event(), threading.Event()

    def save(pose):
        if pose == 1:
            started.set()
            assert release.wait(WAIT_S)
        written.append(pose)
    worker = JobWorker("test_latest", never_fails)
    worker.submit(lambda: save(1), key="pose")
    assert started.wait(WAIT_S)
    worker.submit(lambda: save(2), key="pose")
    worker.submit(lambda: save(3), key="pose")
    assert written == []
    release.set()
    assert worker.close(WAIT_S)
    assert written == [1, 3]


def test_a_caller_key_never_equals_an_unkeyed_job():
    """The worker's own keys for unkeyed jobs are not values a caller can pass."""
    done = []
    worker = JobWorker("test_key_space", never_fails)
    held = Held(worker, done)
    worker.submit(lambda: done.append("unkeyed"))
    for key in (("seq", 1), ("seq", 2), 1, 2, 0):
        worker.submit(lambda key=key: done.append(key), key=key)
    held.release()
    assert worker.close(WAIT_S)
    assert done == ["held", "unkeyed", ("seq", 1), ("seq", 2), 1, 2, 0]


def test_a_failed_job_is_reported_with_its_key_and_later_jobs_still_run():
    errors, done = [], []
    worker = JobWorker("test_errors", lambda e, key: errors.append((str(e), key)))
    held = Held(worker, done)

    def fail(message):
        raise OSError(message)
    worker.submit(lambda: fail("master gone"), key="pose")
    worker.submit(lambda: fail("agent gone"))
    worker.submit(lambda: done.append("good"))
    held.release()
    assert worker.close(WAIT_S)
    assert errors == [("master gone", "pose"), ("agent gone", None)]
    assert done == ["held", "good"]


def test_a_failing_error_callback_does_not_end_the_worker():
    done = []

    def on_error(e, key):
        raise RuntimeError("the logger broke")
    worker = JobWorker("test_bad_callback", on_error)
    worker.submit(lambda: 1 / 0)
    worker.submit(lambda: done.append("after"))
    assert worker.close(WAIT_S)
    assert done == ["after"]


def test_close_runs_what_is_pending_ends_the_thread_and_refuses_later_jobs():
    done = []
    worker = JobWorker("test_close", never_fails)
    held = Held(worker, done)
    worker.submit(lambda: done.append("a"), key="k")
    closing = threading.Thread(target=worker.close, args=(WAIT_S,))
    closing.start()
    held.release()
    closing.join(WAIT_S)
    assert not closing.is_alive()
    assert done == ["held", "a"]
    assert worker.close(WAIT_S)                 # already ended: says so at once
    with pytest.raises(RuntimeError):
        worker.submit(lambda: done.append("late"))
    assert done == ["held", "a"]


def test_close_with_a_timeout_says_whether_the_thread_ended():
    done = []
    worker = JobWorker("test_close_timeout", never_fails)
    held = Held(worker, done)
    assert not worker.close(0.0)                # the held job is still running
    held.release()
    assert worker.close(WAIT_S)


def test_the_thread_is_a_daemon_named_as_given():
    """A daemon: neither the decision node nor AMCL stops its workers, the process's end does."""
    worker = JobWorker("anyscale_laptop", never_fails)
    names = {t.name: t.daemon for t in threading.enumerate()}
    assert names.get("anyscale_laptop") is True
    assert worker.close(WAIT_S)


def test_the_module_imports_without_ros():
    code = ("import sys, anyscale_core.job_worker; "
            "ros = sorted(m for m in sys.modules if m.split('.')[0] in "
            "('rospy', 'rosgraph', 'roslib', 'genpy', 'anyscale_msgs')); "
            "assert not ros, ros")
    src = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [src] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
