"""The rail as an elastic beam on rail pads: the load each sleeper gets from the wheels.

Model (Esveld, Modern Railway Track, 2nd ed. 2001, ch. 5; Timoshenko, Strength of Materials
II, 1956, §1 "beams on elastic foundation"): one rail is an Euler–Bernoulli beam along x of
bending stiffness EI [N m²] and mass m [kg/m] (UIC 60 / 60E1: E 210 GPa, I 3038.3 cm⁴,
60.21 kg/m), discretised into cubic Hermite elements (deflection w [m], z up, and slope per
node) with a node at every rail seat and ``elements_per_span`` elements between seats. Each
rail seat j is a rail pad, a linear spring k_j [N/m] between the rail's node and the sleeper's
rail-seat point (a fastening: it holds in tension too). Loads: wheel loads Q_i [N] (downwards)
at x_i, carried to the nodes of their element by the Hermite shape functions, and the rail's
own weight m g as a distributed load.

Time integration: quasi-static. The rail's bounce on its pads, sqrt(k/(m a))/2π ≈ 200 Hz for
UIC 60 on 60 MN/m pads 0.6 m apart, lies well above the sleeper-passing frequency v/a of the
speeds the traffic programs use (17 Hz at 10 m/s, 46 Hz at 100 km/h), so each step the beam is
in equilibrium with the current wheel positions and sleeper displacements u_j (at 300 km/h, 140
Hz, the rail's inertia would matter; it is left out):

    (K_beam + Σ_j k_j e_j e_jᵀ) w = f_wheels + f_weight + Σ_j k_j u_j e_j

and the pad force on sleeper j is F_j = k_j (w_j − u_j) (z up: negative pushes the sleeper
down). The rail's mass enters as a dead load; its inertia is left out. Because w is linear in
(Q, u), `RailBeam` factorises the matrix once and keeps only what the seats need: a step costs
one small matrix–vector product per sleeper row, in a fixed order (the same bits on every
rank and thread count: no BLAS, which may split sums by thread count).

Ends: a rail of the track's length with free ends (``periodic = False``), or a periodic rail
of period = the track's length (``periodic = True``, the last node is the first): a track
without ends, seats at equal spacing.

With every u_j = 0 and every k_j = k_d at spacing a ≪ L this is Zimmermann's beam on a
continuous foundation of modulus k_d / a: w(x) = −Q/(2 k L) η(x/L), L = (4 EI a / k_d)^(1/4),
η(u) = e^−|u| (cos|u| + sin|u|) (tests/physics/test_rail_beam.py checks it, and the exact
two-support case).
"""
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import InputError
from ..build.validate import number


@dataclass(frozen=True)
class RailSection:
    """A rail's bending stiffness EI [N m²] and mass per length [kg/m]."""

    bending_stiffness: float
    mass: float


UIC60 = RailSection(bending_stiffness=210e9 * 3038.3e-8, mass=60.21)  # 60E1 (EN 13674-1)


def hermite(xi, h):
    """Cubic Hermite shape functions of an element of length ``h`` [m] at ξ = (x − x_a)/h:
    the nodal weights (w_a, θ_a, w_b, θ_b) of a point load at ξ."""
    return np.array([1 - 3 * xi**2 + 2 * xi**3, h * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3,
                     h * (xi**3 - xi**2)])


def element_stiffness(ei, h):
    """Euler–Bernoulli element stiffness (w_a, θ_a, w_b, θ_b) [N/m, N, N m]."""
    return ei / h**3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                 [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])


@njit(cache=True)
def cholesky(a):
    """Lower triangular L with L Lᵀ = a (a symmetric positive definite), in a fixed order;
    raises if a pivot is not positive."""
    n = a.shape[0]
    low = np.zeros_like(a)
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= low[j, k] * low[j, k]
        if not s > 0.0:
            raise ValueError("rail beam: the stiffness matrix is not positive definite")
        low[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= low[i, k] * low[j, k]
            low[i, j] = t / low[j, j]
    return low


@njit(cache=True)
def cholesky_solve(low, b):
    """x with L Lᵀ x = b (forward then backward substitution)."""
    n = low.shape[0]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= low[i, k] * y[k]
        y[i] = s / low[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= low[k, i] * x[k]
        x[i] = s / low[i, i]
    return x


@njit(cache=True)
def matvec(a, x):
    """a @ x summed in index order."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        s = 0.0
        for k in range(a.shape[1]):
            s += a[i, k] * x[k]
        out[i] = s
    return out


class RailBeam:
    """One rail on its pads over the sleepers' rail seats at ``seats_x`` [m] (increasing).

    ``pad_stiffness`` [N/m]: one number or one per seat, each > 0. The rail runs from ``x_start``
    to ``x_end`` [m] (both within the track; default half a spacing beyond the end seats), or is
    periodic with period ``x_end − x_start`` (seats equally spaced, the period a whole number of
    spacings). ``gravity`` [m/s²] (≥ 0) sets the rail's own weight.
    """

    def __init__(self, seats_x, pad_stiffness, *, section=UIC60, x_start=None, x_end=None, periodic=False,
                 elements_per_span=4, gravity=9.81, label="rail"):
        seats = np.asarray(seats_x, float)
        if seats.ndim != 1 or len(seats) < 2 or not np.all(np.isfinite(seats)) or np.any(np.diff(seats) <= 0):
            raise InputError(f"{label}.seats = {seats_x!r}: must be >= 2 increasing finite positions [m]")
        k = np.broadcast_to(np.asarray(pad_stiffness, float), seats.shape).copy() \
            if np.ndim(pad_stiffness) == 0 or len(pad_stiffness) == len(seats) else None
        if k is None or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise InputError(f"{label}.pad_stiffness = {pad_stiffness!r}: must be a number > 0 [N/m] or one per "
                             f"rail seat ({len(seats)})")
        ei = number(f"{label}.bending_stiffness", section.bending_stiffness, 0.0, lo_open=True,
                    allow="a number > 0 [N m^2]")
        mass = number(f"{label}.mass", section.mass, 0.0, allow="a number >= 0 [kg/m]")
        n_el = number(f"{label}.elements_per_span", elements_per_span, 1, integer=True, allow="an integer >= 1")
        g = number(f"{label}.gravity", gravity, 0.0, allow="a number >= 0 [m/s^2]")
        spacing = np.diff(seats)
        x0 = seats[0] - spacing[0] / 2 if x_start is None else number(f"{label}.x_start", x_start, allow="[m]")
        x1 = seats[-1] + spacing[-1] / 2 if x_end is None else number(f"{label}.x_end", x_end, allow="[m]")
        if periodic:
            period = x1 - x0
            a = spacing[0]
            if not np.allclose(spacing, a, rtol=1e-9, atol=0) or abs(period / a - round(period / a)) > 1e-9 \
                    or round(period / a) != len(seats):
                raise InputError(f"{label}.periodic = true: the seats must be equally spaced and fill the period "
                                 f"{period:g} m ({len(seats)} seats at {a:g} m give {len(seats) * a:g} m)")
        elif not (x0 <= seats[0] and x1 >= seats[-1]):
            raise InputError(f"{label}: the rail [{x0:g}, {x1:g}] m must reach over every rail seat "
                             f"[{seats[0]:g}, {seats[-1]:g}] m")
        self.label, self.periodic, self.ei, self.mass, self.gravity = label, bool(periodic), ei, mass, g
        self.seats_x, self.pad_stiffness, self.x_start, self.x_end = seats, k, float(x0), float(x1)
        self.nodes_x, self.seat_node = self._mesh(float(np.min(spacing)) / n_el)
        self._n_dof = n_dof = 2 * (len(self.nodes_x) - (1 if self.periodic else 0))
        stiff = np.zeros((n_dof, n_dof))
        self._weight = np.zeros(n_dof)
        for e in range(len(self.nodes_x) - 1):
            h = self.nodes_x[e + 1] - self.nodes_x[e]
            dofs = self._dofs(e)
            stiff[np.ix_(dofs, dofs)] += element_stiffness(ei, h)
            self._weight[dofs] -= mass * g * np.array([h / 2, h * h / 12, h / 2, -h * h / 12])
        self._seat_dofs = 2 * self.seat_node
        stiff[self._seat_dofs, self._seat_dofs] += k
        self._low = cholesky(stiff)
        # w at the seats is linear in the loads: w_seats = G f with G the seat rows of K⁻¹ (K symmetric)
        unit = np.eye(n_dof)[self._seat_dofs]
        self._g = np.ascontiguousarray(np.stack([cholesky_solve(self._low, e) for e in unit]))
        self._w_weight = matvec(self._g, self._weight)
        self._u_gain = np.ascontiguousarray(self._g[:, self._seat_dofs] * k[None, :])

    # ------------------------------------------------------------------ mesh
    def _mesh(self, h_max):
        """Node positions [m] (every seat a node; elements no longer than ``h_max``) and the node
        of every seat. Periodic: from the first seat over one period (the last node is the first)."""
        s = self.seats_x
        if self.periodic:
            breaks = np.append(s, s[0] + (self.x_end - self.x_start))
        else:
            breaks = np.concatenate([[self.x_start] if self.x_start < s[0] else [], s,
                                     [self.x_end] if self.x_end > s[-1] else []])
        nodes = [breaks[0]]
        for a, b in zip(breaks[:-1], breaks[1:]):
            m = int(np.ceil((b - a) / h_max - 1e-9))
            nodes.extend(np.linspace(a, b, m + 1)[1:])
        nodes = np.array(nodes)
        return nodes, np.searchsorted(nodes, s).astype(np.int64)

    def _dofs(self, e):
        """The 4 DOF indices (w_a, θ_a, w_b, θ_b) of element e (periodic: the last node is node 0)."""
        b = (e + 1) % (len(self.nodes_x) - 1) if self.periodic else e + 1
        return [2 * e, 2 * e + 1, 2 * b, 2 * b + 1]

    def _wheel(self, x):
        """(DOFs, nodal weights) of a unit downward point load at x [m] (periodic: x wrapped into
        the period), or None if x is off a rail with ends."""
        x0, x1 = self.nodes_x[0], self.nodes_x[-1]
        if self.periodic:
            x = x0 + (x - x0) % (x1 - x0)
        elif not x0 <= x <= x1:
            return None
        e = min(int(np.searchsorted(self.nodes_x, x, side="right")) - 1, len(self.nodes_x) - 2)
        h = self.nodes_x[e + 1] - self.nodes_x[e]
        return np.array(self._dofs(e)), -hermite((x - self.nodes_x[e]) / h, h)

    def _loads(self, sleeper_u, wheels_x, wheel_loads):
        """The load vector: the rail's weight, the wheels and the pads' pull k_j u_j."""
        f = self._weight.copy()
        for x, q in zip(wheels_x, wheel_loads):
            found = self._wheel(x)
            if found is not None:
                f[found[0]] += q * found[1]
        f[self._seat_dofs] += self.pad_stiffness * np.asarray(sleeper_u, float)
        return f

    # ------------------------------------------------------------------ answers
    def deflection(self, sleeper_u, wheels_x=(), wheel_loads=()):
        """Deflection w [m] (z up) at `nodes_x` for sleeper rail-seat displacements ``sleeper_u``
        [m] (z up) and wheel loads [N] (downwards) at ``wheels_x`` [m]."""
        w = cholesky_solve(self._low, self._loads(sleeper_u, wheels_x, wheel_loads))[0::2]
        return np.append(w, w[0]) if self.periodic else w

    def seat_forces(self, sleeper_u, wheels_x=(), wheel_loads=()):
        """Force [N] (z up) of each rail pad on its sleeper, F_j = k_j (w_j − u_j), from the seat
        rows of K⁻¹ (a step's cost: one n_seats² product plus 4 n_seats per wheel)."""
        u = np.asarray(sleeper_u, float)
        w = self._w_weight + matvec(self._u_gain, u)
        for x, q in zip(wheels_x, wheel_loads):
            found = self._wheel(x)
            if found is not None:
                w = w + q * matvec(np.ascontiguousarray(self._g[:, found[0]]), found[1])
        return self.pad_stiffness * (w - u)


class SleeperRails:
    """The rails (one `RailBeam` each: a half model has one, a whole track two) over a row of
    sleepers that translate only, coupled to them every step: the load program of every sleeper
    (`pdem.boundaries.loads.SleeperLoad` with ``rail``).

    ``train`` (`pdem.boundaries.loads.AxleTrain`) says where the axles are at t
    (``axle_positions``); each puts ``axle_load``/2 [N] on every rail. The rail seats of sleeper
    j move with it: u_j = z_j − z_j,0 [m] (z up) from the sleeper centres ``reference`` [m] at
    the start of the traffic (`attach`), where the pads are unstressed and the rail straight.
    ``load(t, x)`` is the downward force [N] of every rail's pad on the sleeper at x, from the
    sleepers' positions now (those of ``boxes``, read when the boxes' load is applied: the same
    instant as their contact forces) and the wheels at t; computed once for every sleeper per
    (t, positions) and summed over the rails in order, so every rank (the boxes are replicated)
    gets the same bits. The rails' weight enters through the pads (the sleepers' mass then
    leaves it out).

    Turning sleepers (``seats``: rail r's seat on every sleeper, box axes from the centre [m]):
    the seats move with the sleeper, translation plus rotation × lever arm, u_rj = (c_j + R_j
    s_r)_z − (its height at the start), and each pad acts at its seat: the sleeper gets the
    sum of the pads' forces and their moment Σ_r (R_j s_r) × (0, 0, F_rj) (`moment`)."""

    def __init__(self, beams, train, seats=None):
        self.beams = list(beams)
        self.train = train
        self.index = {float(x): j for j, x in enumerate(self.beams[0].seats_x)}
        self.boxes, self.reference = None, None
        self._key, self._load = None, None
        # turning sleepers: every rail's seat on the sleeper, box axes from its centre [m] (one per beam)
        self.seats = None if seats is None else np.asarray(seats, float).reshape(len(self.beams), 3)
        self._moment = None

    @property
    def turning(self):
        """True if the seats follow the sleepers' rotation (``seats`` given)."""
        return self.seats is not None

    def attach(self, boxes, reference):
        """Couple to ``boxes`` (their rows are the sleepers in seat order) with the sleeper
        centre heights ``reference`` [m] at which the rails were laid; with ``seats``, the seat
        heights [n_rails, n_sleepers] [m] there (`seat_heights`)."""
        self.boxes = boxes
        self.reference = np.asarray(reference, float).copy()

    def seat_points(self, centres, rotations):
        """[n_rails, n_sleepers, 3] the seats' positions [m]: centre + R s (R box → global)."""
        return np.asarray(centres)[None] + np.einsum("jak,rk->rja", np.asarray(rotations), self.seats)

    def seat_heights(self, centres, rotations):
        """[n_rails, n_sleepers] the seats' heights z [m] (the reference of `attach` when turning)."""
        return self.seat_points(centres, rotations)[:, :, 2]

    def turning_forces(self, t, centres, rotations):
        """(force [N] (z up) of every rail's pad on each sleeper [n_rails, n_sleepers], seat points
        [n_rails, n_sleepers, 3] [m]) for the sleepers at ``centres`` turned by ``rotations``: rail
        r's seat on sleeper j moves by u_rj = (c_j + R_j s_r)_z − reference_rj."""
        wheels = self.train.axle_positions(t)
        q = [self.train.axle_load / 2.0] * len(wheels)
        points = self.seat_points(centres, rotations)
        u = points[:, :, 2] - self.reference.reshape(len(self.beams), -1)
        return np.stack([beam.seat_forces(u[r], wheels, q) for r, beam in enumerate(self.beams)]), points

    def pad_forces(self, t, z):
        """Force [N] (z up) of all rails' pads on each sleeper for sleeper centre heights z [m]
        and the wheels at t."""
        wheels = self.train.axle_positions(t)
        q = [self.train.axle_load / 2.0] * len(wheels)
        u = np.asarray(z, float) - self.reference
        total = np.zeros(len(u))
        for beam in self.beams:
            total = total + beam.seat_forces(u, wheels, q)
        return total

    def load(self, t, x):
        if self.turning:
            return float(self._turning(t)[0][self.index[float(x)]])
        z = self.boxes.center[:, 2]
        if self._key is None or self._key[0] != t or not np.array_equal(self._key[1], z):
            self._key, self._load = (t, z.copy()), -self.pad_forces(t, z)
        return float(self._load[self.index[float(x)]])

    def moment(self, t, x):
        """The pads' moment [N·m] (global axes) about the centre of the sleeper at x: Σ_r (R s_r)
        × (0, 0, F_r), with the load of `load` at the same instant and positions."""
        return self._turning(t)[1][self.index[float(x)]]

    def _turning(self, t):
        """(downward load [n], moment [n, 3]) on the turning sleepers, once per (t, positions,
        rotations); the rails summed in order."""
        bx = self.boxes
        c, rot = bx.center, bx.rotation
        if self._key is None or self._key[0] != t or not np.array_equal(self._key[1], c) \
                or not np.array_equal(self._key[2], rot):
            forces, points = self.turning_forces(t, c, rot)
            arm = points - c[None]
            total = np.zeros(forces.shape[1])
            moment = np.zeros((forces.shape[1], 3))
            for r in range(len(self.beams)):
                total = total + forces[r]
                moment[:, 0] += arm[r, :, 1] * forces[r]
                moment[:, 1] -= arm[r, :, 0] * forces[r]
            self._key, self._load, self._moment = (t, c.copy(), rot.copy()), -total, moment
        return self._load, self._moment

    @property
    def weight(self):
        """The rails' weight [N] (what the pads carry with no wheel on the rails)."""
        return sum(b.mass * b.gravity * (b.x_end - b.x_start) for b in self.beams)

    def spec(self):
        b = self.beams[0]
        return {"type": "rail_beam", "rails": len(self.beams), "bending_stiffness": b.ei, "mass": b.mass,
                "pad_stiffness": b.pad_stiffness.tolist(), "x_start": b.x_start, "x_end": b.x_end,
                "nodes": len(b.nodes_x), **({"seats": self.seats.tolist()} if self.turning else {})}
