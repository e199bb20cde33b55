"""AnyScale test-bed navigation demo: pure numpy/scipy algorithms (no ROS imports here)."""
import os

# The nodes' matrices are tiny; OpenBLAS worker threads only busy-wait between calls (one
# spun a whole core in the EKF). Must run before numpy is first imported.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
