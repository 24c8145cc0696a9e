"""bench.box_full reads the time split from the timing table a run stopped by --steps prints
(`pdem.simulation.Timers.table`): the parser and the table agree on every section."""
from bench.box_full import SPLIT, timing
from pdem.simulation import TIMERS, Timers


def test_timing_reads_every_section_of_the_table():
    t = Timers()
    for k, name in enumerate(TIMERS):
        t.seconds[name] = 1.25 * (k + 1) + 1e-3 * k
    text = "stopped at step 100\n" + t.table() + "\n"
    got = timing(text)
    assert set(SPLIT) == set(TIMERS)
    assert got == {k: round(t.seconds[k], 3) for k in SPLIT}
