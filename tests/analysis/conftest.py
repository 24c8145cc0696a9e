"""Synthetic box-test records with known answers, and the check of a bad file's error, for the
analysis tests.

The record is a haversine load 3 <-> 40 kN at 1 Hz; the ballast force equals the load
(quasi-static). In cycle k the settlement rises linearly with stiffness k_load[k] up to the peak
and falls with k_unload[k], leaving a permanent settlement that follows S(N) = a + b ln N exactly.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from pdem.format.read import ResultFileError
from pdem.format.schema import write_results

F_MIN, F_MAX = 3.0e3, 40.0e3  # [N]
A, B = 4.0e-3, 1.5e-3         # S(N) = A + B ln N [m]


def make_box_record(n_cycles=8, per_cycle=200, a=A, b=B):
    """Series and per-cycle truth of a synthetic box test (SI units)."""
    dF = F_MAX - F_MIN
    k = np.arange(1, n_cycles + 1)
    s_end = a + b * np.log(k)
    s_start = np.concatenate(([0.0], s_end[:-1]))
    plastic = s_end - s_start
    k_unload = 40e6 * (1.0 + 0.1 * k)                # [N/m]
    resilient = dF / k_unload
    k_load = dF / (plastic + resilient)
    s_peak = s_start + dF / k_load

    i = np.arange(n_cycles * per_cycle + 1)
    time = i / per_cycle                              # 1 Hz
    load = F_MIN + dF * (1.0 - np.cos(2.0 * np.pi * time)) / 2.0
    c = np.minimum(i // per_cycle, n_cycles - 1)      # cycle index (0-based) of each sample
    j = i - c * per_cycle                             # sample within the cycle
    loading = j <= per_cycle // 2
    settlement = np.where(loading,
                          s_start[c] + (load - F_MIN) / k_load[c],
                          s_peak[c] - (F_MAX - load) / k_unload[c])
    cycles = dict(cycle=k.astype(float), t_start=k - 1.0, settlement_start=s_start,
                  settlement_peak=s_peak, settlement_end=s_end,
                  force_peak=np.full(n_cycles, F_MAX), force_min=np.full(n_cycles, F_MIN))
    series = dict(time=time, step=i * 1000.0, sleeper_load=load, sleeper_force=load.copy(),
                  sleeper_settlement=settlement)
    return SimpleNamespace(series=series, cycles=cycles, k_load=k_load, k_unload=k_unload,
                           plastic=plastic, resilient=resilient, a=a, b=b,
                           bounds=np.arange(0, len(i), per_cycle), n_cycles=n_cycles)


ATTRS = dict(scene={"name": "box_test", "f": 1.0, "F_min": F_MIN, "F_max": F_MAX},
             pdem_version="0.1.0", kind="box_test")


@pytest.fixture
def box_attrs():
    """Root attributes of the synthetic files."""
    return dict(ATTRS)


@pytest.fixture
def box_record():
    return make_box_record()


@pytest.fixture
def box_file(tmp_path, box_record):
    """A valid box-test results file with a /cycles table."""
    return write_results(tmp_path / "box.h5", box_record.series, box_record.cycles, ATTRS)


@pytest.fixture
def box_file_no_cycles(tmp_path, box_record):
    """The same test without /cycles (cycles must be detected)."""
    return write_results(tmp_path / "box_nocycles.h5", box_record.series, None, ATTRS)


@pytest.fixture
def expect_error(one_line_error):
    """``expect_error(read, path, *words)``: ``read(path)`` raises a ResultFileError of one line that
    names the file and every word; returns its message."""
    return lambda read, path, *words: one_line_error(ResultFileError, lambda: read(path), str(path), *words)
