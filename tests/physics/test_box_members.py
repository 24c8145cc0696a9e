"""Rigid boxes with a surface of member spheres (the thesis's clump sleeper, `pdem.bodies.boxes.BoxMembers`).

Truth: the sphere–sphere contact that Yade's tests validate (tests/validation): a sphere bouncing
and rolling on a member of a fixed box must follow, bit for bit, the trajectory it has on a fixed
sphere at the same place (a member is a sphere that does not move or spin); Newton's third law
(the box's force equals minus the sum of the forces on the spheres, math.fsum); statics (a box
with members resting on spheres carries its weight, and spheres lying on it press it with theirs);
a loaded member box on a fixed bed comes to rest where load + weight = Σ k_n·pen.
"""
import math

import numpy as np
import pytest
from factories import ball_and_steel

from pdem import InputError
from pdem.driver.observables import box_face_forces, box_forces

G = 9.81
R = 0.01
R_M = 0.005


def grid(n, spacing, z):
    """Offsets of an n × n plate of members at height z [m] (relative to the box centre)."""
    a = (np.arange(n) - (n - 1) / 2.0) * spacing
    x, y = np.meshgrid(a, a, indexing="ij")
    return np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])


def trajectory(on_member, steps=3000):
    """A sphere thrown with spin onto a fixed sphere of radius R_M at (0.001, -0.002, 0): its
    own (pos, vel, angvel) each 100 steps; the fixed sphere is a box member or a sphere."""
    sc, ball, steel = ball_and_steel(gravity=G)
    start = (0.0, 0.0, R + R_M - 2e-4)
    if on_member:
        sc.add_box((0.001, -0.002, 0.0), (R_M, R_M, R_M), steel, mass=1.0, fixed=True,
                   members=[(0.0, 0.0, 0.0)], member_radius=R_M)
        sc.add_spheres([start], R, ball, vel=[(0.3, -0.1, -0.2)], angvel=[(5.0, 20.0, -3.0)])
    else:
        sc.add_spheres([(0.001, -0.002, 0.0)], R_M, steel, fixed=True)
        sc.add_spheres([start], R, ball, vel=[(0.3, -0.1, -0.2)], angvel=[(5.0, 20.0, -3.0)])
    sim = sc.build()
    out = []
    for _ in range(steps // 100):
        sim.run(100)
        b = sim.bodies()
        k = int(np.argmax(b["radius"]))
        out.append(np.concatenate([b["pos"][k], b["vel"][k], b["angvel"][k]]))
    return np.array(out)


def test_member_contact_is_the_sphere_sphere_contact_bit_for_bit():
    """On a member or on a fixed sphere, the same bits: Ig2, Ip2 (radii r_m and r), the
    ratcheting-corrected relative velocity, friction sliding and rolling."""
    member, sphere = trajectory(True), trajectory(False)
    assert np.abs(member[0, 3:6] - member[-1, 3:6]).max() > 0.05  # the contact changed the motion
    assert np.array_equal(member, sphere)


def test_loaded_member_box_rests_on_fixed_spheres_newton_and_statics():
    """A box with a 4 × 4 plate of members under it, loaded by 20 N and its weight, on 16 fixed
    spheres right below the members: at rest, the spheres' forces sum to minus the box's
    (Newton, fsum), the box carries load + weight, and every member's overlap is
    (F + m g)/(16 k_n) with Yade's k_n of two spheres (2 E1 r1 E2 r2/(E1 r1 + E2 r2))."""
    from pdem.boundaries.loads import Constant

    sc, ball, steel = ball_and_steel(dt=2e-6, damping=0.4, gravity=G)
    offs = grid(4, 0.02, -0.01 + R_M)
    mass = 2.0
    sc.add_box((0.0, 0.0, 0.01 + R), (0.04, 0.04, 0.01), steel, mass=mass, blocked="xyXYZ", damping=0.4,
               load=Constant(20.0), members=offs, member_radius=R_M)
    beds = [(x, y, 0.0) for x, y, _ in offs]
    sc.add_spheres(beds, R, ball, fixed=True)
    sim = sc.build()
    sim.run(30000)
    kind = sim.kind("sphere_member")
    rows = kind.contacts.real_rows()
    assert len(rows) == 16
    on_spheres = math.fsum(kind.contacts.force[rows, 2])
    assert box_forces(sim)[0, 2] == pytest.approx(-on_spheres, rel=1e-14)
    total = 20.0 + mass * G
    assert box_forces(sim)[0, 2] == pytest.approx(total, rel=1e-6)
    kn = 2.0 * (1e9 * R_M) * (1e8 * R) / (1e9 * R_M + 1e8 * R)
    assert kind.contacts.params[rows, 0] == pytest.approx(kn, rel=1e-14)
    np.testing.assert_allclose(kind.contacts.overlap[rows], total / (16 * kn), rtol=1e-5)
    bottom, side = box_face_forces(sim)
    assert bottom[2] == pytest.approx(total, rel=1e-6) and side[2] == 0.0


def test_members_give_no_flat_faces_and_bad_members_are_refused():
    """A box with members has no sphere_box contacts (a sphere inside its extents but clear of
    its members feels nothing); a member outside the box, a radius <= 0: one-line errors."""
    sc, ball, steel = ball_and_steel()
    sc.add_box((0.0, 0.0, 0.0), (0.05, 0.05, 0.05), steel, mass=1.0, fixed=True,
               members=grid(2, 0.08, 0.0), member_radius=R_M)
    sc.add_spheres([(0.0, 0.0, 0.0)], R, ball)
    sim = sc.build()
    sim.run(10)
    assert sim.kind("sphere_box") is None
    assert np.array_equal(sim.bodies()["vel"][0], [0.0, 0.0, 0.0])
    for members, radius, what in (([(0.06, 0.0, 0.0)], R_M, "inside the box"), ([(0.0, 0.0, 0.0)], 0.0, "> 0"),
                                  ([[0.0, 0.0]], R_M, "[k, 3]")):
        sc, ball, steel = ball_and_steel(gravity=G)
        with pytest.raises(InputError, match=r"^boxes\[0\]\.member") as e:
            sc.add_box((0.0, 0.0, 0.0), (0.05, 0.05, 0.05), steel, mass=1.0, members=members, member_radius=radius)
        assert what in str(e.value) and "\n" not in str(e.value)
