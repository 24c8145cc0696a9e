"""Force programs of force-controlled bodies (SPEC.md 1.6): the magnitude F(t) [N] of the load.

A program is a small immutable spec with ``value(t)`` (t [s] since the start of the run) and
``spec()`` (JSON-able, for the scene description). The direction is the body's
(`pdem.bodies.boxes`), by default downwards (−z). Imports nothing from pdem but the errors.

- `Constant(force)`: F = force.
- `Haversine(f_min, f_max, frequency, cycles, start=0)`: for ``start ≤ t ≤ start + cycles/f``,
  F = F_min + (F_max − F_min)(1 − cos 2πf(t − start))/2 (F_min at the start and end of each
  cycle, F_max at mid-cycle); F_min before and after (thesis ch. 5, Nottingham box test).
- `HalfSine(f_min, f_max, frequency, cycles, start=0)`: as `Haversine` with
  F = F_min + (F_max − F_min)|sin πf(t − start)| (one positive half sine per cycle: the same
  peaks at mid-cycle, steeper at the start and end of each cycle, no rest at F_min).
- `Impulse(f0, duration, start=0)`: F = F_0 (1 − τ'/τ) for 0 ≤ τ' = t − start ≤ τ, else 0.
- `Ramp(f_from, f_to, duration, start=0)`: F = F_from + (F_to − F_from) clamp((t − start)/τ, 0, 1).
- `Motion(speed, displacement=inf, start=0)`: not a force but a prescribed displacement
  u(t) = min(v · max(t − start, 0), u_max) [m] along the body's direction (displacement
  control: move at ``speed`` [m/s] until ``displacement`` [m] is reached, then hold; velocity
  control without a limit). The driver gives the body the velocity (u(t + Δt) − u(t))/Δt of each
  step (`Motion.step_velocity`), so it lands on u_max exactly and stays there.
- `AxleTrain(...)`: trains of axles passing at a constant speed over a row of sleepers (moving
  axle loads); `AxleTrain.sleeper_load(x)` is the program of the sleeper at x: the time-shifted
  rail-seat share of every wheel (`rail_seat_share`, Zimmermann's beam on an elastic
  foundation), or, given a ``rail`` (`pdem.boundaries.rail_beam.SleeperRails`, the rail as a
  beam on pads), what the rail's pads push on that sleeper now (it depends on where the
  sleepers are: a hanging sleeper passes its load to its neighbours).
"""
from math import ceil, cos, exp, pi, sin

from ..errors import InputError
from ..build.validate import number


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


class HalfSine(Haversine):
    """Half-sine cycles between ``f_min`` and ``f_max`` [N] at ``frequency`` [Hz] (one cycle =
    one half period of |sin|), ``cycles`` times, starting at ``start`` [s]; F_min outside."""

    def value(self, t):
        if t <= self.start or t >= self.end:
            return self.f_min
        return self.f_min + (self.f_max - self.f_min) * abs(sin(pi * self.frequency * (t - self.start)))

    def spec(self):
        return {**super().spec(), "type": "half_sine"}


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


class Ramp:
    """F from ``f_from`` to ``f_to`` [N] linearly over ``duration`` [s] from ``start`` [s], then held."""

    def __init__(self, f_from, f_to, duration, *, start=0.0, label="load"):
        self.f_from = number(f"{label}.f_from", f_from, allow="a finite number [N]")
        self.f_to = number(f"{label}.f_to", f_to, allow="a finite number [N]")
        self.duration = number(f"{label}.duration", duration, 0.0, lo_open=True, allow="a time > 0 [s]")
        self.start = number(f"{label}.start", start, 0.0, allow="a time >= 0 [s]")

    def value(self, t):
        s = min(max((t - self.start) / self.duration, 0.0), 1.0)
        return self.f_from + (self.f_to - self.f_from) * s

    def spec(self):
        return {"type": "ramp", "f_from": self.f_from, "f_to": self.f_to, "duration": self.duration,
                "start": self.start}


class Motion:
    """Prescribed displacement u(t) = min(speed · max(t − start, 0), displacement) [m] (module
    docstring): displacement control, or velocity control with ``displacement`` = inf."""

    def __init__(self, speed, displacement=float("inf"), *, start=0.0, label="load"):
        self.speed = number(f"{label}.speed", speed, 0.0, lo_open=True, allow="a speed > 0 [m/s]")
        if displacement != float("inf"):
            displacement = number(f"{label}.displacement", displacement, 0.0, lo_open=True,
                                  allow="a distance > 0 [m]")
        self.displacement = float(displacement)
        self.start = number(f"{label}.start", start, 0.0, allow="a time >= 0 [s]")

    def value(self, t):
        """u(t) [m]."""
        return min(self.speed * max(t - self.start, 0.0), self.displacement)

    def step_velocity(self, t, dt):
        """The speed [m/s] of the step from t to t + dt that follows u."""
        return (self.value(t + dt) - self.value(t)) / dt

    def spec(self):
        return {"type": "motion", "speed": self.speed, "displacement": repr(self.displacement)
                if self.displacement == float("inf") else self.displacement, "start": self.start}


# ---------------------------------------------------------------------------- moving axle loads
ETA_ZERO = 0.75 * pi  # first zero of Zimmermann's influence line η(u) [-]


def eta(u):
    """Zimmermann's influence line of a beam on an elastic (Winkler) foundation under a point
    load, η(u) = e^−|u| (cos|u| + sin|u|), u = distance / L, cut at its first zero |u| = 3π/4
    (beyond it η < 0: the rail would pull the sleeper up, which the load model leaves out)."""
    u = abs(u)
    if u >= ETA_ZERO:
        return 0.0
    return exp(-u) * (cos(u) + sin(u))


def rail_seat_share(d, spacing, length):
    """Share [-] of a wheel load carried by the rail seat at distance ``d`` [m] from the wheel.

    Zimmermann (Esveld, Modern Railway Track, 2nd ed. 2001, ch. 5): the rail is a beam of
    characteristic length L = (4 EI a / k_d)^(1/4) on discrete supports of stiffness k_d at
    spacing a, and a rail seat at distance d carries F = Q (a / 2L) η(d/L). Here η is cut at
    its first zero and the shares are normalised over the supports of an infinite regular track
    (every a, one of them at distance d), so that at every wheel position the rail seats of a
    long track carry exactly the wheel load: share(d) = η(d/L) / Σ_m η((d + m a)/L). Under the
    wheel that is a/2L-like: 0.40 for a = 0.6 m, L = 0.71 m, 0.24 to each neighbour."""
    reach = ETA_ZERO * length
    if abs(d) >= reach:
        return 0.0
    m_max = int(ceil(2.0 * reach / spacing)) + 1  # every support within reach of the wheel
    total = 0.0
    for m in range(-m_max, m_max + 1):
        total += eta((d + m * spacing) / length)
    return eta(d / length) / total


class AxleTrain:
    """``passages`` trains of axles at ``offsets`` [m] behind the first axle (a bogie layout),
    each axle carrying ``axle_load`` [N] (two wheels), running at ``speed`` [m/s] along x over
    sleepers at ``spacing`` [m]. Passage p (0, 1, ...) starts at t_p = start + p·period; its
    first axle runs from ``x_from`` to ``x_to`` [m] (an axle loads the track only between
    them), the last one leaves ``x_to`` at t_p + (x_to − x_from + offsets[-1])/speed, then the
    track rests ``rest_time`` [s] unloaded: period = (x_to − x_from + offsets[-1])/speed +
    rest_time. ``length`` [m] is the characteristic length of `rail_seat_share`."""

    def __init__(self, axle_load, offsets, speed, passages, *, spacing, length, x_from, x_to, rest_time=0.0,
                 start=0.0, label="traffic"):
        self.axle_load = number(f"{label}.axle_load", axle_load, 0.0, lo_open=True, allow="a number > 0 [N]")
        if not isinstance(offsets, (list, tuple)) or not offsets:
            raise InputError(f"{label}.axles = {offsets!r}: must be a list of axle positions behind the first "
                             "axle [m], starting with 0")
        self.offsets = [number(f"{label}.axles", x, 0.0, allow="a list of positions >= 0 [m]") for x in offsets]
        if self.offsets[0] != 0.0 or any(b < a for a, b in zip(self.offsets, self.offsets[1:])):
            raise InputError(f"{label}.axles = {offsets!r}: must start with 0 (the first axle) and not decrease [m]")
        self.speed = number(f"{label}.speed", speed, 0.0, lo_open=True, allow="a number > 0 [m/s]")
        self.passages = number(f"{label}.passages", passages, 1, integer=True, allow="an integer >= 1")
        self.spacing = number(f"{label}.spacing", spacing, 0.0, lo_open=True, allow="a number > 0 [m]")
        self.length = number(f"{label}.characteristic_length", length, 0.0, lo_open=True, allow="a number > 0 [m]")
        self.x_from = number(f"{label}.x_from", x_from, allow="a position [m]")
        self.x_to = number(f"{label}.x_to", x_to, allow="a position [m]")
        if not self.x_to > self.x_from:
            raise InputError(f"{label}.x_to = {x_to!r}: must be beyond x_from = {self.x_from!r} [m]")
        self.rest_time = number(f"{label}.rest_time", rest_time, 0.0, allow="a time >= 0 [s]")
        self.start = number(f"{label}.start", start, 0.0, allow="a time >= 0 [s]")

    @property
    def reach(self):
        """Distance [m] beyond which a wheel loads no rail seat (first zero of η)."""
        return ETA_ZERO * self.length

    @property
    def travel_time(self):
        """Time [s] from the first axle at x_from to the last axle at x_to."""
        return (self.x_to - self.x_from + self.offsets[-1]) / self.speed

    @property
    def period(self):
        return self.travel_time + self.rest_time

    @property
    def end(self):
        """Time [s] at which the last passage (with its rest) ends."""
        return self.start + self.passages * self.period

    def passage_times(self, p):
        """(start, end) [s] of passage p (0-based), rest included."""
        t0 = self.start + p * self.period
        return t0, t0 + self.period

    def time_over(self, p, x):
        """Time [s] at which the first axle of passage p is at x."""
        return self.start + p * self.period + (x - self.x_from) / self.speed

    def axle_positions(self, t):
        """Positions [m] of the axles on the track (between x_from and x_to) at time t."""
        if t < self.start or t >= self.end:
            return []
        p = int((t - self.start) // self.period)
        if p >= self.passages:
            return []
        head = self.x_from + self.speed * (t - self.start - p * self.period)
        return [x for x in (head - o for o in self.offsets) if self.x_from <= x <= self.x_to]

    def load(self, t, x, wheels):
        """Force [N] on the sleeper at x from ``wheels`` rail seats (2: a whole sleeper, 1: a half
        in a model cut at the track's centre line) at time t."""
        f = 0.0
        q = self.axle_load / 2.0 * wheels
        for a in self.axle_positions(t):
            if abs(x - a) < self.reach:
                f += q * rail_seat_share(x - a, self.spacing, self.length)
        return f

    def sleeper_load(self, x, wheels, rail=None):
        """The force program of the sleeper at x (``wheels`` rail seats): the prescribed share,
        or through ``rail`` (an object with ``load(t, x)`` [N, downward] and ``spec()``)."""
        return SleeperLoad(self, x, wheels, rail)

    def spec(self):
        return {"type": "axle_train", "axle_load": self.axle_load, "axles": list(self.offsets), "speed": self.speed,
                "passages": self.passages, "spacing": self.spacing, "characteristic_length": self.length,
                "x_from": self.x_from, "x_to": self.x_to, "rest_time": self.rest_time, "start": self.start}


class SleeperLoad:
    """F(t) on one sleeper of an `AxleTrain`: its rail seats' shares of every wheel, or, with a
    ``rail``, the force of the rail's pads on it (`pdem.boundaries.rail_beam.SleeperRails.load`)."""

    def __init__(self, train, x, wheels, rail=None):
        self.train = train
        self.x = float(x)
        self.wheels = int(wheels)
        self.rail = rail

    def value(self, t):
        if self.rail is not None:
            return self.rail.load(t, self.x)
        return self.train.load(t, self.x, self.wheels)

    def moment(self, t):
        """The moment [N·m] of the rail's pads about the sleeper's centre if the rail follows the
        sleeper's rotation (`pdem.boundaries.rail_beam.SleeperRails.moment`), else None (the load
        acts at the box's ``load_point``)."""
        if self.rail is None or not getattr(self.rail, "turning", False):
            return None
        return self.rail.moment(t, self.x)

    def spec(self):
        return {**self.train.spec(), "sleeper_x": self.x, "wheels": self.wheels,
                **({"rail": self.rail.spec()} if self.rail is not None else {})}
