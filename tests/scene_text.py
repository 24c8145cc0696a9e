"""Scene-file text shared by the scene tests (box test, its options, track): the thesis's three
materials at the studies' scaled stiffness (ballast E_k 2.8e6 Pa, steel 10 E_k, rubber 0.1 E_k)."""

BOX_MATERIALS = """[materials.ballast]
density = 2600.0
young = 2.8e6
poisson = 0.3
friction_angle = 0.5

[materials.steel]
density = 7850.0
young = 2.8e7
poisson = 0.25
friction_angle = 0.5

[materials.rubber]
density = 1000.0
young = 2.8e5
poisson = 0.5
friction_angle = 0.7
"""
