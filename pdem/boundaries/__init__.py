"""Boundaries: walls (infinite planes), facets (triangles) and the force programs of loaded bodies.
"""
