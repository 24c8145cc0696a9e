"""The rail as an elastic beam on pads (`pdem.boundaries.rail_beam`) against closed-form answers.

- Two seats, a load anywhere in the span: statically determinate, so the deflection relative to
  the seats is the simply supported beam's, −P b x (l² − b² − x²)/(6 l EI) (P l³/48EI in the
  middle), and the pads carry P b/l and P a/l exactly, whatever their stiffness.
- Seats much closer than the characteristic length: Zimmermann's beam on a continuous Winkler
  foundation, w(x) = −Q/(2kL) e^−|x|/L (cos x/L + sin |x|/L), L = (4EI/k)^(1/4), to ≤ 1 %.
- Equilibrium: the pads carry the wheels and the rail's weight exactly, wherever the wheels are.
- A periodic rail is translation invariant and carries m g a on every seat under its weight.
- A sleeper whose ballast gives way (a hanging sleeper) carries nothing: its load goes to its
  neighbours, and the rest still carry the whole wheel.
"""
import numpy as np
import pytest

from pdem.boundaries.rail_beam import UIC60, RailBeam, RailSection
from pdem.errors import InputError

EI = UIC60.bending_stiffness
WEIGHTLESS = RailSection(EI, 0.0)


def test_the_uic60_section_is_the_standard_one():
    assert EI == pytest.approx(6.38e6, rel=1e-3) and UIC60.mass == 60.21


@pytest.mark.parametrize("a", [0.3, 0.222])  # on a node and inside an element
def test_a_span_between_two_seats_bends_as_a_simply_supported_beam(a):
    span, p = 0.6, 1.0e5
    beam = RailBeam([0.0, span], 6.0e7, section=WEIGHTLESS, x_start=0.0, x_end=span, elements_per_span=4)
    w = beam.deflection([0.0, 0.0], [a], [p])
    x = beam.nodes_x
    relative = w - (w[0] * (span - x) + w[-1] * x) / span
    exact = np.where(x <= a,  # Gere & Timoshenko, Mechanics of Materials: the simply supported beam
                     -p * (span - a) * x * (span**2 - (span - a) ** 2 - x**2),
                     -p * a * (span - x) * (span**2 - a**2 - (span - x) ** 2)) / (6 * span * EI)
    assert np.allclose(relative, exact, rtol=1e-9, atol=1e-12 * abs(exact).max())
    if a == 0.3:
        assert relative[2] == pytest.approx(-p * span**3 / (48 * EI), rel=1e-9)
    assert np.allclose(beam.seat_forces([0.0, 0.0], [a], [p]), [-p * (span - a) / span, -p * a / span], rtol=1e-12)


def zimmermann(x, q, k, length):
    u = np.abs(x) / length
    return -q / (2 * k * length) * np.exp(-u) * (np.cos(u) + np.sin(u))


def test_closely_spaced_seats_give_zimmermanns_beam_on_a_winkler_foundation():
    k, a, q = 1.0e8, 0.02, 1.0e5  # foundation modulus [N/m²], seat spacing [m], wheel [N]
    length = (4 * EI / k) ** 0.25
    seats = np.arange(-8 * length, 8 * length, a)
    beam = RailBeam(seats, k * a, section=WEIGHTLESS, elements_per_span=1)
    x0 = seats[len(seats) // 2] + a / 2  # between two seats
    w = beam.deflection(np.zeros(len(seats)), [x0], [q])
    near = abs(beam.nodes_x - x0) < 3 * length
    exact = zimmermann(beam.nodes_x[near] - x0, q, k, length)
    assert np.max(abs(w[near] - exact)) <= 0.01 * np.max(abs(exact))
    forces = beam.seat_forces(np.zeros(len(seats)), [x0], [q])
    assert np.max(abs(forces - k * a * zimmermann(seats - x0, q, k, length))) <= 0.01 * k * a * q / (2 * k * length)


@pytest.mark.parametrize("x", [0.0, 0.17, 1.2, 2.95])
def test_the_pads_carry_the_wheels_and_the_rail_exactly(x):
    seats = np.arange(8) * 0.6
    beam = RailBeam(seats, 6.0e7, elements_per_span=4)
    loads = [1.0e5, 8.0e4]
    forces = beam.seat_forces(np.zeros(8), [x, x + 0.5], loads)
    rail = UIC60.mass * 9.81 * (beam.x_end - beam.x_start)
    assert forces.sum() == pytest.approx(-(sum(loads) + rail), rel=1e-10)
    w = beam.deflection(np.zeros(8), [x, x + 0.5], loads)
    assert np.allclose(forces, 6.0e7 * w[beam.seat_node], rtol=1e-9)


def test_a_periodic_rail_has_no_ends():
    a, n = 0.6, 8
    beam = RailBeam(np.arange(n) * a + 0.3, 6.0e7, x_start=0.0, x_end=n * a, periodic=True)
    assert np.allclose(beam.seat_forces(np.zeros(n)), -UIC60.mass * 9.81 * a, rtol=1e-10)
    f0 = beam.seat_forces(np.zeros(n), [0.3 + 0.1], [1.0e5])
    assert np.allclose(beam.seat_forces(np.zeros(n), [0.3 + 0.1 + n * a], [1.0e5]), f0, rtol=1e-12)
    assert np.allclose(beam.seat_forces(np.zeros(n), [0.3 + 0.1 + 3 * a], [1.0e5]), np.roll(f0, 3), rtol=1e-9)


def sleepers_on_ballast(beam, ballast, wheels_x, loads):
    """Seat forces with each sleeper (massless) on a ballast spring ``ballast[j]`` [N/m]: the
    sleepers' displacements u solve F(u) + k_b u = 0 (F is linear in u)."""
    n = len(beam.seats_x)
    f0 = beam.seat_forces(np.zeros(n), wheels_x, loads)
    gain = np.stack([beam.seat_forces(np.eye(n)[j], wheels_x, loads) - f0 for j in range(n)], 1)
    u = np.linalg.solve(gain - np.diag(ballast), -f0)
    return beam.seat_forces(u, wheels_x, loads), u


def test_a_hanging_sleeper_sheds_its_load_to_its_neighbours():
    seats = np.arange(9) * 0.6
    beam = RailBeam(seats, 6.0e7, section=WEIGHTLESS)
    q, kb = 1.0e5, 5.0e7
    supported, _ = sleepers_on_ballast(beam, np.full(9, kb), [seats[4]], [q])
    ballast = np.full(9, kb)
    ballast[4] = 0.0  # the ballast under the loaded sleeper gave way
    hanging, u = sleepers_on_ballast(beam, ballast, [seats[4]], [q])
    assert hanging[4] == pytest.approx(0.0, abs=1e-6 * q)
    assert hanging.sum() == pytest.approx(-q, rel=1e-10) and supported.sum() == pytest.approx(-q, rel=1e-10)
    assert hanging[3] < supported[3] < 0 and hanging[5] < supported[5] < 0
    assert u[4] < u[3]  # it hangs from the rail, lower than its neighbours
    # the supported case is the rail on pads and ballast in series, solved as one beam
    series = RailBeam(seats, 6.0e7 * kb / (6.0e7 + kb), section=WEIGHTLESS)
    assert np.allclose(supported, series.seat_forces(np.zeros(9), [seats[4]], [q]), rtol=1e-8)


@pytest.mark.parametrize("kwargs, field", [
    (dict(seats_x=[0.0, 0.6], pad_stiffness=0.0), "rail.pad_stiffness = 0.0"),
    (dict(seats_x=[0.0, 0.6], pad_stiffness=[6e7, -1.0]), "rail.pad_stiffness"),
    (dict(seats_x=[0.0, 0.6], pad_stiffness=[6e7]), "rail.pad_stiffness"),
    (dict(seats_x=[0.6, 0.0], pad_stiffness=6e7), "rail.seats"),
    (dict(seats_x=[0.0, 0.6, 1.3], pad_stiffness=6e7, x_start=0.0, x_end=1.8, periodic=True), "rail.periodic"),
    (dict(seats_x=[0.0, 0.6], pad_stiffness=6e7, x_start=0.1), "rail: the rail"),
    (dict(seats_x=[0.0, 0.6], pad_stiffness=6e7, section=RailSection(-1.0, 60.0)), "rail.bending_stiffness"),
])
def test_bad_input_is_named_on_one_line(kwargs, field):
    with pytest.raises(InputError) as e:
        RailBeam(**kwargs)
    assert str(e.value).startswith(field) and "\n" not in str(e.value)
