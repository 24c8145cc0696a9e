"""Force programs of force-controlled bodies (SPEC.md 1.6): the magnitude F(t) [N] of the load.

A program is a small immutable spec with ``value(t)`` (t [s] since the start of the run) and
``spec()`` (JSON-able, for the scene description). The direction is the body's
(`pdem.boxes`), by default downwards (−z). Imports nothing from pdem but the errors.

- `Constant(force)`: F = force.
- `Haversine(f_min, f_max, frequency, cycles, start=0)`: for ``start ≤ t ≤ start + cycles/f``,
  F = F_min + (F_max − F_min)(1 − cos 2πf(t − start))/2 (F_min at the start and end of each
  cycle, F_max at mid-cycle); F_min before and after (thesis ch. 5, Nottingham box test).
- `Impulse(f0, duration, start=0)`: F = F_0 (1 − τ'/τ) for 0 ≤ τ' = t − start ≤ τ, else 0.
"""
from math import cos, pi

from .errors import InputError
from .validate import number


class Constant:
    """F(t) = force [N]."""

    def __init__(self, force, *, label="load"):
        self.force = number(f"{label}.force", force, allow="a finite number [N]")

    def value(self, t):
        return self.force

    def spec(self):
        return {"type": "constant", "force": self.force}


class Haversine:
    """Haversine cycles between ``f_min`` and ``f_max`` [N] at ``frequency`` [Hz], ``cycles`` times,
    starting at ``start`` [s]; F_min outside the cycles."""

    def __init__(self, f_min, f_max, frequency, cycles, *, start=0.0, label="load"):
        self.f_min = number(f"{label}.f_min", f_min, allow="a finite number [N]")
        self.f_max = number(f"{label}.f_max", f_max, allow="a finite number [N]")
        if self.f_max < self.f_min:
            raise InputError(f"{label}.f_max = {f_max!r}: must be >= f_min = {self.f_min!r} [N]")
        self.frequency = number(f"{label}.frequency", frequency, 0.0, lo_open=True, allow="a number > 0 [Hz]")
        self.cycles = number(f"{label}.cycles", cycles, 1, integer=True, allow="an integer >= 1")
        self.start = number(f"{label}.start", start, 0.0, allow="a time >= 0 [s]")

    @property
    def end(self):
        """Time [s] at which the last cycle ends."""
        return self.start + self.cycles / self.frequency

    def value(self, t):
        if t <= self.start or t >= self.end:
            return self.f_min
        return self.f_min + (self.f_max - self.f_min) * (1.0 - cos(2.0 * pi * self.frequency * (t - self.start))) / 2.0

    def spec(self):
        return {"type": "haversine", "f_min": self.f_min, "f_max": self.f_max, "frequency": self.frequency,
                "cycles": self.cycles, "start": self.start}


class Impulse:
    """F = f0 (1 − (t − start)/duration) on [start, start + duration], else 0 [N]."""

    def __init__(self, f0, duration, *, start=0.0, label="load"):
        self.f0 = number(f"{label}.f0", f0, allow="a finite number [N]")
        self.duration = number(f"{label}.duration", duration, 0.0, lo_open=True, allow="a time > 0 [s]")
        self.start = number(f"{label}.start", start, 0.0, allow="a time >= 0 [s]")

    def value(self, t):
        tau = t - self.start
        if tau < 0.0 or tau > self.duration:
            return 0.0
        return self.f0 * (1.0 - tau / self.duration)

    def spec(self):
        return {"type": "impulse", "f0": self.f0, "duration": self.duration, "start": self.start}
