"""pdem.io.snapshots: gid-ordered particle snapshots and blocks (cells beside the particles) whose
XDMF indexes match the HDF5 file; meshio's XDMF time-series reader sees every step."""

import errno
import json
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from io_fakecomm import run_ranks

from pdem.io.snapshots import Block, SnapshotError, SnapshotWriteError, SnapshotWriter

NUMPY_TYPE = {("Float", "8"): "float64", ("Float", "4"): "float32", ("Int", "8"): "int64",
              ("Int", "4"): "int32", ("UInt", "1"): "uint8"}


def particles(step, gids):
    gids = np.asarray(gids, dtype=np.int64)
    pos = np.stack([gids * 0.01, np.full(gids.size, step * 1e-3), -gids * 0.02], axis=1)
    return {"gid": gids, "position": pos, "radius": 0.005 + gids * 1e-4,
            "velocity": pos * 2.0, "fields": {"angvel": -pos, "material": gids % 3, "broken": gids % 2 == 1}}


def write_two_ranks(directory, steps, append=False, restart_step=None):
    def body(comm):
        w = SnapshotWriter(directory, comm=comm, append=append, restart_step=restart_step)
        gids = [5, 1, 3] if comm.rank == 0 else [4, 0, 2, 6]
        for s in steps:
            w.write(s, s * 1e-4, **particles(s, gids))

    _, errors = run_ranks(2, body)
    assert errors == [None, None]


PARTICLE_ATTRIBUTES = {"position": "Vector", "radius": "Scalar", "velocity": "Vector", "gid": "Scalar",
                       "angvel": "Vector", "material": "Scalar", "broken": "Scalar"}


def check_xdmf(xmf_path, attributes=PARTICLE_ATTRIBUTES, topology="Polyvertex"):
    """One temporal collection; every HDF reference exists with the declared shape and type (the
    topology's rows are the cells, the geometry's and node attributes' the vertices, cell
    attributes' the cells); returns the grids found (name, time, cells)."""
    root = ET.parse(xmf_path).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    (collection,) = root.find("Domain")
    assert collection.get("GridType") == "Collection" and collection.get("CollectionType") == "Temporal"
    grids = []
    with h5py.File(xmf_path.parent / "snapshots.h5", "r") as f:
        for grid in collection:
            topo = grid.find("Topology")
            cells, per_cell = int(topo.get("NumberOfElements")), int(topo.get("NodesPerElement"))
            assert topo.get("TopologyType") == topology
            vertices = int(grid.find("Geometry/DataItem").get("Dimensions").split()[0])
            for item in grid.iter("DataItem"):
                assert item.get("Format") == "HDF"
                file_name, dataset = item.text.strip().split(":")
                assert file_name == "snapshots.h5" and dataset in f, item.text
                ds = f[dataset]
                dims = tuple(int(d) for d in item.get("Dimensions").split())
                assert ds.shape == dims, item.text
                assert ds.dtype == NUMPY_TYPE[(item.get("NumberType"), item.get("Precision"))]
            assert tuple(f[topo.find("DataItem").text.split(":")[1]].shape) == (cells, per_cell)
            for a in grid.findall("Attribute"):
                rows = int(a.find("DataItem").get("Dimensions").split()[0])
                assert rows == (vertices if a.get("Center") == "Node" else cells), a.get("Name")
            names = {a.get("Name"): a.get("AttributeType") for a in grid.findall("Attribute")}
            assert names == attributes
            g = f[grid.get("Name")]
            assert float(grid.find("Time").get("Value")) == g.attrs["time"]
            grids.append((grid.get("Name"), float(grid.find("Time").get("Value")), cells))
    return grids


def test_snapshots_ordered_by_gid_and_xdmf_consistent(tmp_path):
    write_two_ranks(tmp_path, [0, 100, 200])
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        assert f.attrs["schema"] == "pdem-snapshots"
        g = f["step_000000000100"]
        expected = particles(100, np.arange(7))
        np.testing.assert_array_equal(g["gid"][()], np.arange(7))
        for key in ("position", "radius", "velocity"):
            np.testing.assert_array_equal(g[key][()], expected[key])
        np.testing.assert_array_equal(g["angvel"][()], expected["fields"]["angvel"])
        assert g["broken"].dtype == np.uint8
        np.testing.assert_array_equal(g["broken"][()], expected["fields"]["broken"])
        np.testing.assert_array_equal(g["connectivity"][()].ravel(), np.arange(7))
    grids = check_xdmf(tmp_path / "snapshots.xmf")
    assert grids == [("step_000000000000", 0.0, 7), ("step_000000000100", 0.01, 7),
                     ("step_000000000200", 0.02, 7)]


def test_meshio_reads_every_step_of_the_xdmf(tmp_path):
    """meshio's time-series reader takes its mesh from the first step; every step's own positions
    and fields come with read_data(k) (the node attribute "position"), also the last step's."""
    meshio = pytest.importorskip("meshio", reason="meshio is an optional test dependency")
    write_two_ranks(tmp_path, [0, 100, 200])
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "snapshots.xmf")) as reader:
        points, cells = reader.read_points_cells()
        np.testing.assert_array_equal(points, particles(0, np.arange(7))["position"])
        assert cells[0].type == "vertex" and len(cells[0].data) == 7
        assert reader.num_steps == 3
        for k, step in enumerate([0, 100, 200]):
            t, point_data, _ = reader.read_data(k)
            assert t == step * 1e-4
            expected = particles(step, np.arange(7))
            for key in ("position", "radius", "velocity", "gid"):
                np.testing.assert_array_equal(point_data[key], expected[key])
            np.testing.assert_array_equal(point_data["angvel"], expected["fields"]["angvel"])


def test_append_after_restart_drops_later_snapshots(tmp_path):
    write_two_ranks(tmp_path, [0, 100, 200, 300])
    write_two_ranks(tmp_path, [200, 250], append=True, restart_step=150)
    names = [g[0] for g in check_xdmf(tmp_path / "snapshots.xmf")]
    assert names == ["step_000000000000", "step_000000000100", "step_000000000200", "step_000000000250"]
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        assert "step_000000000300" not in f


def test_damaged_file_is_moved_aside_on_append(tmp_path):
    write_two_ranks(tmp_path, [0, 100])
    h5 = tmp_path / "snapshots.h5"
    h5.write_bytes(h5.read_bytes()[:1000])  # as if killed while writing a snapshot
    lines = []
    w = SnapshotWriter(tmp_path, append=True, restart_step=100, log=lines.append)
    assert len(lines) == 1 and "snapshots.h5 is damaged" in lines[0] and "snapshots.h5.damaged" in lines[0]
    w.write(150, 0.015, **particles(150, [2, 0, 1]))
    assert [g[0] for g in check_xdmf(tmp_path / "snapshots.xmf")] == ["step_000000000150"]


def test_duplicate_gid_raises_on_every_rank(tmp_path):
    def body(comm):
        w = SnapshotWriter(tmp_path, comm=comm)
        w.write(1, 0.0, **particles(1, [0, 1] if comm.rank == 0 else [1, 2]))

    _, errors = run_ranks(2, body)
    for exc in errors:
        assert isinstance(exc, SnapshotError) and "gid 1 passed twice" in str(exc)
        assert not isinstance(exc, SnapshotWriteError)  # a bug upstream, not the system's failure


def test_a_failed_write_raises_snapshot_write_error_on_every_rank(tmp_path, monkeypatch):
    """Rank 0's write failing with an OSError (disk full) or MemoryError: `SnapshotWriteError`
    (exit status 5) on every rank, naming the step and the cause."""
    def full(self, *args):
        raise OSError(errno.ENOSPC, "No space left on device", str(self.h5_path))

    monkeypatch.setattr(SnapshotWriter, "_write_rank0", full)

    def body(comm):
        SnapshotWriter(tmp_path, comm=comm).write(7, 0.0, **particles(7, [0, 1] if comm.rank == 0 else [2]))

    _, errors = run_ranks(2, body)
    for exc in errors:
        assert isinstance(exc, SnapshotWriteError), exc
        assert "snapshots.h5: step 7:" in str(exc) and "No space left on device" in str(exc)


# ---------------------------------------------------------------------------- blocks
def unit_square(z):
    return np.array([[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]])


def blocks(step):
    """A wall square moving up with the step, a triangle, and lines joining particle gids."""
    return {"walls": Block("Quadrilateral", [[0, 1, 2, 3]], unit_square(step * 1e-3),
                           {"wall": np.array([0], np.int32), "force": [[0.0, 0.0, float(step)]]}),
            "facets": Block("Triangle", [[0, 1, 2]], unit_square(0.5)[:3], {"facet": [7]}),
            "contacts": Block("Polyline", [[0, 6], [3, 2], [5, 1]][: 1 + step // 100],
                              cell_fields={"normal_force": np.arange(1 + step // 100) + 0.5})}


def write_blocks_two_ranks(directory, steps, contacts=True):
    def body(comm):
        w = SnapshotWriter(directory, comm=comm)
        gids = [5, 1, 3] if comm.rank == 0 else [4, 0, 2, 6]
        for s in steps:
            b = blocks(s)
            if not contacts:
                del b["contacts"]
            # the other ranks pass rubbish: the writer only reads rank 0's blocks
            w.write(s, s * 1e-4, **particles(s, gids), blocks=b if comm.rank == 0 else {"x": None})

    _, errors = run_ranks(2, body)
    assert errors == [None, None]


def test_blocks_in_their_groups_and_indexes(tmp_path):
    write_blocks_two_ranks(tmp_path, [0, 100, 200])
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        g = f["step_000000000200"]
        assert g["walls"].attrs["topology"] == "Quadrilateral" and int(g["walls"].attrs["on_particles"]) == 0
        np.testing.assert_array_equal(g["walls/points"][()], unit_square(0.2))
        np.testing.assert_array_equal(g["walls/connectivity"][()], [[0, 1, 2, 3]])
        np.testing.assert_array_equal(g["walls/force"][()], [[0.0, 0.0, 200.0]])
        # lines join particle gids: their vertices are the rows of the gid-ordered particles
        assert int(g["contacts"].attrs["on_particles"]) == 1 and "points" not in g["contacts"]
        rows = g["contacts/connectivity"][()]
        np.testing.assert_array_equal(g["gid"][()][rows], [[0, 6], [3, 2], [5, 1]])
        np.testing.assert_array_equal(g["contacts/normal_force"][()], [0.5, 1.5, 2.5])
    particle_names = [n for n, _, _ in check_xdmf(tmp_path / "snapshots.xmf")]
    walls = check_xdmf(tmp_path / "snapshots_walls.xmf", {"position": "Vector", "wall": "Scalar", "force": "Vector"},
                       "Quadrilateral")
    facets = check_xdmf(tmp_path / "snapshots_facets.xmf", {"position": "Vector", "facet": "Scalar"}, "Triangle")
    lines = check_xdmf(tmp_path / "snapshots_contacts.xmf", {"position": "Vector", "normal_force": "Scalar"},
                       "Polyline")
    assert [n for n, _, _ in walls] == [n for n, _, _ in facets] == particle_names
    assert [c for _, _, c in walls] == [1, 1, 1] and [c for _, _, c in lines] == [1, 2, 3]
    root = ET.parse(tmp_path / "snapshots_contacts.xmf").getroot()
    geometry = root.find("Domain/Grid/Grid/Geometry/DataItem").text
    assert geometry.strip() == "snapshots.h5:/step_000000000000/position"


def test_meshio_reads_the_last_step_of_a_block(tmp_path):
    meshio = pytest.importorskip("meshio", reason="meshio is an optional test dependency")
    write_blocks_two_ranks(tmp_path, [0, 100, 200])
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "snapshots_contacts.xmf")) as reader:
        reader.read_points_cells()
        t, point_data, cell_data = reader.read_data(reader.num_steps - 1)
    assert t == 200 * 1e-4
    np.testing.assert_array_equal(point_data["position"], particles(200, np.arange(7))["position"])
    np.testing.assert_array_equal(cell_data["normal_force"][0], [0.5, 1.5, 2.5])


def test_a_fresh_run_removes_the_old_block_indexes(tmp_path):
    write_blocks_two_ranks(tmp_path, [0, 100])
    assert (tmp_path / "snapshots_contacts.xmf").exists()
    (tmp_path / "snapshots_notes.xmf.txt").write_text("a user's file")
    write_blocks_two_ranks(tmp_path, [0], contacts=False)
    assert not (tmp_path / "snapshots_contacts.xmf").exists() and (tmp_path / "snapshots_walls.xmf").exists()
    assert (tmp_path / "snapshots_notes.xmf.txt").exists()


@pytest.mark.parametrize("block, words", [
    (Block("Polyline", [[0, 9]]), "gid 9 is no particle"),
    (Block("Triangle", [[0, 1, 3]], np.zeros((3, 3))), "vertex outside 0..2"),
    (Block("Pyramid", [[0, 1, 2, 3, 4]], np.zeros((5, 3))), "topology 'Pyramid'"),
    (Block("Triangle", [[0, 1, 2]], np.zeros((3, 3)), {"area": [1.0, 2.0]}), "area has shape (2,)"),
])
def test_bad_block_raises_on_every_rank(tmp_path, block, words):
    def body(comm):
        w = SnapshotWriter(tmp_path, comm=comm)
        w.write(1, 0.0, **particles(1, [0, 1] if comm.rank == 0 else [2]), blocks={"b": block})

    _, errors = run_ranks(2, body)
    for exc in errors:
        assert isinstance(exc, SnapshotError) and words in str(exc) and "\n" not in str(exc)


def test_rank0_fields_in_gid_order(tmp_path):
    def body(comm):
        w = SnapshotWriter(tmp_path, comm=comm)
        gids = [5, 1, 3] if comm.rank == 0 else [4, 0, 2, 6]
        w.write(1, 0.0, **particles(1, gids), rank0_fields={"fragment_id": np.arange(7) // 2})

    _, errors = run_ranks(2, body)
    assert errors == [None, None]
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        g = f["step_000000000001"]
        np.testing.assert_array_equal(g["fragment_id"][()], [0, 0, 1, 1, 2, 2, 3])
        assert "fragment_id" in g.attrs["fields"]


# ---------------------------------------------------------------------------- a simulation's snapshots
RUN_STEPS = (0, 1000, 2000)


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    """`factories.snapshot_scene` run serially, snapshots with the contact network at RUN_STEPS:
    (directory, simulation at the last step)."""
    from factories import snapshot_scene

    from pdem.driver.snapshots import open_snapshots, write_snapshot
    from pdem.parallel.comm import SerialComm

    d = tmp_path_factory.mktemp("scene_run")
    sim = snapshot_scene().build(comm=SerialComm())
    snaps = open_snapshots(d, sim.comm, {"snapshot_every": 1000, "snapshot_contacts": True})
    write_snapshot(snaps, sim)
    for a, b in zip(RUN_STEPS[:-1], RUN_STEPS[1:]):
        sim.run(b - a)
        write_snapshot(snaps, sim)
    return d, sim


def last_group(d):
    f = h5py.File(d / "snapshots.h5", "r")
    return f, f[sorted(f)[-1]]


def test_meshio_reads_the_last_step_of_a_run(scene_run):
    """The last step read with meshio: its point count, positions and every field are those of the
    HDF5 file and of the simulation's bodies (by gid); the boxes' and walls' files too."""
    meshio = pytest.importorskip("meshio", reason="meshio is an optional test dependency")
    d, sim = scene_run
    bodies = sim.bodies()
    f, g = last_group(d)
    with f, meshio.xdmf.TimeSeriesReader(str(d / "snapshots.xmf")) as reader:
        reader.read_points_cells()
        assert reader.num_steps == len(RUN_STEPS)
        t, point_data, _ = reader.read_data(reader.num_steps - 1)
        assert t == sim.time == g.attrs["time"]
        assert len(point_data["position"]) == g.attrs["n_particles"] == len(bodies["gid"])
        for name in ["position", "radius", "velocity", "gid", *json.loads(g.attrs["fields"])]:
            np.testing.assert_array_equal(point_data[name], g[name][()], err_msg=name)
        for name, column in (("position", "pos"), ("velocity", "vel"), ("angvel", "angvel"), ("force", "force"),
                             ("radius", "radius"), ("gid", "gid"), ("clump_id", "clump")):
            np.testing.assert_array_equal(point_data[name], bodies[column], err_msg=name)
        for block in ("walls", "facets", "boxes", "contacts"):
            with meshio.xdmf.TimeSeriesReader(str(d / f"snapshots_{block}.xmf")) as r:
                r.read_points_cells()
                _, pd, cd = r.read_data(r.num_steps - 1)
            points = g["position"] if block == "contacts" else g[block]["points"]
            np.testing.assert_array_equal(pd["position"], points[()])
            for name in json.loads(g[block].attrs["fields"]):
                np.testing.assert_array_equal(cd[name][0], g[block][name][()], err_msg=f"{block}/{name}")


def test_body_kinds_clumps_and_fragments(scene_run):
    """body_kind from how the scene was built (one fixed sphere, 60 rigid clumps of 8, 6 bonded
    grains of 32); fragment_id: one per rigid clump (its smallest member gid), the fixed sphere
    its own, and the fragments' sizes those of `pdem.bodies.fragments.fragments`."""
    from factories import SNAPSHOT_FIXED_GID

    from pdem.bodies.fragments import fragments

    d, sim = scene_run
    f, g = last_group(d)
    with f:
        gid, kind, clump, frag = (g[k][()] for k in ("gid", "body_kind", "clump_id", "fragment_id"))
    rigid = np.isin(gid, sim.clumps.mgid)
    assert kind[gid == SNAPSHOT_FIXED_GID].tolist() == [1] and clump[gid == SNAPSHOT_FIXED_GID].tolist() == [-1]
    assert np.all(kind[rigid] == 2) and rigid.sum() == 60 * 8
    assert np.all(kind[~rigid & (clump >= 0)] == 3) and (~rigid & (clump >= 0)).sum() == 6 * 32
    assert np.bincount(kind).tolist() == [0, 1, 480, 192]
    for c in np.unique(clump[rigid]):
        members = clump == c
        assert np.all(frag[members] == gid[members].min())
    assert frag[gid == SNAPSHOT_FIXED_GID].tolist() == [SNAPSHOT_FIXED_GID]
    ids, sizes = np.unique(frag, return_counts=True)
    assert np.all(np.isin(ids, gid)) and np.all(frag <= gid)
    expected = fragments(sim)["n_members"]
    assert sizes.tolist() == expected.tolist() and len(ids) > 61 + 6, "no bonded grain broke"


def quaternion_matrix(w, x, y, z):
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_boxes_walls_and_facets_drawn_where_they_are(scene_run):
    """The turned box: a hexahedron of positive volume (VTK's corner order) centred on the box,
    its edges along the columns of its orientation's matrix with the box's lengths; each wall a
    quadrilateral in its plane over every sphere centre; the facet its triangle."""
    d, sim = scene_run
    bx = sim.boxes
    f, g = last_group(d)
    with f:
        corners = g["boxes/points"][()].reshape(-1, 8, 3)
        quads = g["walls/points"][()].reshape(-1, 4, 3)
        tri = g["facets/points"][()]
        pos = g["position"][()]
    R = quaternion_matrix(*bx.ori[0])
    assert np.degrees(np.arccos(min(1.0, R[0, 0]))) > 0.5, "the box must have turned"
    c = corners[0]
    np.testing.assert_allclose(c.mean(axis=0), bx.center[0], atol=1e-12)
    for k, (a, b) in enumerate(((0, 1), (0, 3), (0, 4))):
        np.testing.assert_allclose(c[b] - c[a], 2 * bx.half[0, k] * R[:, k], atol=1e-12)
    assert np.dot(np.cross(c[1] - c[0], c[3] - c[0]), c[4] - c[0]) > 0
    for k in range(len(sim.walls)):
        a = int(sim.walls.axis[k])
        q = quads[k]
        assert np.all(q[:, a] == sim.walls.position[k])
        others = [i for i in range(3) if i != a]
        assert np.all(pos[:, others] > q[:, others].min(axis=0)) and np.all(pos[:, others] < q[:, others].max(axis=0))
    np.testing.assert_array_equal(tri, sim.facets.vertices[0])


def test_forces_obey_newtons_third_law_and_contacts_touch(scene_run):
    """The spheres' forces plus the walls', boxes' and facets' sum to zero (every contact force
    acts on two bodies); every contact line joins two spheres that touched when the last step's
    forces were computed (within their relative motion in that step, |Δv| Δt), unless it is a
    bond (it may hold them apart); its normal force is the contact's."""
    from pdem.driver import observables

    d, sim = scene_run
    f, g = last_group(d)
    with f:
        force, pos, radius, gid, vel = (g[k][()] for k in ("force", "position", "radius", "gid", "velocity"))
        total = force.sum(axis=0) + g["walls/force"][()].sum(axis=0) + g["boxes/force"][()].sum(axis=0)
        rows = g["contacts/connectivity"][()]
        fn = g["contacts/normal_force"][()]
        np.testing.assert_array_equal(gid[rows], np.stack([g["contacts/gid1"][()], g["contacts/gid2"][()]], 1))
    total += observables.facet_force(sim, [0])
    assert np.linalg.norm(total) <= 1e-9 * np.abs(force).sum(), total
    c = sim.contacts("sphere_sphere")
    np.testing.assert_array_equal(gid[rows], np.stack([c["gid1"], c["gid2"]], 1))
    np.testing.assert_array_equal(fn, np.linalg.norm(c["normal_force"], axis=1))
    bond = (c["normal_adhesion"] > 0) | (c["shear_adhesion"] > 0)
    dist = np.linalg.norm(pos[rows[:, 0]] - pos[rows[:, 1]], axis=1)
    moved = np.linalg.norm(vel[rows[:, 0]] - vel[rows[:, 1]], axis=1) * sim.last_dt
    touching = dist <= (radius[rows[:, 0]] + radius[rows[:, 1]] + moved) * (1 + 1e-12)
    assert np.all(touching | bond) and bond.any() and (~bond).sum() > 20, (~bond).sum()


def test_a_scene_file_asks_for_the_contact_network(tmp_path):
    """`pdem run` of a plain scene file: snapshots with walls; the contact network only with
    run.snapshot_contacts = true; no clump or fragment field in a scene without clumps."""
    from factories import TINY_DEPOSITION
    from pdem_cli import run_pdem

    for contacts in (False, True):
        scene = tmp_path / f"scene_{contacts}.toml"
        text = TINY_DEPOSITION.replace("steps = 400", "steps = 1600\nsnapshot_every = 800\n"
                                       f"snapshot_contacts = {str(contacts).lower()}")
        scene.write_text(text)
        out = tmp_path / f"out_{contacts}"
        run_pdem(1, scene, out)
        indexes = {"snapshots.xmf", "snapshots_walls.xmf"} | ({"snapshots_contacts.xmf"} if contacts else set())
        assert {p.name for p in out.glob("*.xmf")} == indexes
        with h5py.File(out / "snapshots.h5", "r") as f:
            assert sorted(f) == ["step_000000000000", "step_000000000800", "step_000000001600"]
            g = f["step_000000001600"]
            assert json.loads(g.attrs["fields"]) == ["angvel", "body_kind", "force"]
            assert np.all(g["body_kind"][()] == 0) and len(g["walls/wall"]) == 5
            if contacts:
                assert len(g["contacts/normal_force"]) > 0 and np.all(g["contacts/normal_force"][()] > 0)
