"""What the test bed's system tests run as on this host, and the one reason they may not run
(issue 41), pure: the conftest.py files of anyscale_testbed's tests call it.

A test that needs the test bed runs, or skips only where this machine cannot run it (no root,
namespaces or cgroups; a host slower than the slow-day mode covers). Such a skip's reason starts
with NOT_RUN, which the conftest counts into one loud line of pytest's summary; with
ANYSCALE_REQUIRE_SYSTEM_TESTS=1 it fails instead (a release check)."""
from dataclasses import dataclass
import math
from typing import List, Mapping, Optional, Sequence

from .host_speed import REFERENCE_IDLE_MS, host_factor

NOT_RUN = "SYSTEM TEST NOT RUN: "
REQUIRE_ENV = "ANYSCALE_REQUIRE_SYSTEM_TESTS"
EMULATE_ENV = "ANYSCALE_EMULATED_HOST_FACTOR"
# The slowest host the slow-day mode was validated for, as a factor of the reference day: the
# fixed-quota system tests pass on an emulated host 3 x slower and fail at 4.5 x, where a node's
# own start-up, which the mode cannot scale, outlasts its Δ
# (docs/measurements/2026-11-28-slow-host.md).
MAX_HOST_FACTOR = 3.0


def required(env: Mapping[str, str]) -> bool:
    return env.get(REQUIRE_ENV, "") not in ("", "0")


@dataclass(frozen=True)
class HostMode:
    """How the fixed-quota system tests run here: as on a host `factor` times slower than the
    reference day (the slow-day mode), on this host slowed down `slowdown` times (an
    emulation, 1 = none)."""
    idle_ms: float          # this host's idle reading of host_speed's workload
    factor: float
    slowdown: float = 1.0

    def argv(self) -> List[str]:
        """run_testbed.py's and bench_fault_soak.py's options for it."""
        return (["--host-factor", f"{self.factor:.3f}"]
                + (["--emulate-slow-host", f"{self.slowdown:.3f}"] if self.slowdown > 1 else []))

    def describe(self) -> str:
        if self.slowdown > 1:
            return (f"EMULATING a host {self.factor:.2f} x slower than the reference day "
                    f"({REFERENCE_IDLE_MS:g} ms): this one read {self.idle_ms:.1f} ms, slowed "
                    f"down {self.slowdown:.2f} x")
        return (f"this host read {self.idle_ms:.1f} ms: {self.factor:.2f} x slower than the "
                f"reference day ({REFERENCE_IDLE_MS:g} ms)")


def host_mode(idle_ms: float, env: Mapping[str, str]) -> HostMode:
    """The mode for a host whose idle reading is `idle_ms`; with ANYSCALE_EMULATED_HOST_FACTOR=F
    (test bed only) this host emulates one F times slower than the reference day (ValueError
    for an F that is not a number >= 1)."""
    emulated = env.get(EMULATE_ENV, "")
    if not emulated:
        return HostMode(idle_ms, host_factor(idle_ms))
    try:
        factor = float(emulated)
    except ValueError:
        factor = math.nan
    if not (math.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"{EMULATE_ENV}={emulated!r}: expected a factor >= 1")
    return HostMode(idle_ms, factor, max(1.0, factor * REFERENCE_IDLE_MS / idle_ms))


def too_slow(mode: HostMode, limit: float = MAX_HOST_FACTOR) -> Optional[str]:
    """Why the fixed-quota tests cannot run in this mode, or None."""
    if mode.factor <= limit:
        return None
    return f"{mode.describe()}: beyond the slow-day mode's {limit:g} x"


def summary_line(reasons: Sequence[str]) -> str:
    """One line for all tests that did not run: how many, and why (each reason once)."""
    counts = {}
    for r in reasons:
        counts[r] = counts.get(r, 0) + 1
    why = "; ".join(f"{r} ({n})" for r, n in counts.items())
    return (f"SYSTEM TESTS SKIPPED: {len(reasons)} test(s) of the two-scale test bed did not "
            f"run: {why}. {REQUIRE_ENV}=1 makes this a failure.")
