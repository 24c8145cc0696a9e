"""Bodies: particle state (spheres as structure-of-arrays), rigid and breakable clumps (shapes,
generators, mass properties, set-up), bonds, fragments, and rigid boxes (sleeper, platen, plate).
"""
