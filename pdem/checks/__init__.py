"""Checks of a running simulation: diagnostics (energy, overlaps, the blow-up check) and the runaway
guard; each stops a run with one line naming the cause (`pdem.errors.InstabilityError`).
"""
