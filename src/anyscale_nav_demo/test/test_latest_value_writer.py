"""LatestValueWriter: offers never wait for a write, and only the latest offer is written."""
import threading

from anyscale_nav_demo.latest_value_writer import LatestValueWriter


def test_an_offer_returns_while_a_write_is_still_running():
    started, release, written = threading.Event(), threading.Event(), []

    def slow_write(value):
        started.set()
        release.wait(5.0)
        written.append(value)
    writer = LatestValueWriter(slow_write, on_error=lambda e: None)
    writer.offer(1)
    assert started.wait(5.0)
    writer.offer(2)                     # returns although the write of 1 has not ended
    writer.offer(3)
    assert written == []
    release.set()
    writer.stop(5.0)
    assert written == [1, 3]            # 2 was replaced by 3 before it could be written


def test_stop_writes_what_is_pending_and_ends_the_thread():
    written = []
    writer = LatestValueWriter(written.append, on_error=lambda e: None)
    writer.offer("a")
    writer.stop(5.0)
    assert written == ["a"]
    assert not writer._thread.is_alive()


def test_a_failed_write_is_reported_and_later_offers_are_still_written():
    errors, written, reported = [], [], threading.Event()

    def write(value):
        if value == "bad":
            raise OSError("master gone")
        written.append(value)

    def on_error(e):
        errors.append(e)
        reported.set()
    writer = LatestValueWriter(write, on_error)
    writer.offer("bad")
    assert reported.wait(5.0)
    writer.offer("good")
    writer.stop(5.0)
    assert [str(e) for e in errors] == ["master gone"] and written == ["good"]
