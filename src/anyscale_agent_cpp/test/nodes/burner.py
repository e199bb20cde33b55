#!/usr/bin/python3
"""Test fixture node (rospy): keeps ~fraction of one core busy (busy loop with a duty cycle),
in a worker thread, so CPU accounting must cover the whole process, not just its main thread."""
import threading
import time

import rospy


def burn(fraction, stop):
    period = 0.01
    while not stop.is_set():
        start = time.monotonic()
        while time.monotonic() - start < fraction * period:
            pass
        time.sleep(max(0.0, period - (time.monotonic() - start)))


def main():
    rospy.init_node("burner")
    fraction = float(rospy.get_param("~fraction", 0.5))
    stop = threading.Event()
    worker = threading.Thread(target=burn, args=(fraction, stop), daemon=True)
    worker.start()
    rospy.spin()
    stop.set()


if __name__ == "__main__":
    main()
