"""Moving axle loads (`pdem.boundaries.loads.AxleTrain`, `rail_seat_share`) against independent truth:
Zimmermann's influence line written out with numpy, conservation of the wheel load over the
sleepers, the time shift spacing/speed between neighbouring sleepers, the passage timing, and
one-line errors for bad input."""
from math import pi

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.boundaries.loads import ETA_ZERO, AxleTrain, eta, rail_seat_share

A, L = 0.6, 0.71  # sleeper spacing, characteristic length [m]


def eta_numpy(u):
    u = np.abs(np.asarray(u, float))
    return np.where(u < 0.75 * pi, np.exp(-u) * (np.cos(u) + np.sin(u)), 0.0)


def test_influence_line_is_zimmermanns_cut_at_its_first_zero():
    u = np.linspace(-4.0, 4.0, 801)
    got = np.array([eta(x) for x in u])
    assert np.allclose(got, eta_numpy(u), rtol=0, atol=1e-15)
    assert eta(0.0) == 1.0 and eta(ETA_ZERO) == 0.0
    assert abs(np.exp(-ETA_ZERO) * (np.cos(ETA_ZERO) + np.sin(ETA_ZERO))) < 1e-15  # it is η's first zero
    assert eta(ETA_ZERO - 1e-3) > 0.0


@pytest.mark.parametrize("offset", [0.0, 0.05, 0.17, 0.3, 0.44, 0.599])
def test_shares_of_a_long_regular_track_carry_the_whole_wheel_load(offset):
    d = np.arange(-20, 21) * A + offset
    shares = np.array([rail_seat_share(x, A, L) for x in d])
    assert abs(shares.sum() - 1.0) < 1e-14
    assert np.all(shares >= 0.0)
    # proportional to η at each support (the normalisation is common to all of them)
    ref = eta_numpy(d / L)
    assert np.allclose(shares, ref / ref.sum(), rtol=1e-14, atol=0)


def test_share_under_the_wheel_is_the_40_to_50_percent_of_practice():
    s0 = rail_seat_share(0.0, A, L)
    assert 0.38 < s0 < 0.42  # B91 at 600 mm on a medium support: ~40 % under the wheel
    assert rail_seat_share(A, A, L) == rail_seat_share(-A, A, L)
    # stiffer supports (shorter L) concentrate the load: about a/2L of Zimmermann
    assert rail_seat_share(0.0, A, 0.5) > 0.5 > s0


def test_dense_supports_tend_to_zimmermanns_a_over_2L():
    """For a << L the normaliser is the integral of the positive lobe, 2L (1 - e^-3π/4 cos 3π/4) / a."""
    a = 0.01 * L
    lobe = 1.0 - np.exp(-0.75 * pi) * np.cos(0.75 * pi)
    assert abs(rail_seat_share(0.0, a, L) / (a / (2 * L) / lobe) - 1.0) < 1e-3


def train(**kw):
    args = dict(axle_load=20e3, offsets=[0.0, 2.5], speed=10.0, passages=3, spacing=A, length=L, x_from=-2.0,
                x_to=6.0, rest_time=0.3, start=1.0)
    args.update(kw)
    offsets = args.pop("offsets")
    return AxleTrain(args.pop("axle_load"), offsets, args.pop("speed"), args.pop("passages"), **args)


def test_passage_timing_and_axle_positions():
    tr = train()
    travel = (6.0 - (-2.0) + 2.5) / 10.0
    assert tr.travel_time == pytest.approx(travel, rel=1e-15) and tr.period == pytest.approx(travel + 0.3)
    assert tr.end == pytest.approx(1.0 + 3 * (travel + 0.3))
    assert tr.axle_positions(0.99) == [] and tr.axle_positions(tr.end) == []
    assert tr.axle_positions(1.0) == [-2.0]  # the second axle is not on the track yet
    assert tr.axle_positions(1.0 + 0.5) == pytest.approx([3.0, 0.5])
    assert tr.axle_positions(1.0 + travel + 0.1) == []  # resting between passages
    t0, t1 = tr.passage_times(1)
    assert t0 == pytest.approx(1.0 + travel + 0.3) and t1 == pytest.approx(t0 + travel + 0.3)
    assert tr.time_over(1, 2.0) == pytest.approx(t0 + 0.4)


def test_each_sleeper_sees_the_same_pulse_shifted_by_spacing_over_speed():
    tr = train(passages=1)
    x = (np.arange(6) + 0.5) * A
    t = np.linspace(1.0, 1.0 + tr.travel_time, 400)
    pulses = np.array([[tr.load(ti, xk, 2) for ti in t] for xk in x])
    for k in range(1, 6):
        shifted = np.array([tr.load(ti + k * A / tr.speed, x[k], 2) for ti in t])
        assert np.allclose(shifted, pulses[0], rtol=1e-9, atol=1e-6)
    # the peak of sleeper 0 is the axle load's share under a wheel, times two wheels / 2
    assert pulses.max() == pytest.approx(20e3 * rail_seat_share(0.0, A, L), rel=1e-3)
    assert np.all(pulses >= 0)


def test_a_long_track_carries_every_axle_on_it():
    tr = train(passages=1, x_from=-10.0, x_to=40.0)
    x = (np.arange(-20, 70) + 0.5) * A
    for t in np.linspace(1.4, 3.5, 9):  # both axles well inside
        total = sum(tr.load(t, xk, 2) for xk in x)
        assert total == pytest.approx(2 * 20e3, rel=1e-13)
        assert sum(tr.load(t, xk, 1) for xk in x) == pytest.approx(20e3, rel=1e-13)  # half model: one wheel


@pytest.mark.parametrize("kw, message", [
    ({"speed": 0}, "traffic.speed = 0: must be a number > 0 [m/s]"),
    ({"axle_load": -1.0}, "traffic.axle_load = -1.0: must be a number > 0 [N]"),
    ({"offsets": [1.0, 2.0]}, "traffic.axles = [1.0, 2.0]: must start with 0"),
    ({"offsets": [0.0, 2.0, 1.0]}, "traffic.axles = [0.0, 2.0, 1.0]: must start with 0 (the first axle) and not "),
    ({"x_to": -3.0}, "traffic.x_to = -3.0: must be beyond x_from = -2.0"),
    ({"passages": 0}, "traffic.passages = 0: must be an integer >= 1"),
])
def test_bad_trains_are_one_line_errors(kw, message):
    with pytest.raises(InputError) as err:
        train(**kw)
    assert message in str(err.value) and "\n" not in str(err.value)
