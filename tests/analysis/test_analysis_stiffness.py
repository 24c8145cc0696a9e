"""Loading, unloading and resilient stiffness recovered from synthetic loops."""

import numpy as np
import pytest

from analysis import (CycleTable, cycle_stiffness, cycle_table, loading_stiffness,
                      resilient_stiffness, slope, unloading_stiffness)

RTOL = 1e-6


def loop(k_load, k_unload, offset=2e-3, f_min=3e3, f_max=40e3, n=401):
    """One haversine load-unload loop, piecewise linear: loading k_load, unloading k_unload."""
    t = np.linspace(0.0, 1.0, n)
    force = f_min + (f_max - f_min) * (1 - np.cos(2 * np.pi * t)) / 2
    peak = n // 2
    u_peak = offset + (f_max - f_min) / k_load
    disp = np.where(np.arange(n) <= peak, offset + (force - f_min) / k_load,
                    u_peak - (f_max - force) / k_unload)
    return force, disp


@pytest.mark.parametrize("k_load, k_unload", [(30e6, 120e6), (2.5e8, 2.5e9), (1e5, 1e5)])
def test_piecewise_linear_loop(k_load, k_unload):
    force, disp = loop(k_load, k_unload)
    assert disp[-1] > disp[0]  # a permanent offset remains
    assert loading_stiffness(force, disp) == pytest.approx(k_load, rel=RTOL)
    assert unloading_stiffness(force, disp) == pytest.approx(k_unload, rel=RTOL)


@pytest.mark.parametrize("fraction", [0.1, 0.3, 0.5, 1.0])
def test_unloading_fraction(fraction):
    force, disp = loop(30e6, 120e6)
    assert unloading_stiffness(force, disp, fraction=fraction) == pytest.approx(120e6, rel=RTOL)


def test_unloading_uses_only_the_start_of_the_branch():
    """Unloading stiff for the first 40 % of the drop, then soft: the slope is the stiff one."""
    force, disp = loop(30e6, 120e6)
    peak = int(np.argmax(force))
    f_kink = force[peak] - 0.4 * (force[peak] - force[-1])
    after = (np.arange(len(force)) > peak) & (force < f_kink)
    u_kink = disp[peak] - (force[peak] - f_kink) / 120e6
    disp = np.where(after, u_kink - (f_kink - force) / 10e6, disp)
    assert unloading_stiffness(force, disp, fraction=0.3) == pytest.approx(120e6, rel=RTOL)
    assert unloading_stiffness(force, disp, fraction=1.0) < 60e6


def test_loading_window_excludes_seating():
    """A soft seating phase below 5 % of the force range does not enter the 10-90 % window."""
    force, disp = loop(30e6, 120e6)
    peak = int(np.argmax(force))
    f_seat = force[0] + 0.05 * (force[peak] - force[0])
    seating = (np.arange(len(force)) <= peak) & (force < f_seat)
    disp = disp.copy()
    extra = np.where(seating, (f_seat - force) / 1e6, 0.0)  # softer below f_seat
    disp[: peak + 1] -= extra[: peak + 1]
    assert loading_stiffness(force, disp) == pytest.approx(30e6, rel=RTOL)
    assert loading_stiffness(force, disp, window=(0.0, 1.0)) < 29e6


def test_slope_regresses_force_on_displacement():
    rng = np.random.default_rng(1)
    u = np.linspace(0, 1e-3, 2001)
    f = 5e7 * u + rng.normal(0.0, 500.0, u.size)  # noise in the force only
    assert slope(f, u) == pytest.approx(5e7, rel=1e-2)
    assert slope([1.0, 2.0], [0.0, 0.0]) == np.inf


def test_bad_parameters():
    force, disp = loop(30e6, 120e6)
    with pytest.raises(ValueError, match="window"):
        loading_stiffness(force, disp, window=(0.9, 0.1))
    with pytest.raises(ValueError, match="fraction"):
        unloading_stiffness(force, disp, fraction=0.0)
    with pytest.raises(ValueError, match="equal length"):
        loading_stiffness(force, disp[:-1])


def test_per_cycle_stiffness(box_record):
    s = box_record.series
    table = cycle_table(s["time"], s["sleeper_force"], s["sleeper_settlement"], box_record.bounds)
    k = cycle_stiffness(s["sleeper_force"], s["sleeper_settlement"], box_record.bounds, table,
                        load=s["sleeper_load"])
    np.testing.assert_allclose(k.loading, box_record.k_load, rtol=RTOL)
    np.testing.assert_allclose(k.unloading, box_record.k_unload, rtol=RTOL)
    # resilient = (F_peak - F_min) / rebound = k_unload for a linear unloading branch
    np.testing.assert_allclose(k.resilient, box_record.k_unload, rtol=RTOL)


def test_resilient_stiffness_nan_without_rebound():
    one = np.ones(2)
    table = CycleTable(cycle=np.array([1.0, 2.0]), t_start=np.array([0.0, 1.0]),
                       settlement_start=np.array([0.0, 1e-3]), settlement_peak=np.array([1e-3, 2e-3]),
                       settlement_end=np.array([1e-3, 1.5e-3]), force_peak=40e3 * one,
                       force_min=3e3 * one)
    k = resilient_stiffness(table)
    assert np.isnan(k[0])
    assert k[1] == pytest.approx(37e3 / 0.5e-3)
