"""pdem.io.checkpoint: round trip across fake ranks, pruning, damaged files, resume choice."""

import json
import os

import h5py
import numpy as np
import pytest
from io_fakecomm import SerialComm, run_ranks

from pdem.io.checkpoint import (
    CheckpointError,
    checkpoint_name,
    find_resume_checkpoint,
    list_checkpoints,
    read_checkpoint,
    write_checkpoint,
)

KEYS = {"particles": ["gid"], "contacts/sphere_sphere": ["gid_i", "gid_j"], "walls": ["wid"]}


def particle_rows(gids):
    gids = np.asarray(gids, dtype=np.int64)
    return {
        "gid": gids,
        "pos": np.stack([gids * 0.1, gids * 0.2 + 1e-17, -gids / 3.0], axis=1),
        "radius": 0.01 + gids * 1e-4,
        "fixed": gids % 2 == 0,
    }


def contact_rows(pairs):
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return {
        "gid_i": pairs[:, 0].copy(),
        "gid_j": pairs[:, 1].copy(),
        "history": np.stack([pairs[:, 0] * 1.5, pairs[:, 1] / 7.0, pairs.sum(1) * 1e-9], axis=1),
    }


def meta(step=100):
    rng = np.random.default_rng(42)
    return {
        "step": step,
        "time": 0.1 + 0.2,  # not exactly representable: must come back bit for bit
        "dt": 2.3e-6,
        "keys": KEYS,
        "rng": rng.bit_generator.state,  # 128-bit integers inside
        "scene": {"name": "oedometer", "n": np.int64(7)},
    }


def serial_tables():
    return {
        "particles": particle_rows([3, 1, 2, 0]),
        "contacts/sphere_sphere": contact_rows([(2, 3), (0, 1)]),
        "walls": {"wid": np.array([0, 1]), "pos": np.zeros((2, 3)), "force": np.ones((2, 3))},
    }


def test_round_trip_two_ranks_sorted_and_deduplicated(tmp_path):
    def rank_body(comm):
        if comm.rank == 0:
            tables = {
                "particles": particle_rows([5, 1, 3]),
                # (1, 4) crosses the slab boundary: both ranks hold an identical copy
                "contacts/sphere_sphere": contact_rows([(3, 5), (1, 4), (1, 3)]),
                "walls": {"wid": np.array([1, 0]), "pos": np.zeros((2, 3)), "force": np.ones((2, 3))},
                "contacts/sphere_wall": {"gid": np.array([5, 0]), "wid": np.array([1, 0]),
                                         "history": np.ones((2, 2))},
            }
        else:
            tables = {
                "particles": particle_rows([4, 0, 2]),
                "contacts/sphere_sphere": contact_rows([(1, 4), (0, 2), (2, 4)]),
                "walls": {"wid": np.array([0, 1]), "pos": np.zeros((2, 3)), "force": np.ones((2, 3))},
                "contacts/sphere_wall": {"gid": np.zeros(0, np.int64), "wid": np.zeros(0, np.int64),
                                         "history": np.zeros((0, 2))},  # none on this rank
            }
        keys = {**KEYS, "contacts/sphere_wall": ["gid", "wid"]}
        return write_checkpoint(tmp_path, 100, tables, {**meta(), "keys": keys}, comm)

    results, errors = run_ranks(2, rank_body)
    assert errors == [None, None]
    assert results[0] == results[1] == tmp_path / "ckpt_000000000100.h5"

    tables, m = read_checkpoint(results[0])
    p = tables["particles"]
    np.testing.assert_array_equal(p["gid"], np.arange(6))
    for col, expected in particle_rows(np.arange(6)).items():
        np.testing.assert_array_equal(p[col], expected)
        assert p[col].dtype == expected.dtype
    c = tables["contacts/sphere_sphere"]
    pairs = [(0, 2), (1, 3), (1, 4), (2, 4), (3, 5)]
    assert list(zip(c["gid_i"], c["gid_j"])) == pairs
    np.testing.assert_array_equal(c["history"], contact_rows(pairs)["history"])
    np.testing.assert_array_equal(tables["walls"]["wid"], [0, 1])
    np.testing.assert_array_equal(tables["contacts/sphere_wall"]["gid"], [0, 5])
    assert m["time"] == 0.1 + 0.2 and m["dt"] == 2.3e-6 and m["step"] == 100
    assert m["rng"] == json.loads(json.dumps(np.random.default_rng(42).bit_generator.state))
    assert m["keys"]["particles"] == ["gid"] and m["scene"]["n"] == 7


def test_conflicting_duplicates_raise_on_every_rank(tmp_path):
    def rank_body(comm):
        rows = contact_rows([(1, 4)])
        if comm.rank == 1:
            rows["history"][0, 0] += 1e-12  # the copies disagree: a bug upstream
        tables = {"particles": particle_rows([comm.rank]), "contacts/sphere_sphere": rows,
                  "walls": {"wid": np.array([0])}}
        return write_checkpoint(tmp_path, 7, tables, meta(7), comm)

    _, errors = run_ranks(2, rank_body)
    for exc in errors:
        assert isinstance(exc, CheckpointError)
        assert "gid_i=1, gid_j=4" in str(exc) and "history" in str(exc)
        assert str(exc).startswith("ckpt_000000000007.h5: ") and "\n" not in str(exc)
    assert list_checkpoints(tmp_path) == []
    assert list(tmp_path.iterdir()) == []


def test_tables_that_differ_between_ranks_raise_everywhere(tmp_path):
    def rank_body(comm):
        tables = {"particles": particle_rows([comm.rank])}
        if comm.rank == 1:
            tables["particles"]["pos"] = tables["particles"]["pos"].astype(np.float32)
        return write_checkpoint(tmp_path, 1, tables, {"keys": KEYS}, comm)

    _, errors = run_ranks(2, rank_body)
    assert all(isinstance(e, CheckpointError) and "differ" in str(e) for e in errors)


@pytest.mark.parametrize("bad, message", [
    (lambda t: t["particles"].update(radius=np.ones(3)), "column radius has 3 rows, other columns have 4"),
    (lambda t: t.update(bonds={"gid": np.arange(2)}), "table bonds: no key columns"),
    (lambda t: t["particles"].update(gid=np.arange(4.0)), "key column gid must be a 1-D integer array"),
])
def test_invalid_tables_are_refused(tmp_path, bad, message):
    tables = serial_tables()
    bad(tables)
    with pytest.raises(CheckpointError, match=message):
        write_checkpoint(tmp_path, 1, tables, meta(1), SerialComm())


def test_readable_with_plain_h5py_and_empty_tables(tmp_path):
    tables = serial_tables()
    tables["contacts/sphere_wall"] = {"gid": np.zeros(0, np.int64), "wid": np.zeros(0, np.int64),
                                     "history": np.zeros((0, 4))}
    keys = {**KEYS, "contacts/sphere_wall": ["gid", "wid"]}
    path = write_checkpoint(tmp_path, 5, tables, {**meta(5), "keys": keys}, SerialComm())
    with h5py.File(path, "r") as f:
        assert f.attrs["schema"] == b"pdem-checkpoint" and f.attrs["complete"] == 1
        assert f.attrs["step"] == 5 and f.attrs["time"] == 0.1 + 0.2
        assert json.loads(f["meta"][()].tobytes())["keys"]["particles"] == ["gid"]
        np.testing.assert_array_equal(f["tables/particles/gid"][()], [0, 1, 2, 3])
        assert f["tables/contacts/sphere_wall/history"].shape == (0, 4)
        assert json.loads(f["tables/contacts/sphere_sphere"].attrs["keys"]) == ["gid_i", "gid_j"]
    back, _ = read_checkpoint(path)
    assert back["contacts/sphere_wall"]["history"].shape == (0, 4)


def test_keep_prunes_old_and_abandoned_checkpoints(tmp_path):
    comm = SerialComm()
    for step in (10, 20, 30, 40, 50, 60):
        write_checkpoint(tmp_path, step, serial_tables(), meta(step), comm, keep=3)
    assert [s for s, _ in list_checkpoints(tmp_path)] == [40, 50, 60]
    # a leftover temp file of a killed writer goes with the next successful write
    (tmp_path / "ckpt_000000000070.h5.tmp").write_bytes(b"partial")
    # restarting from 50 and checkpointing at 55 abandons 60
    write_checkpoint(tmp_path, 55, serial_tables(), meta(55), comm, keep=3)
    assert sorted(p.name for p in tmp_path.iterdir()) == [checkpoint_name(s) for s in (40, 50, 55)]
    write_checkpoint(tmp_path, 65, serial_tables(), meta(65), comm, keep=None)
    assert [s for s, _ in list_checkpoints(tmp_path)] == [40, 50, 55, 65]


def flip_byte(path, dataset, index=5):
    with h5py.File(path, "r") as f:
        offset = f[dataset].id.get_offset()
    with open(path, "r+b") as fh:
        fh.seek(offset + index)
        byte = fh.read(1)
        fh.seek(offset + index)
        fh.write(bytes([byte[0] ^ 0x01]))


def write_three(tmp_path):
    return [write_checkpoint(tmp_path, s, serial_tables(), meta(s), SerialComm()) for s in (100, 200, 300)]


def test_edited_byte_is_refused(tmp_path):
    path = write_three(tmp_path)[-1]
    flip_byte(path, "tables/particles/pos")
    with pytest.raises(CheckpointError) as info:
        read_checkpoint(path)
    assert str(info.value) == "ckpt_000000000300.h5: dataset particles/pos checksum mismatch"


def test_truncated_file_is_refused(tmp_path):
    path = write_three(tmp_path)[-1]
    os.truncate(path, path.stat().st_size // 2)
    with pytest.raises(CheckpointError) as info:
        read_checkpoint(path)
    msg = str(info.value)
    assert msg.startswith("ckpt_000000000300.h5: cannot open as HDF5") and "truncated" in msg
    assert "\n" not in msg


def test_incomplete_wrong_schema_and_row_count_are_refused(tmp_path):
    a, b, c = write_three(tmp_path)
    with h5py.File(a, "r+") as f:
        del f.attrs["complete"]
    with h5py.File(b, "r+") as f:
        f.attrs["schema"] = "someone-else"
    with h5py.File(c, "r+") as f:
        f["tables/particles"].attrs["n_rows"] = 3
    messages = []
    for path in (a, b, c):
        with pytest.raises(CheckpointError) as info:
            read_checkpoint(path)
        messages.append(str(info.value))
    assert messages == [
        "ckpt_000000000100.h5: incomplete (attribute complete is not 1)",
        "ckpt_000000000200.h5: schema is 'someone-else', expected 'pdem-checkpoint'",
        "ckpt_000000000300.h5: dataset particles/fixed has shape (4,), table has 3 rows",
    ]
    with pytest.raises(CheckpointError, match="ckpt_000000000400.h5: file does not exist"):
        read_checkpoint(tmp_path / "ckpt_000000000400.h5")


def test_find_resume_falls_back_to_previous(tmp_path):
    assert find_resume_checkpoint(tmp_path / "missing") is None
    paths = write_three(tmp_path)
    assert find_resume_checkpoint(tmp_path, log=pytest.fail) == paths[-1]
    flip_byte(paths[-1], "tables/contacts/sphere_sphere/history")
    lines = []
    assert find_resume_checkpoint(tmp_path, log=lines.append) == paths[1]
    assert lines == ["checkpoint ckpt_000000000300.h5 is damaged (dataset contacts/sphere_sphere/history "
                     "checksum mismatch); resuming from ckpt_000000000200.h5"]
    # with a comm: rank 0 decides, all ranks get the answer
    results, errors = run_ranks(2, lambda comm: find_resume_checkpoint(tmp_path, log=lambda s: None, comm=comm))
    assert errors == [None, None] and results == [paths[1], paths[1]]
    for p in paths[:2]:
        os.truncate(p, 100)
    lines.clear()
    assert find_resume_checkpoint(tmp_path, log=lines.append) is None
    assert len(lines) == 3 and all("no valid checkpoint" in line for line in lines)


def test_bit_flips_anywhere_are_refused_or_harmless(tmp_path):
    """Flip one bit at many offsets (metadata included): never a wrong answer, never a hang."""
    path = write_checkpoint(tmp_path, 1, serial_tables(), meta(1), SerialComm())
    ref_tables, ref_meta = read_checkpoint(path)
    data = path.read_bytes()
    bad = tmp_path / "flipped.h5"
    refused = 0
    for offset in range(0, len(data), 23):
        flipped = bytearray(data)
        flipped[offset] ^= 0x10
        bad.write_bytes(flipped)
        try:
            tables, m = read_checkpoint(bad)
        except CheckpointError as exc:
            assert "\n" not in str(exc)
            refused += 1
            continue
        assert m == ref_meta, offset
        for t, cols in ref_tables.items():
            for c, a in cols.items():
                assert tables[t][c].dtype == a.dtype and tables[t][c].tobytes() == a.tobytes(), (offset, t, c)
    assert refused > len(data) // 23 // 2
