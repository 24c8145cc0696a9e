"""Seed variability statistics against textbook values (Student's t table, a hand-computed set)."""
import numpy as np
import pytest

from analysis.variability import student_t_quantile, variability


@pytest.mark.parametrize("dof, p, t", [(9, 0.975, 2.262157), (1, 0.975, 12.706205), (4, 0.95, 2.131847),
                                       (30, 0.995, 2.749996), (1000, 0.975, 1.962339)])
def test_t_quantiles_match_the_table(dof, p, t):
    assert student_t_quantile(p, dof) == pytest.approx(t, abs=2e-6)


def test_statistics_of_a_known_sample():
    v = variability([2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0])
    assert v.n == 8 and v.mean == 5.0 and v.minimum == 2.0 and v.maximum == 9.0
    assert v.std == pytest.approx(np.sqrt(32.0 / 7.0), rel=1e-15)
    assert v.cov == pytest.approx(np.sqrt(32.0 / 7.0) / 5.0, rel=1e-15)
    half = 2.364624 * np.sqrt(32.0 / 7.0) / np.sqrt(8)  # t_{0.975, 7}
    assert (v.ci_low, v.ci_high) == pytest.approx((5.0 - half, 5.0 + half), abs=1e-5)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="at least 2 finite values"):
        variability([1.0])
    with pytest.raises(ValueError, match="at least 2 finite values"):
        variability([1.0, np.nan])
