"""`anyscale profile`, the ROS part: runs profile_plan.py's windows through the agents
(agent_session_ros.py), reads each node's CPU from the agents' status and counts its output
rates, then writes the figures into the model (model_update.py) and prints them.

The CPU figures are the agents' own /proc samples (NodeProcess.cpu_percent), the numbers the
decision node sees at run time, rather than a second sampler of our own: psutil here would see
only this machine's processes, not the laptop's. Output rates are counted by this command
(model_draft_ros.RateCounter), so a figure says at which rate the node ran on that scale.
"""
import datetime
import json
import sys
import time
from typing import List, Optional, Sequence

from .agent_session_ros import AgentSession, check_running
from .model_draft_ros import RateCounter
from .model_loader import read_yaml
from .model_todos import load_model_with_todos
from .model_update import update_model_text, write_text_atomically
from .profile_plan import (Measurement, describe_measurement, format_duration, measurements_json,
                           memory_figures, plan_profile, predict_seconds, profile_edits,
                           summarise)
from .progress import TimeProgress

CALLER = "/anyscale_profile"


def run(model_path: str, nodes: Optional[Sequence[str]], warmup_s: float, window_s: float,
        lease_s: float, start_timeout_s: float, dry_run: bool, as_json: bool) -> int:
    loaded = load_model_with_todos(model_path)
    model = loaded.model
    plan = plan_profile(model, nodes)
    session = AgentSession(model, CALLER, lease_s=lease_s, start_timeout_s=start_timeout_s)
    progress: Optional[TimeProgress] = None
    measurements: List[Measurement] = []
    counter = None
    say = (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        session.open(plan.scales_needed)
        to_start = [n for n in model.node_names if n not in session.initial]
        predicted = predict_seconds(plan, warmup_s, window_s, len(to_start))
        moves = plan.moves
        say(f"anyscale profile: {len(plan.windows)} windows (every node at home"
            + (f", then {moves} with one node moved" if moves else "") + f"), each {warmup_s:g} s "
            f"warm-up + {window_s:g} s measured; {len(to_start)} nodes to start; predicted "
            f"{format_duration(predicted)}")
        for node, scale, why in plan.skipped:
            say(f"  not measured: {node} on {scale} ({why})")
        progress = TimeProgress(predicted)
        session.tick = progress.tick
        session.bring_home(on_start=lambda n, s: progress.phase(f"starting {n} on {s}"))
        outputs = sorted({t for w in plan.windows for n, _ in w.measures
                          for t in model.output_topics(n)})
        counter = RateCounter(outputs)
        for window in plan.windows:
            if window.moved is not None:
                progress.phase(f"moving {window.moved} to {window.scale}")
                session.move(window.moved, window.scale)
            progress.phase(f"{window.describe()}: warm-up")
            progress.sleep(warmup_s)
            progress.phase(f"{window.describe()}: measuring")
            session.record(True)
            counter.open()
            start = time.monotonic()
            progress.sleep(window_s)
            end = time.monotonic()
            rates = counter.close()
            session.record(False)
            for node, scale in window.measures:
                check_running(session, node, scale)
                instance = model.instance_name(node, scale)
                own = {topic: r.hz for (topic, publisher), r in rates.items()
                       if publisher == instance and topic in model.output_topics(node)}
                own.update({t: 0.0 for t in model.output_topics(node) if t not in own})
                m = summarise(session.samples(), node, scale, start, end, own)
                measurements.append(m)
                progress.write(f"  {m.node:<16} {describe_measurement(m)}")
            if window.moved is not None:
                progress.phase(f"moving {window.moved} home to {session.home[window.moved]}")
                session.move(window.moved, session.home[window.moved])
    finally:
        if counter is not None:
            counter.unregister()
        if progress is not None:
            progress.phase("stopping what was started")
        problems = session.close(log=say)
        if progress is not None:
            progress.close()
        for problem in problems:
            say(f"anyscale profile: warning: {problem}")

    when = datetime.datetime.now()
    written = False
    if not dry_run:
        # Read again now: the file may have been edited while the system was measured.
        with open(model_path, encoding="utf-8") as f:
            text = f.read()
        numbers, comments = profile_edits(read_yaml(model_path), measurements, when, warmup_s,
                                          window_s)
        write_text_atomically(model_path, update_model_text(text, numbers, comments,
                                                            model_path))
        written = True
    if as_json:
        print(json.dumps({"model": model_path, "measured_at": when.isoformat(timespec="seconds"),
                          "warmup_s": warmup_s, "window_s": window_s,
                          "measurements": measurements_json(measurements),
                          "memory_mb": memory_figures(measurements),
                          "not_measured": [{"node": n, "scale": s, "why": w}
                                           for n, s, w in plan.skipped],
                          "written": written}, indent=2))
        return 0
    print(f"{'NODE':<16} {'SCALE':<10} {'CPU_USAGE':>9}  {'% OF ONE CORE':>14}  {'RSS':>7}  "
          "OUTPUT")
    for m in measurements:
        rates = ", ".join(f"{t} {hz:.1f} Hz" for t, hz in sorted(m.output_rates.items())) or "-"
        print(f"{m.node:<16} {m.scale:<10} {m.cpu_usage:>7.1f} %  {m.cpu_one_core:>6.1f} ± "
              f"{m.cpu_sd:<5.1f}  {m.rss_mb:>4.0f} MB  {rates}")
    print(f"{model_path}: " + ("cpu_usage and memory_mb written, with how they were measured"
                               if written else "not changed (--dry-run)"))
    return 0
