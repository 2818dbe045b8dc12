"""Progress of a run: one updating line on a terminal, a few plain lines otherwise (CI logs)."""

import sys
import time


class Progress:
    def __init__(self, duration, quiet=False, stream=None):
        self.duration = max(duration, 1e-9)
        self.stream = stream or sys.stdout
        self.quiet = quiet
        self.tty = self.stream.isatty()
        self.next_plain = 0.0  # next fraction of the run at which a plain line is printed
        self.start = time.monotonic()
        self.width = 0

    def _line(self, ev):
        alive = ev.get("alive", [])
        return (f"t={ev['t']:7.1f}/{self.duration:.1f} s  alive {len(alive)}  "
                f"aligned pairs {ev.get('aligned_pairs', 0)}  maps exchanged {ev.get('maps_received', 0)}  "
                f"wall {time.monotonic() - self.start:6.1f} s")

    def update(self, ev):
        if self.quiet:
            return
        text = self._line(ev)
        if self.tty:
            self.stream.write("\r" + text.ljust(self.width))
            self.width = len(text)
        else:
            frac = ev["t"] / self.duration
            if frac + 1e-9 < self.next_plain:
                return
            self.stream.write(text + "\n")
            self.next_plain = (int(frac * 4 + 1e-9) + 1) / 4.0  # at most ~5 lines per run
        self.stream.flush()

    def note(self, text):
        if self.quiet:
            return
        if self.tty and self.width:
            self.stream.write("\r" + " " * self.width + "\r")
            self.width = 0
        self.stream.write(text + "\n")
        self.stream.flush()

    def finish(self):
        if self.tty and self.width and not self.quiet:
            self.stream.write("\n")
            self.stream.flush()
            self.width = 0
