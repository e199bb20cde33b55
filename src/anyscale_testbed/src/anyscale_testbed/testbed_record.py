"""What a test-bed run recorded: the record the monitor node fills (events, receipts of the
output topics, poses, link, processes), saved as JSON and loaded back, and the mapping in force
at a moment. Pure (no ROS): the system tests, the benchmarks and the end-of-run table read it;
the figures drawn from it are testbed_figures.py."""
from dataclasses import asdict, dataclass, field
import json
import os
from typing import Dict, List, Optional, Sequence, Tuple


# The decision node's private parameters a record keeps (evaluation_shortfall judges by them).
DECISION_PARAMS = ("hysteresis_s", "bandwidth_hold_s", "weak_link_mbps", "hold_after_loss_s",
                   "node_hold_after_loss_s", "link_forecast")

# What a move was, from its event (the decision node's reasons say it): a move out; a return
# after the link was lost (the new instance started at home, the old one beyond reach); a return
# planned before a hole the link map foresaw; any other return (the bandwidth or weak-link rule,
# a connection's tolerance, the remote scale's CPU: planned, make before break).
MOVE_OUT, LINK_LOSS_RETURN, LINK_AHEAD_RETURN, OTHER_RETURN = (
    "move out", "link-loss return", "planned return (link ahead)", "other return")
MOVE_KINDS = (MOVE_OUT, LINK_LOSS_RETURN, LINK_AHEAD_RETURN, OTHER_RETURN)
# The decision node's diagnostic status of the link forecast ("<node>: link ahead").
LINK_AHEAD_STATUS = "link ahead"


@dataclass
class EventRecord:
    t: float                # monitor clock (s since the run started) when it was received
    kind: str               # start, migrate, migrate_back, adopt, failed, restart
    node: str
    from_scale: str
    to_scale: str
    reason: str
    duration_s: float       # decision -> new instance registered; NaN if it was not
    success: bool
    decided_t: float        # when the decision was taken (the event's stamp), monitor clock


@dataclass
class ProcessSample:
    t: float
    link_up: bool                           # the modelled WiFi at that moment
    instances: Dict[str, List[str]]         # node -> network namespace of each live process
    paused: List[str] = field(default_factory=list)  # instance names paused (SIGSTOP), e.g. /amcl


@dataclass
class Violation:
    """A connection's output topic silent for longer than its tolerance Δ."""
    topic: str
    start_t: float          # its last message before the silence (monitor clock)
    end_t: float            # its first message after it, or the run's end if none came
    silence_s: float
    tolerance_s: float
    cause: str              # the moves, restarts and link changes around it, in words


@dataclass
class TestbedRecord:
    __test__ = False        # not a pytest class
    started_wall: float = 0.0
    world: str = ""
    link: str = ""
    mappings: List[Tuple[float, Dict[str, str], float, float]] = field(default_factory=list)
    events: List[EventRecord] = field(default_factory=list)
    receipts: Dict[str, List[float]] = field(default_factory=dict)    # topic -> receive times
    # topic -> (receive time, sending node) of each message whose sender differs from the one
    # before it: the instances' names tell the robot's from the laptop's (a move's handover).
    senders: Dict[str, List[Tuple[float, str]]] = field(default_factory=dict)
    truth: List[Tuple[float, float, float]] = field(default_factory=list)     # t, x, y
    estimate: List[Tuple[float, float, float]] = field(default_factory=list)  # AMCL's t, x, y
    bandwidth: List[Tuple[float, float]] = field(default_factory=list)  # t, modelled Mbit/s
    processes: List[ProcessSample] = field(default_factory=list)
    master_publishers: List[Tuple[float, Dict[str, List[str]]]] = field(default_factory=list)
    navigation_status: List[Tuple[float, str]] = field(default_factory=list)
    finished_t: Optional[float] = None
    # Why the monitor ended: "done" (navigation's loops), "duration", or "shutdown" (the ROS
    # system went down first: a required node of the world died, or the run was stopped).
    ended_by: str = ""
    outputs: Dict[str, str] = field(default_factory=dict)         # node -> its output topic
    tolerances: Dict[str, float] = field(default_factory=dict)    # output topic -> Δ in s
    # output topic -> the subscriber nodes of its judged connections: a connection exists, and
    # its silences count, once its subscribers have started (testbed_figures.judged_from).
    # Empty in older records: their outputs are judged from the first message on.
    subscribers: Dict[str, List[str]] = field(default_factory=dict)
    # The topics of critical connections (Δ 0) -> the highest freq_min among them, when the
    # monitor records their receipts too (~record_critical, the fault soak); else empty.
    critical_freq_min: Dict[str, float] = field(default_factory=dict)
    # Those topics' messages that carry a header -> (receive time, header stamp), both on this
    # record's clock: a silence is then told as made late (the stamps are as far apart) or
    # delivered late. Empty in older records and without ~record_critical.
    stamps: Dict[str, List[Tuple[float, float]]] = field(default_factory=dict)
    # silences longer than their tolerance: testbed_figures.tolerance_violations
    violations: List[Violation] = field(default_factory=list)
    # Ground truth's heading at truth's samples (t, yaw rad), for the mean |omega| of the
    # paper's Fig. 6, and the ids of the AR markers recognised during the run.
    truth_yaw: List[Tuple[float, float]] = field(default_factory=list)
    markers_seen: List[int] = field(default_factory=list)
    # run_testbed.py --normalise-cpu (host_speed.py): each period's (t, robot cores, laptop
    # cores, median CPU ms of the host-speed workload), t on this record's clock, and the
    # calibration's reference_cpu_ms. Empty / None: the quotas stayed the calibrated ones.
    cpu_normalisation: List[Tuple[float, float, float, float]] = field(default_factory=list)
    reference_cpu_ms: Optional[float] = None
    # Inputs of the moving nodes whose receipts are in `receipts` too (the monitor's
    # ~record_inputs): a silence's cause then says whether they kept coming.
    inputs: List[str] = field(default_factory=list)
    # run_testbed.py was stopped (Ctrl-C, SIGTERM) before the run ended by itself: the record
    # holds what ran until then, and no bench resumes from it (bench_runs.latest_record).
    interrupted: bool = False
    # The decision node's parameters the run's figures are judged by (DECISION_PARAMS, read
    # from the parameter server when its first mapping came); empty in older records.
    decision_params: Dict[str, object] = field(default_factory=dict)
    # Each scale's CPU as its agent reported it (ScaleStatus.cpu_percent: % of its quota, else
    # of all its cores), (t, %) on this record's clock: a silence's cause then says whether the
    # scale that ran the node was at its limit. Empty in older records.
    scale_cpu: Dict[str, List[Tuple[float, float]]] = field(default_factory=dict)
    # The decision node's live CPU cost estimates as it last published them
    # (/anyscale/cost_estimates): per node and scale, the model's figure, the live estimate,
    # the estimate when last learned there and from how many reports, whether that is a lower
    # bound, returns for rate or CPU in a row. Empty in older records.
    cost_estimates: List[Dict[str, object]] = field(default_factory=list)
    # The model's scales, master first (the monitor's ~model): the end table's time per scale
    # is shown on three or more (scale_times.py). Empty in older records.
    scales: List[str] = field(default_factory=list)
    # The decision node's "link ahead" diagnostics where they changed: (t, its summary, whether
    # some remote scale had a forecast). Empty in older records.
    link_ahead: List[Tuple[float, str, bool]] = field(default_factory=list)

    def save(self, path: str):
        with open(path, "w") as f:
            json.dump(asdict(self), f, allow_nan=True)

    def snapshot(self) -> "TestbedRecord":
        """A copy of the record as it is, made in a few ms for a long one: every list and
        dict of lists copied, their items shared (the monitor appends items, never changes
        one)."""
        copy = {}
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, list):
                value = list(value)
            elif isinstance(value, dict):
                value = {k: list(v) if isinstance(v, list) else v for k, v in value.items()}
            copy[name] = value
        return TestbedRecord(**copy)

    @staticmethod
    def load(path: str) -> "TestbedRecord":
        with open(path) as f:
            d = json.load(f)
        rec = TestbedRecord(**{k: v for k, v in d.items()
                               if k not in ("events", "processes", "violations")})
        rec.events = [EventRecord(**e) for e in d["events"]]
        rec.violations = [Violation(**v) for v in d.get("violations", [])]
        rec.processes = [ProcessSample(**p) for p in d["processes"]]
        rec.mappings = [(t, m, p, o) for t, m, p, o in d["mappings"]]
        rec.cpu_normalisation = [tuple(e) for e in d.get("cpu_normalisation", [])]
        return rec


def store_cpu_normalisation(path: str, history: Sequence[Tuple[float, float, float, float]],
                            reference_cpu_ms: Optional[float]):
    """Adds the quotas' history (wall-clock t, as host_speed.CpuNormaliser keeps it) to the
    record at `path`, on the record's clock. run_testbed.py calls it after the monitor, which
    writes the record, has ended; written whole and then renamed, as the monitor does."""
    rec = TestbedRecord.load(path)
    rec.cpu_normalisation = [(t - rec.started_wall, robot, laptop, ms)
                             for t, robot, laptop, ms in history]
    rec.reference_cpu_ms = reference_cpu_ms
    _replace(rec, path)


def mark_interrupted(path: str):
    """Notes in the record at `path` that its run was stopped before it ended by itself;
    called, like store_cpu_normalisation, once the monitor has ended."""
    rec = TestbedRecord.load(path)
    rec.interrupted = True
    _replace(rec, path)


def _replace(rec: TestbedRecord, path: str):
    tmp = path + ".tmp"
    rec.save(tmp)
    os.replace(tmp, path)


def kind_of_move(e: EventRecord) -> str:
    """MOVE_KINDS of a migrate or migrate_back event ("" for any other event)."""
    if e.kind == "migrate":
        return MOVE_OUT
    if e.kind != "migrate_back":
        return ""
    if e.reason.startswith("link to"):
        return LINK_LOSS_RETURN
    return LINK_AHEAD_RETURN if e.reason.startswith("link ahead") else OTHER_RETURN


def mapping_at(rec: TestbedRecord, t: float) -> Dict[str, str]:
    current: Dict[str, str] = {}
    for when, mapping, _, _ in rec.mappings:
        if when > t:
            break
        current = mapping
    return current
