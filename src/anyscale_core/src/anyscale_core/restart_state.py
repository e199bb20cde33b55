"""What a restarted decision node must remember of the one before it, as plain data (pure
Python, no ROS): the decision engine's holds in time, encoded with wall-clock times.

Why. The paper's hysteresis says that a node brought home is not moved out again for T
(hysteresis_s), and after a link loss no node moves out until the link has been up for its
hold after a loss (hold_after_loss_s, node_hold_after_loss_s). Both are times the engine keeps
in memory: when each node was last brought home (DecisionEngine.migrated_back_at) and when the
link was last seen down (BandwidthHold).
The decision node is restarted when it dies (its warm standby forks a new one, or roslaunch
respawns it), and a new engine that knows neither moves nodes out again as soon as the link
has shown its bandwidth for bandwidth_hold_s (5 s): inside T, and inside the hold after a loss.

What. Only what a hold needs, each entry only while the hold it feeds still runs:
- `migrated_back_at`: node -> when it was last brought home, while younger than T;
- `link_lost_at`: when the link to a remote scale was last seen down, while younger than
  the longest hold after a loss;
- `mapping` (node -> scale) with `saved_at`: a node that was out when the old decision node
  died and that the new one finds back home (its lease ran out while nobody renewed it) or
  starts at home was brought home by the restart: it is held for T from then. `saved_at` is
  refreshed while nodes are out (decision_ros: STATE_REFRESH_S), so that it says the mapping
  was still current then.
Nothing else: the engine's start-up (adopt_or_start) gives every node a fresh start-up grace
(moved_at) and watches the link's bandwidth for bandwidth_hold_s before any move out, both
safe sides to err on; restart back-offs and rate trackers start afresh as for a new node.

Clocks. The engine runs on a monotonic clock, which does not carry across processes: times are
stored as wall-clock (time.time()) and converted back with the new process's pair (wall, engine
now). A stored time in the future (the wall clock stepped back) counts as now: its hold runs in
full, on the safe side. A state saved longer ago than the longest hold it could feed (T, the
longest hold after a loss) is ignored as a whole: a restart that slow (or a state left by an
earlier run) holds nothing any more.

Malformed state (not JSON, another version, a time that is no number) raises
RestartStateError with what was wrong; the engine then starts fresh (DecisionEngine.
restore_saved_state), as a new decision node always did."""
from dataclasses import dataclass, field, replace
import json
import math
from typing import Dict, Mapping, Optional

STATE_VERSION = 1


class RestartStateError(ValueError):
    """A saved state that cannot be read; the message says what is wrong with it."""


@dataclass(frozen=True)
class RestartState:
    """The engine's holds, on the engine's clock (s)."""
    saved_at: float
    mapping: Mapping[str, str] = field(default_factory=dict)
    migrated_back_at: Mapping[str, float] = field(default_factory=dict)
    link_lost_at: Optional[float] = None


def worth_writing(state: RestartState, written: Optional[RestartState], out: bool,
                  since_written_s: float, refresh_s: float) -> bool:
    """Whether `state` should replace `written`, the state last stored (None: nothing yet),
    stored `since_written_s` ago: when what it holds changed, and every `refresh_s` while nodes
    are `out` (saved_at then says the mapping was current). A loss time that only moved on by
    less than refresh_s is no change: while the link stays down it moves on every tick, and
    written each tick it cost the robot 3 parameter writes a second for as long as the link
    was down, when the robot does all the work; a restart loses at most refresh_s of a hold
    after a loss, and a link still down is seen down afresh at once."""
    if written is None:
        return True
    if out and since_written_s >= refresh_s:
        return True
    new, old = state.link_lost_at, written.link_lost_at
    if new is not None and old is not None and new - old < refresh_s:
        state = replace(state, link_lost_at=old)
    return replace(state, saved_at=0.0) != replace(written, saved_at=0.0)


def encode(state: RestartState, wall_now: float, now: float) -> str:
    """JSON, times on the wall clock (rounded to 10 ms: an unchanged state encodes the same)."""
    def wall(t: float) -> float:
        return round(wall_now - (now - t), 2)
    return json.dumps({"version": STATE_VERSION,
                       "saved_at": wall(state.saved_at),
                       "mapping": dict(sorted(state.mapping.items())),
                       "migrated_back_at": {n: wall(t)
                                            for n, t in sorted(state.migrated_back_at.items())},
                       "link_lost_at": None if state.link_lost_at is None
                       else wall(state.link_lost_at)},
                      sort_keys=True)


def decode(text, wall_now: float, now: float) -> RestartState:
    """The state `encode` wrote, on this process's engine clock; RestartStateError if it is
    not one."""
    if not isinstance(text, str):
        raise RestartStateError(f"expected a JSON string, got {type(text).__name__}")
    try:
        data = json.loads(text)
    except ValueError as e:
        raise RestartStateError(f"not JSON ({e})") from None
    if not isinstance(data, dict):
        raise RestartStateError(f"expected a JSON object, got {type(data).__name__}")
    if data.get("version") != STATE_VERSION:
        raise RestartStateError(f"version {data.get('version')!r}, this node reads "
                                f"{STATE_VERSION}")

    def engine_time(value, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise RestartStateError(f"{key}: expected a wall-clock time in s, got {value!r}")
        return now - max(0.0, wall_now - float(value))    # a future time counts as now

    def table(key: str) -> dict:
        value = data.get(key, {})
        if not isinstance(value, dict):
            raise RestartStateError(f"{key}: expected an object, got {value!r}")
        return value

    mapping = table("mapping")
    bad = {n: s for n, s in mapping.items() if not isinstance(s, str)}
    if bad:
        raise RestartStateError(f"mapping: expected scale names, got {bad!r}")
    back: Dict[str, float] = {n: engine_time(t, f"migrated_back_at.{n}")
                              for n, t in table("migrated_back_at").items()}
    lost = data.get("link_lost_at")
    return RestartState(engine_time(data.get("saved_at"), "saved_at"), dict(mapping), back,
                        None if lost is None else engine_time(lost, "link_lost_at"))
