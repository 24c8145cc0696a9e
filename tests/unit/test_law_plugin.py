"""The plug-in point of contact laws: a second law (tests/unit/toy_law.py, the linear law
without the Coulomb cap) is registered from outside pdem/ and selected by name; its scene runs
the generated loops, and the law's difference shows exactly where it should.

A sphere pressed on a wall (gravity) and given a sideways velocity: with the linear law the
shear force is capped at |Fn| tan φ and the sphere slides; without the cap it sticks (the shear
spring only oscillates) and |Fs| exceeds |Fn| tan φ. Before the cap is reached both laws give
the same bits (same Ip2, same spring)."""
import numpy as np
import toy_law

from pdem import Scene
from pdem.contact import LAWS, register_law

R, RHO, E, PHI = 0.01, 2600.0, 1e7, 0.3


def slide(law, steps):
    sc = Scene(dt=1e-6, gravity=(0.0, 0.0, -9.81), law=law, allow_initial_overlap=True)
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=PHI)
    sc.add_spheres([(0.0, 0.0, R - 1e-6)], R, m, vel=[(0.05, 0.0, 0.0)])
    sc.add_wall("z", 0.0, m, sense=1)
    sim = sc.build()
    ratios = []
    for _ in range(steps):
        sim.run(1)
        c = sim.contacts("sphere_wall")
        fn = np.linalg.norm(c["normal_force"][0])
        fs = np.linalg.norm(c["shear_force"][0])
        ratios.append(fs / (fn * np.tan(PHI)))
    return sim, np.array(ratios)


def test_toy_law_is_selected_by_name_and_differs_only_past_the_cap():
    register_law(toy_law)
    assert LAWS["linear_uncapped"] is toy_law
    lin, r_lin = slide("linear", 400)
    toy, r_toy = slide("linear_uncapped", 400)
    assert toy.law is toy_law and toy.spec["settings"]["law"] == "linear_uncapped"
    assert np.max(r_lin) <= 1.0 + 1e-12  # the cap holds
    assert np.max(r_toy) > 1.5  # no cap: the spring loads far past it
    first_capped = int(np.argmax(r_lin >= 1.0 - 1e-12))
    assert first_capped > 0
    np.testing.assert_array_equal(r_lin[:first_capped], r_toy[:first_capped])  # identical before the cap


def test_a_law_missing_pieces_is_refused():
    import types

    import pytest

    from pdem import InputError

    with pytest.raises(InputError, match="lacks"):
        register_law(types.SimpleNamespace(NAME="broken"))


def test_a_law_without_stiffness_keys_is_refused():
    import types

    import pytest

    from pdem import InputError
    from pdem.contact import linear, stiffness_keys

    pieces = {k: v for k, v in vars(linear).items() if k != "STIFFNESS_KEYS"}
    with pytest.raises(InputError, match="lacks STIFFNESS_KEYS"):
        register_law(types.SimpleNamespace(**pieces))
    assert stiffness_keys("viscous") == ("kn", "ks", "rolling_stiffness")
    assert stiffness_keys() == ("kn", "ks", "rolling_stiffness", "young")  # what the driver scales
