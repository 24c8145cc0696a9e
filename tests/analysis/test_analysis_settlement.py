"""Permanent settlement per cycle, its plastic and resilient parts, and the fits."""

import numpy as np
import pytest

from analysis import (CycleTable, fit_log, fit_power, permanent_settlement, plastic_settlement,
                      resilient_settlement)

N = np.arange(1.0, 101.0)


def test_log_law_recovered():
    fit = fit_log(N, 4e-3 + 1.5e-3 * np.log(N))
    assert fit.a == pytest.approx(4e-3, rel=1e-9)
    assert fit.b == pytest.approx(1.5e-3, rel=1e-9)
    assert fit.r2 == pytest.approx(1.0, abs=1e-12)
    assert fit(10.0) == pytest.approx(4e-3 + 1.5e-3 * np.log(10.0))


def test_power_law_recovered():
    fit = fit_power(N, 6e-3 * N ** 0.21)
    assert fit.s1 == pytest.approx(6e-3, rel=1e-9)
    assert fit.b == pytest.approx(0.21, rel=1e-9)
    assert fit.r2 == pytest.approx(1.0, abs=1e-12)


def test_noisy_data_r2_below_one():
    s = 4e-3 + 1.5e-3 * np.log(N) + np.random.default_rng(2).normal(0, 1e-4, N.size)
    fit = fit_log(N, s)
    assert 0.9 < fit.r2 < 1.0
    assert fit.b == pytest.approx(1.5e-3, rel=0.05)


def test_fit_errors():
    with pytest.raises(ValueError, match="positive"):
        fit_power(N, np.log(N))  # zero after the first cycle
    with pytest.raises(ValueError, match="at least 5 needed"):
        fit_log([1.0], [1e-3])
    with pytest.raises(ValueError, match="3 cycle"):  # 3 points carry no two-parameter law (issue #34)
        fit_log([1.0, 2.0, 3.0], [1e-3, 1.2e-3, 1.3e-3])
    with pytest.raises(ValueError, match=">= 1"):
        fit_log([0.0, 1.0, 2.0, 3.0, 4.0], [1e-3, 2e-3, 3e-3, 4e-3, 5e-3])


def test_plastic_and_resilient_parts(box_record):
    table = CycleTable.from_mapping(box_record.cycles)
    np.testing.assert_allclose(plastic_settlement(table), box_record.plastic, rtol=1e-12)
    np.testing.assert_allclose(resilient_settlement(table), box_record.resilient, rtol=1e-12)
    np.testing.assert_allclose(np.cumsum(plastic_settlement(table)), permanent_settlement(table),
                               rtol=1e-12)
    fit = fit_log(table.cycle, permanent_settlement(table))
    assert (fit.a, fit.b) == pytest.approx((box_record.a, box_record.b), rel=1e-9)
