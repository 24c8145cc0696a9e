"""The direct shear box (ASTM D3080), the one-file scene of docs/design.md (keys: `DEFAULTS`).

A base plane z = 0; a fixed lower frame (four faces of facets: a square of ``side`` [m] up to ``height``/2
[m], and a ledge beyond its +x face, its thick top) and the upper frame above it, translating along +x
while shearing; a frictionless platen (rigid box, z translation only, covering the moved frame) carrying
``normal_stress`` × ``side``² [N]. Stages: ``pour`` (a seeded loose cloud filling the box to ``height``;
settle), ``consolidate`` (the platen placed on the bed and loaded; settle), ``shear`` (the upper frame moves
at ``shear_velocity`` [m/s] up to ``shear_displacement`` [m]). ``results.h5`` (kind "shear_box",
`SHEAR_BOX_SERIES`): ``shear_displacement`` [m], ``shear_force`` [N] (−x force of the spheres on the upper
frame, an exact sum), ``normal_force`` [N] (on the platen), ``platen_z`` [m]."""
from ..boundaries.loads import Constant
from ..build.config import check_keys, run_settings, scene_from_dict
from ..build.validate import number
from ..driver import observables
from ..driver.results import series_writer, write_root_attrs
from ..driver.stages import Stage, check_no_steps, empty_tables
from ..errors import InputError
from ..format.schema import SHEAR_BOX_SERIES
from .common.preparation import PREPARATION_DEFAULTS, PreparedRun, add_cloud, check_preparation, pour_stage, \
    settle_stage

POSITIVE = {"side": 0.1, "height": 0.06, "platen_thickness": 0.01, "platen_mass": 0.2, "normal_stress": 1.0e4,
            "shear_velocity": 0.1, "shear_displacement": 0.008}  # [m], [kg], [Pa], [m/s]
DEFAULTS = {**POSITIVE, "ballast_material": "grains", "frame_material": "steel", "platen_material": "steel",
            **PREPARATION_DEFAULTS}
UPPER = 10  # facet rows: the lower frame and its ledge before, the upper frame from here


def settings(doc):
    """The [shear_box] table with defaults, checked (one-line InputError naming the key)."""
    check_keys("scene file", doc, {"simulation", "run", "materials", "shear_box"})
    check_keys("shear_box", doc["shear_box"], set(DEFAULTS))
    c = check_preparation("shear_box", {**DEFAULTS, **doc["shear_box"]})
    for k in POSITIVE:
        c[k] = number(f"shear_box.{k}", c[k], 0.0, lo_open=True, allow="a number > 0")
    for k in ("ballast_material", "frame_material", "platen_material"):
        if not isinstance(c[k], str) or c[k] not in doc.get("materials", {}):
            raise InputError(f"shear_box.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    if c["shear_displacement"] >= c["side"] / 2:
        raise InputError(f"shear_box.shear_displacement = {c['shear_displacement']!r}: must be < side/2 [m]")
    return c


def square_faces(a, z0, z1, dx=0.0):
    """8 triangles of the four faces x, y = ±a [m] between z0 and z1 [m], shifted by dx along x."""
    xy = [(-a + dx, -a), (a + dx, -a), (a + dx, a), (-a + dx, a), (-a + dx, -a)]
    return [t for (x0, y0), (x1, y1) in zip(xy, xy[1:]) for t in
            (((x0, y0, z0), (x1, y1, z0), (x1, y1, z1)), ((x0, y0, z0), (x1, y1, z1), (x0, y0, z1)))]


def box_scene(doc, c, state, tables):
    """The `Scene` of a stage: base, frames, the platen once placed, the spheres of ``tables``."""
    sim = {**doc.get("simulation", {}), "allow_initial_overlap": True}
    scene = scene_from_dict({"simulation": sim, "materials": doc["materials"]})
    a, h2, d, fm = c["side"] / 2, c["height"] / 2, c["shear_displacement"], c["frame_material"]
    scene.add_wall("z", 0.0, fm, sense=1, name="base")
    ledge = [((a, -a, h2), (a + d, -a, h2), (a + d, a, h2)), ((a, -a, h2), (a + d, a, h2), (a, a, h2))]
    for tri in square_faces(a, 0.0, h2) + ledge + square_faces(a, h2, state.get("frame_top") or c["height"]):
        scene.add_facet(tri, fm)
    if state.get("platen_z") is not None:
        load = Constant(c["normal_stress"] * 4 * a * a, label="shear_box")
        scene.add_box((d / 2, 0.0, state["platen_z"]), (a + d / 2, a, c["platen_thickness"] / 2), c["platen_material"],
                      c["platen_mass"], blocked="xyXYZ", load=load, damping=scene.settings.damping, name="platen")
    scene.add_sphere_columns(tables["particles"])
    return scene


def fill(doc, c, tables):
    """``tables`` with the seeded loose cloud of spheres that fills the box to ``height``."""
    a = c["side"] / 2
    return add_cloud(tables, doc, c, (-a, -a), (a, a), 0.0, 4 * a * a * c["height"], c["seed"], 0,
                     ("shear_box", "in the box"))


def check(doc):
    """Check a parsed shear-box scene file without running it (one-line InputError)."""
    c = settings(doc)
    run_settings(doc)
    box_scene(doc, c, {"platen_z": c["height"]}, fill(doc, c, empty_tables()))


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the shear box of a parsed scene file; returns the exit status."""
    check_no_steps(steps)
    return ShearBoxRun(path, doc, out_dir, comm, fresh).run()


class ShearBoxRun(PreparedRun):
    NAME = "shear_box"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = settings(doc)
        super().__init__(path, doc, out_dir, comm, fresh)

    def stage_list(self):
        return [pour_stage(self, self.scene, self.pour),
                settle_stage(self, self.scene, "consolidate", open=self.place_platen).then(close=self.record),
                Stage("shear", self.scene, self.shear_program, prepare=self.start_shear, record=self.stage_record,
                      close=lambda sim: self.stage_done(sim, "shear"))]

    def scene(self, tables):
        return box_scene(self.doc, self.c, self.state, tables)

    def open_results(self):
        out, doc = self.out / "results.h5", self.doc
        self.series = series_writer(out, SHEAR_BOX_SERIES, self.comm, restart_step=self.restart_step)
        self.loop.flush.append(self.series)
        if self.comm.rank == 0:
            write_root_attrs(out, {k: doc[k] for k in ("simulation", "materials", "shear_box")}, "shear_box", True)

    def close_results(self):
        self.series.close()

    def pour(self, tables):
        p = (tables := fill(self.doc, self.c, tables))["particles"]
        self.state["frame_top"] = 1.05 * float((p["pos"][:, 2] + p["radius"]).max())
        return tables, f"poured {len(p['radius'])} spheres, upper frame up to {self.state['frame_top']:.4f} m"

    def place_platen(self, tables):
        p = tables["particles"]
        self.state["platen_z"] = float((p["pos"][:, 2] + p["radius"]).max()) + self.c["platen_thickness"] / 2
        return tables, f"placed the platen, loaded with {self.c['normal_stress']:g} Pa"

    def start_shear(self, sim, scene, mid_stage):
        sim.facets.velocity[UPPER:, 0] = self.c["shear_velocity"]  # the upper frame moves

    def record(self, sim):
        """A row of results.h5 (collective: the frame force is an exact sum over all ranks)."""
        self.series.append({"step": sim.step, "time": sim.time, "dt": sim.dt, "platen_z": sim.boxes.center[0, 2],
                            "shear_displacement": float(sim.facets.vertices[UPPER, 0, 0]) + self.c["side"] / 2,
                            "shear_force": -float(observables.facet_force(sim, range(UPPER, len(sim.facets)))[0]),
                            "normal_force": sim.boxes.contact_force[0, 2]})

    def shear_program(self, sim, scene):
        """A row every run.output_every steps (1 if 0; the first at the end of consolidate)."""
        every = self.run_cfg["output_every"] or 1
        t_end = self.state["stage_t0"] + self.c["shear_displacement"] / self.c["shear_velocity"]

        def on_step(sim):
            if sim.step % every == 0:
                self.record(sim)
            self.snapshot(sim)

        return on_step, lambda sim: sim.time >= t_end, every, t_end

    def finish(self, sim, wall_s):
        prep = {"stages": ["pour", "consolidate"], "body": "platen centre"}
        super().finish(sim, wall_s, summary="shear_box", title="direct shear box", about=[], notes=[], preparation=prep,
                       stage_columns=[("sleeper_z", "platen centre z [m]", ".4f")], area=self.c["side"] ** 2)
