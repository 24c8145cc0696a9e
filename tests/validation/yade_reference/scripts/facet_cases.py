# Sphere r=0.01 against one fixed facet (utils.facet), damping 0.2, dt 1e-6, gravity, recorded every
# 500 iterations up to 20000, and also every 10 iterations while the contact is real (every 100 for
# facet_face_slide, whose contact lasts the whole run).  This file holds all four scenes; run one of the wrappers
# facet_face.py, facet_face_slide.py, facet_edge.py, facet_vertex.py, facet_tilted.py (each sets CASE and exec's this file):
#   cd tests/validation/yade_reference && yade -n -j1 -x scripts/facet_face.py
import sys, os, math
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *

DAMPING, DT, R = 0.2, 1e-6, 0.01
TRI = [(0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.1, 0.0)]
ANG = math.radians(20.0)


def rot_x(p, a=ANG):
    # rotation by angle a about the x axis: (x, y cos a - z sin a, y sin a + z cos a)
    return (p[0], p[1] * math.cos(a) - p[2] * math.sin(a), p[1] * math.sin(a) + p[2] * math.cos(a))


if CASE == 'facet_face':
    verts, c, v, w = TRI, (0.02, 0.02, 0.011), (0.3, 0.1, -0.2), (0.0, 0.0, 0.0)
    note = 'sphere lands on the face (gap 1 mm) with vel (0.3,0.1,-0.2) and slides on it'
elif CASE == 'facet_face_slide':
    # starts at the static overlap (pen = m g / kn, kn with radius1 = 2r for the facet) and slides
    kna, knb = 2e9 * (2 * R), 1e8 * R
    kn = 2 * kna * knb / (kna + knb)
    m = 2600 * (4. / 3) * math.pi * R ** 3
    verts, c, v, w = TRI, (0.02, 0.02, R - m * 9.81 / kn), (0.3, 0.1, 0.0), (0.0, 0.0, 0.0)
    note = 'sphere starts on the face at the static overlap and slides, then rolls, on it'
elif CASE == 'facet_edge':
    # hypotenuse x+y=0.1; in-plane distance of (0.055,0.055) from it = 0.01/sqrt(2) = 7.07 mm;
    # at z=0.0072 the distance to the edge is 10.09 mm (gap ~0.09 mm): edge contact after a short fall
    verts, c, v, w = TRI, (0.055, 0.055, 0.0072), (-0.02, -0.02, 0.0), (0.0, 0.0, 0.0)
    note = 'centre outside the triangle projection, within r of the hypotenuse: edge contact'
elif CASE == 'facet_vertex':
    # (0.106,-0.004): beyond vertex (0.1,0,0) (outside both adjacent edges); in-plane distance 7.21 mm,
    # at z=0.0071 the distance to the vertex is 10.12 mm: vertex contact after a short fall
    verts, c, v, w = TRI, (0.106, -0.004, 0.0071), (-0.02, 0.01, 0.0), (0.0, 0.0, 0.0)
    note = 'centre in the vertex region of (0.1,0,0): vertex contact'
elif CASE == 'facet_tilted':
    # facet (-0.1,0,0),(0.1,0,0),(0,0.2,0) rotated 20 deg about x (uphill = +y); the sphere starts
    # 1e-6 m above the face at in-plane point (0, 0.12) with 0.2 m/s downhill along the slope, no spin:
    # it slides, then rolls down (towards -y)
    verts = [rot_x(p) for p in [(-0.1, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.2, 0.0)]]
    c = rot_x((0.0, 0.12, R + 1e-6))
    v = rot_x((0.0, -0.2, 0.0))
    w = (0.0, 0.0, 0.0)
    note = 'facet tilted 20 deg about x; sphere slides then rolls downhill (-y)'
else:
    raise ValueError(CASE)

mF = add_material('steelLike', 7850, 2e9, 0.3, 0.4)
mS = add_material('sphereMat', 2600, 1e8, 0.3, 0.4)
O.bodies.append(utils.facet(verts, material=mF))  # fixed=True by default
s = O.bodies.append(utils.sphere(c, R, material=mS))
O.bodies[s].state.vel = v
O.bodies[s].state.angVel = w
setup_engines(DAMPING, DT)
desc = [describe_body(b) for b in O.bodies]
desc[0]['vertices_input'] = [list(map(float, p)) for p in verts]
iters = [0, 1, 2, 3, 10, 100] + list(range(500, 20001, 500))
# dense sampling of the short impacts; the sustained contact of facet_face_slide only every 100
recs, events = run_and_record(iters, contact_every=(100 if CASE == 'facet_face_slide' else 10))
write_json(CASE + '.json', CASE, DAMPING, DT, desc, recs, events, extra={'note': note})
