"""Building a simulation: the `Scene` declaration, scene files (TOML) and their one-line checks,
materials and initial packings.
"""
