"""A progress bar in seconds for the characterisation commands (profile, thresholds): the whole
run's predicted time as the bar's length, the elapsed time as its position, the current step as
its label. tqdm (python3-tqdm) draws it on standard error, and only on a terminal: in a log or
a pipe it stays silent, so --json output is never mixed with it."""
import sys
import time
from typing import Optional


class TimeProgress:
    def __init__(self, predicted_s: float, enabled: Optional[bool] = None, stream=None):
        from tqdm import tqdm
        self._start = time.monotonic()
        self._stream = stream or sys.stderr
        # disable=None: tqdm turns itself off when the stream is not a terminal.
        self._bar = tqdm(total=max(1, int(round(predicted_s))), unit="s", file=self._stream,
                         disable=None if enabled is None else not enabled,
                         bar_format="{desc} {percentage:3.0f}%|{bar}| {n}/{total} s "
                                    "[{remaining} left]", dynamic_ncols=True)
        self._shown = 0

    def phase(self, text: str):
        self._bar.set_description_str(text, refresh=False)
        self.tick()

    def tick(self):
        """Moves the bar to the elapsed time; the total grows when the run is slower than
        predicted, so the bar never claims to be done early."""
        elapsed = int(time.monotonic() - self._start)
        if elapsed >= self._bar.total:
            self._bar.total = elapsed + 1
        if elapsed > self._shown:
            self._bar.update(elapsed - self._shown)
            self._shown = elapsed
        else:
            self._bar.refresh()

    def sleep(self, seconds: float, should_stop=lambda: False):
        """Sleeps `seconds`, keeping the bar moving; returns early when should_stop()."""
        end = time.monotonic() + seconds
        while time.monotonic() < end and not should_stop():
            time.sleep(min(0.2, max(0.0, end - time.monotonic())))
            self.tick()

    def write(self, line: str):
        """A line above the bar (tqdm keeps the bar below it)."""
        if self._bar.disable:
            print(line, file=self._stream, flush=True)
        else:
            self._bar.write(line, file=self._stream)

    def close(self):
        self._bar.close()
