"""A short breakable-clump oedometer (`pdem.scenes.oedometer`, every stage, shortened) on 1 and
N ranks: the same bits (SPEC 3).

Run by `make test` under ``mpiexec -n 2`` and ``-n 3`` (serially: the run against a second
serial run, i.e. determinism). Rank 0 runs the scene alone (`SerialComm`), then every rank runs
it together; the load series, the preparation series, the fragment records and the final bodies
and platen must be identical bit for bit (`run_files.run_differences`). Twice: the CI grains
(stress-free bonds), and grains bonded on overlaps held by the pour's tenfold bond strength
(``bond_boost``, scaled on every rank's copy of a bond) and returned mid-pour."""
import pytest
from factories import oedometer_ci_doc, toml_text
from run_files import run_differences

from pdem.parallel.comm import SerialComm
from pdem.scenes import oedometer

SHORT = {"settle_max_time": 0.08, "settle_min_time": 0.02, "vibration_time": 0.01, "load_time": 0.04}


def run_scene(doc, path, out, comm):
    status = oedometer.run(str(path), doc, out, comm, fresh=True)
    assert status == 0


@pytest.mark.parametrize("boost", [False, True])
def test_oedometer_rank_invariance(comm, mpi_tmp_path, boost):
    doc = oedometer_ci_doc(**SHORT)
    if boost:
        doc["oedometer"].update(bond_boost=10.0, bond_boost_time=0.01)
        doc["oedometer"]["clumps"].update(member_spacing=0.0057, stress_free=False)
    doc["simulation"]["slab_axis"] = "x"
    scene = mpi_tmp_path / "scene.toml"
    if comm.rank == 0:
        scene.write_text(toml_text(doc))
        run_scene(doc, scene, mpi_tmp_path / "serial", SerialComm())
    comm.barrier()
    run_scene(doc, scene, mpi_tmp_path / f"ranks{comm.size}", comm)
    comm.barrier()
    bad = run_differences(mpi_tmp_path / "serial", mpi_tmp_path / f"ranks{comm.size}") if comm.rank == 0 else None
    bad = comm.bcast(bad)
    assert bad == [], f"{comm.size} ranks differ from 1: {bad}"
