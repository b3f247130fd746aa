"""Progress on the terminal: cases done / failed / errored / running and the time left.
A tqdm bar on a terminal, plain lines (at most one per case, every few seconds) otherwise."""
from __future__ import annotations

import sys
import time


class Progress:
    def __init__(self, total: int, already: int = 0, slots: int = 1, stream=None, min_interval: float = 2.0):
        self.total, self.done, self.slots = total, already, max(1, slots)
        self.failed = self.errored = 0
        self.ran = 0
        self.t0 = time.monotonic()
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.min_interval = min_interval
        self._last = 0.0
        self.bar = None
        if self.tty:
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=already, unit="case", file=self.stream, dynamic_ncols=True)

    @property
    def running(self) -> int:
        return min(self.slots, self.total - self.done)

    def eta(self) -> float | None:
        if self.ran == 0:
            return None
        return (time.monotonic() - self.t0) / self.ran * (self.total - self.done)

    def line(self) -> str:
        eta = self.eta()
        left = "?" if eta is None else f"{eta:.0f} s"
        return (f"{self.done}/{self.total} done, {self.failed} failed, {self.errored} errored, "
                f"{self.running} running, ~{left} left")

    def update(self, verdict: str, case_id: str = "") -> None:
        self.done += 1
        self.ran += 1
        self.failed += verdict == "fail"
        self.errored += verdict == "error"
        if self.bar is not None:
            self.bar.set_postfix_str(f"failed {self.failed} errored {self.errored} running {self.running}")
            self.bar.update(1)
            return
        now = time.monotonic()
        if verdict != "pass" or now - self._last >= self.min_interval or self.done == self.total:
            self._last = now
            tag = "" if verdict == "pass" else f" [{case_id}: {verdict}]"
            print(f"campaign: {self.line()}{tag}", file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
