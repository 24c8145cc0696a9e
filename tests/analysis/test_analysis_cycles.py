"""Splitting a record into cycles and the per-cycle table."""

import numpy as np
import pytest

from analysis import bounds_from_t_start, cycle_table, detect_bounds


def test_detect_bounds_at_load_minima(box_record):
    bounds = detect_bounds(box_record.series["sleeper_load"])
    np.testing.assert_array_equal(bounds, box_record.bounds)


def test_incomplete_last_cycle_is_dropped(box_record):
    load = box_record.series["sleeper_load"]
    cut = box_record.bounds[-2] + 140  # 70 % into the last cycle, still unloading
    bounds = detect_bounds(load[:cut])
    np.testing.assert_array_equal(bounds, box_record.bounds[:-1])


def test_preload_plateau_before_cycling(box_record):
    load = box_record.series["sleeper_load"]
    held = np.concatenate((np.full(50, load[0]), load))
    bounds = detect_bounds(held)
    assert bounds[0] == 50  # the last sample before the load starts to rise
    np.testing.assert_array_equal(bounds, box_record.bounds + 50)


def test_noise_near_mid_range_does_not_split_cycles(box_record):
    load = box_record.series["sleeper_load"]
    noisy = load + np.random.default_rng(0).normal(0.0, 0.01 * np.ptp(load), load.size)
    assert len(detect_bounds(noisy)) == box_record.n_cycles + 1


def test_constant_load_has_no_cycle():
    assert len(detect_bounds(np.full(10, 3e3))) == 0


def test_bounds_from_t_start(box_record):
    s = box_record.series
    bounds = bounds_from_t_start(s["time"], box_record.cycles["t_start"] + 1e-4)
    np.testing.assert_array_equal(bounds, box_record.bounds)
    with pytest.raises(ValueError, match="not increasing"):
        bounds_from_t_start(s["time"], [0.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="outside"):
        bounds_from_t_start(s["time"], [0.0, 1e3])


def test_cycle_table_matches_truth(box_record):
    s = box_record.series
    table = cycle_table(s["time"], s["sleeper_force"], s["sleeper_settlement"], box_record.bounds)
    for name, expected in box_record.cycles.items():
        np.testing.assert_allclose(getattr(table, name), expected, rtol=1e-12, atol=1e-12,
                                   err_msg=name)
    with pytest.raises(ValueError, match="no complete load cycle"):
        cycle_table(s["time"], s["sleeper_force"], s["sleeper_settlement"], [0])
