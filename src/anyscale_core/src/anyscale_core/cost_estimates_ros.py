"""The decision node's live cost estimates out (rospy): latched on /anyscale/cost_estimates for
`anyscale top` and the test bed's record, and into ~learned_costs_out for `anyscale profile
--from-run`. What they are is placement_learning.py's."""
import datetime
import threading
import time

import rospy
from anyscale_msgs.msg import CostEstimates

from . import ros_convert as conv
from .learned_costs import dump_learned
from .model import ModelError
from .model_update import write_text_atomically

# ~learned_costs_out is written this often while the node runs, and at its shutdown: a node
# killed (SIGKILL, a power cut) loses at most this much of a run's learning.
LEARNED_REFRESH_S = 30.0


class CostEstimatesOut:
    def __init__(self, engine, lock: threading.Lock, learned_costs_out: str, model_path: str,
                 worker):
        """`engine`'s learning is read under `lock`; files are written on `worker` (a
        job_worker) so that a slow disk holds no tick, and at shutdown."""
        self.engine, self.lock, self.worker = engine, lock, worker
        self.path, self.model_path = learned_costs_out, model_path
        self.pub = rospy.Publisher("/anyscale/cost_estimates", CostEstimates, queue_size=1,
                                   latch=True)
        self.sent = None
        self.written_at = time.monotonic()
        if self.path:
            rospy.on_shutdown(self.write)

    def publish(self):
        """The estimates and back-offs when they changed to the precision shown; the file every
        LEARNED_REFRESH_S."""
        with self.lock:
            rows = self.engine.learning.rows(time.monotonic())
        key = conv.cost_estimates_key(rows)
        if key != self.sent:
            self.sent = key
            self.pub.publish(conv.cost_estimates_msg(rows, rospy.Time.now()))
        if self.path and time.monotonic() - self.written_at >= LEARNED_REFRESH_S:
            self.written_at = time.monotonic()
            self.worker.submit(self.write, key="learned_costs")

    def write(self):
        with self.lock:
            rows = [r.cost for r in self.engine.learning.rows(time.monotonic())]
        try:
            write_text_atomically(self.path, dump_learned(rows, self.model_path,
                                                          datetime.datetime.now()))
        except ModelError as e:
            rospy.logwarn_throttle(60.0, f"anyscale decision: ~learned_costs_out: {e}")
