"""Rigid boxes with free rotations (`pdem.bodies.boxes`, contact kind ``sphere_oriented_box``)
against rigid-body mechanics.

Truth is independent of pdem's output: Newton–Euler for a known force and moment (dv/dt = F/m,
dL/dt = τ, ω = L/I with the solid cuboid's I = m(a² + c²)/12), conservation of the total linear
and angular momentum of a sphere striking a free box off-centre, statics of a box on two
supports under an eccentric load (support forces from the force and moment balance, tilt from
the supports' stiffness, Yade's Ip2 formula for kn; frictionless: no shear moment), and the
closest-point geometry of a cuboid rotated by a known angle.
"""
import math

import numpy as np
import pytest
from factories import BALL, STEEL, ball_and_steel

from pdem import InputError
from pdem.boundaries.loads import Constant

R = 0.01
HALF = (0.1, 0.05, 0.02)
E_S, E_B = BALL["young"], STEEL["young"]
KN_BOX = 2.0 * (E_B * R) * (E_S * R) / (E_B * R + E_S * R)  # YADE_MODEL §4 with radius1 = radius2 = r


def _cuboid_inertia(m, half):
    a, b, c = 2.0 * np.asarray(half)
    return m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])


def test_known_moment_gives_newton_euler():
    """A free box in zero gravity pushed down by P at distance e from its centre along x:
    v_z = −P t/m, L_y = P e t (the moment while its tilt is still tiny), ω_y = L_y/I_y, no spin
    about x or z, and the tilt angle is Σ ω Δt."""
    dt, n, m, p, e = 1e-5, 400, 2.0, 3.0, 0.08
    sc, ball, steel = ball_and_steel(dt=dt)
    sc.add_spheres([(1.0, 1.0, 1.0)], R, ball, fixed=True)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=m, blocked="", load=Constant(p), load_point=(e, 0.0, 0.0))
    sim = sc.build()
    assert [k.name for k in sim.kinds] == ["sphere_sphere", "sphere_oriented_box"]
    tilt = 0.0
    for _ in range(n):
        sim.run(1)
        tilt += sim.boxes.angvel[0, 1] * dt
    b, t = sim.boxes, n * dt
    iy = _cuboid_inertia(m, HALF)[1]
    assert b.velocity[0] == pytest.approx([0.0, 0.0, -p * t / m], rel=1e-12, abs=1e-15)
    assert b.angmom[0, 1] == pytest.approx(p * e * t, rel=1e-6)
    assert b.angvel[0] == pytest.approx([0.0, p * e * t / iy, 0.0], rel=1e-6, abs=1e-15)
    assert math.asin(b.rotation[0, 0, 2]) == pytest.approx(tilt, rel=1e-9)  # R e_z = (sin θ, 0, cos θ)
    assert b.center[0, 0] == 0.0 and b.center[0, 1] == 0.0


def test_eccentric_impact_conserves_momentum():
    """A spinning sphere strikes a free box off-centre (zero gravity, friction): the total linear
    momentum and the total angular momentum about the origin (the box's L plus the orbital parts
    and the sphere's I ω) are conserved, and the box turns."""
    sc, ball, steel = ball_and_steel(dt=1e-6)
    sc.add_spheres([(0.07, 0.02, HALF[2] + R + 0.001)], R, ball, vel=[(0.1, 0.05, -1.0)], angvel=[(3.0, -2.0, 1.0)])
    mass = 0.5
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=mass, blocked="")
    sim = sc.build()
    p, b = sim.particles, sim.boxes

    def momenta():
        lin = p.mass[0] * p.vel[0] + mass * b.velocity[0]
        ang = (p.inertia[0] * p.angvel[0] + p.mass[0] * np.cross(p.pos[0], p.vel[0]) + b.angmom[0]
               + mass * np.cross(b.center[0], b.velocity[0]))
        return lin, ang

    lin0, ang0 = momenta()
    touched = 0
    for _ in range(60):
        sim.run(50)
        touched += len(sim.kind("sphere_oriented_box").contacts.real_rows())
    lin1, ang1 = momenta()
    assert touched > 0
    np.testing.assert_allclose(lin1, lin0, rtol=0, atol=1e-12 * np.abs(lin0).max())
    np.testing.assert_allclose(ang1, ang0, rtol=0, atol=1e-6 * np.abs(ang0).max())
    assert np.all(np.abs(b.angvel[0]) > 1e-3)


def test_contact_torque_is_moment_of_contact_forces():
    """One step of a sphere overlapping a free box's corner region: the torque summed on the box
    equals (x_c − c) × f with the contact point x_c = x − (r − pen/2) n and f = −(force on the
    sphere), from the contact table."""
    sc, ball, steel = ball_and_steel()
    x = np.array([HALF[0] + 0.004, -0.03, HALF[2] + 0.006])
    sc.add_spheres([x], R, ball, vel=[(0.2, 0.1, -0.3)])
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked="")
    sim = sc.build()
    sim.run(1)
    c = sim.contacts("sphere_oriented_box")
    n, pen, f = c["normal"][0], c["overlap"][0], -c["force"][0]
    point = x - (R - 0.5 * pen) * n
    np.testing.assert_allclose(sim.boxes.contact_torque[0], np.cross(point, f), rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(sim.boxes.contact_force[0], f)


def test_rotated_box_contact_geometry():
    """A box turned by 30° about z (a known moment turns it, then it is stopped by damping off):
    a sphere placed above its rotated top face and one off its rotated x face get the normal and
    overlap of the closest point in the box's own axes."""
    sc, ball, steel = ball_and_steel(dt=1e-6)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked="xyzXY")
    theta = math.radians(30.0)
    ex = np.array([math.cos(theta), math.sin(theta), 0.0])
    ey = np.array([-math.sin(theta), math.cos(theta), 0.0])
    x_face = (HALF[0] + R - 0.002) * ex + 0.01 * ey
    x_top = np.array([0.0, 0.0, HALF[2] + R - 0.003]) + 0.05 * ex
    sc.add_spheres([x_face, x_top], R, ball, fixed=True)
    sim = sc.build()
    q = np.array([math.cos(theta / 2), 0.0, 0.0, math.sin(theta / 2)])  # set the turned state directly
    sim.boxes.ori[0] = q
    sim.boxes.kernel_f[0, 9:18] = np.array([ex, ey, [0.0, 0.0, 1.0]]).T.ravel()
    sim.rebuild()
    sim.run(1)
    c = sim.contacts("sphere_oriented_box")
    order = np.argsort(c["gid1"])
    np.testing.assert_allclose(c["normal"][order[0]], ex, atol=1e-15)
    np.testing.assert_allclose(c["normal"][order[1]], [0.0, 0.0, 1.0], atol=1e-15)
    assert c["overlap"][order[0]] == pytest.approx(0.002, rel=1e-9)
    assert c["overlap"][order[1]] == pytest.approx(0.003, rel=1e-9)


def test_eccentric_load_on_two_supports_tilts_as_statics_says():
    """A box (z and the tilt about y free) on two fixed spheres at x = ±a under its weight W and a
    load P at x = e comes to rest with the support forces of the force and moment balance,
    R± = (W + P)/2 ± P e/(2a), and the tilt θ = (R+ − R−)/(k_n 2a) of the supports' springs."""
    g, m, p, e, a = 9.81, 2.0, 30.0, 0.06, 0.08
    sc, ball, _ = ball_and_steel(dt=2e-6, gravity=g)
    steel = sc.material(**{**STEEL, "friction_angle": 0.0})
    z = -HALF[2] - R
    sc.add_spheres([(-a, 0.0, z), (a, 0.0, z)], R, ball, fixed=True)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=m, blocked="xyXZ", damping=0.3, load=Constant(p),
               load_point=(e, 0.0, 0.0))
    sim = sc.build()
    sim.run(60000)
    c = sim.contacts("sphere_oriented_box")
    by_x = np.argsort([sim.body(int(gid))["pos"][0] for gid in c["gid1"]])
    fz = -c["force"][by_x, 2]  # force of each support on the box, up
    w = m * g
    expected = [(w + p) / 2 - p * e / (2 * a), (w + p) / 2 + p * e / (2 * a)]
    assert fz == pytest.approx(expected, rel=1e-4)
    theta = math.asin(sim.boxes.rotation[0, 0, 2])  # about +y: the loaded +x end goes down
    assert c["kn"] == pytest.approx([KN_BOX, KN_BOX], rel=1e-12)
    assert theta == pytest.approx((expected[1] - expected[0]) / (KN_BOX * 2 * a), rel=1e-3)
    assert np.abs(sim.boxes.angvel[0, 1]) < 1e-6


@pytest.mark.parametrize("inertia, field", [
    ((1.0, -1.0, 1.0), "boxes.sleeper.inertia"),
    ([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "boxes.sleeper.inertia"),
    ([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "boxes.sleeper.inertia"),
    ("heavy", "boxes.sleeper.inertia"),
])
def test_bad_inertia_is_one_line_naming_the_field(inertia, field):
    sc, ball, steel = ball_and_steel()
    with pytest.raises(InputError) as err:
        sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked="xyXZ", inertia=inertia, name="sleeper")
    assert str(err.value).startswith(field) and "\n" not in str(err.value)


def test_member_box_with_free_rotation_is_refused():
    sc, ball, steel = ball_and_steel()
    with pytest.raises(InputError) as err:
        sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked="xyXZ", members=[(0.0, 0.0, 0.0)],
                   member_radius=0.01, name="sleeper")
    assert str(err.value).startswith("boxes.sleeper.blocked") and "\n" not in str(err.value)


def test_given_tensor_has_its_principal_axes():
    """A non-diagonal tensor: the principal moments are its eigenvalues and R starts as the identity
    (the box is axis-aligned until it turns)."""
    sc, ball, steel = ball_and_steel()
    sc.add_spheres([(1.0, 1.0, 1.0)], R, ball, fixed=True)
    t = np.array([[2.0, 0.5, 0.0], [0.5, 3.0, 0.0], [0.0, 0.0, 4.0]])
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked="", inertia=t)
    sim = sc.build()
    b = sim.boxes
    np.testing.assert_allclose(np.sort(b.inertia[0]), np.linalg.eigvalsh(t), rtol=1e-14)
    np.testing.assert_allclose(b.axes[0] @ np.diag(b.inertia[0]) @ b.axes[0].T, t, atol=1e-14)
    np.testing.assert_array_equal(b.rotation[0], np.eye(3))


def test_axis_aligned_and_rotating_boxes_keep_their_kinds():
    """In one scene an axis-aligned box keeps the ``sphere_box`` kind and a rotating one gets
    ``sphere_oriented_box``: each sphere touches its own box through its own kind only, and the
    axis-aligned box gets no torque."""
    sc, ball, steel = ball_and_steel()
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, fixed=True)
    sc.add_box((0.5, 0.0, 0.0), HALF, steel, mass=1.0, blocked="xyXZ")
    sc.add_spheres([(0.0, 0.0, HALF[2] + R - 0.001), (0.55, 0.0, HALF[2] + R - 0.001)], R, ball, fixed=True)
    sim = sc.build()
    sim.run(1)
    aligned, oriented = sim.contacts("sphere_box"), sim.contacts("sphere_oriented_box")
    assert aligned["index"].tolist() == [0] and oriented["index"].tolist() == [1]
    assert aligned["gid1"].tolist() == [0] and oriented["gid1"].tolist() == [1]
    assert sim.boxes.contact_torque[0].tolist() == [0.0, 0.0, 0.0]
    # pushed down (F_z < 0) at 0.05 m along +x from the centre: the moment −0.05 F_z about +y
    assert sim.boxes.contact_force[1, 2] < 0.0
    assert sim.boxes.contact_torque[1] == pytest.approx([0.0, -0.05 * sim.boxes.contact_force[1, 2], 0.0], rel=1e-12)
