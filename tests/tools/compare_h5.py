"""Compare the datasets of two HDF5 files (or two run directories) bit for bit.

    python tests/tools/compare_h5.py A B [--skip NAME ...]

A and B are files, or directories: then every ``*.h5`` under A is compared with the file of the
same relative path under B (checkpoints excluded: their layout may change between versions).
Every dataset must exist on both sides with the same shape, dtype and bytes; exit status 0 when
all agree, 1 otherwise (each difference printed on one line). Used to show that a change of the
code changed no result (e.g. ``make run``'s results before and after a refactoring).
``--skip NAME`` leaves out the datasets at or under NAME: e.g. two checkpoints of the same step
written on different rank counts hold the same ``tables/`` but their ``meta`` records the ranks
(``compare_h5.py ckpt_a.h5 ckpt_b.h5 --skip meta``).
"""
import argparse
import sys
from pathlib import Path

import h5py
import numpy as np


def datasets(f):
    out = {}
    f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def compare_files(a, b, skip=()):
    """List of one-line differences between the datasets of files a and b (except ``skip``)."""
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        da, db = datasets(fa), datasets(fb)
    for d in (da, db):
        for k in [k for k in d if any(k == s or k.startswith(s.rstrip("/") + "/") for s in skip)]:
            del d[k]
    bad = [f"{a}: {k} only on one side" for k in sorted(set(da) ^ set(db))]
    for k in sorted(set(da) & set(db)):
        x, y = np.asarray(da[k]), np.asarray(db[k])
        if x.shape != y.shape or x.dtype != y.dtype:
            bad.append(f"{a}: {k}: shape/dtype {x.shape} {x.dtype} vs {y.shape} {y.dtype}")
        elif x.dtype.kind in "biufc" and not np.array_equal(np.ascontiguousarray(x).view(np.uint8),
                                                             np.ascontiguousarray(y).view(np.uint8)):
            diff = np.count_nonzero(x != y) if x.shape else 1
            bad.append(f"{a}: {k}: {diff} entries differ")
        elif x.dtype.kind not in "biufc" and not np.array_equal(x, y):
            bad.append(f"{a}: {k}: differs")
    return bad, len(set(da) & set(db))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--skip", nargs="+", default=[], metavar="NAME", help="datasets (or groups) left out")
    args = ap.parse_args(argv)
    a, b = Path(args.a), Path(args.b)
    pairs = [(a, b)] if a.is_file() else [(p, b / p.relative_to(a)) for p in sorted(a.rglob("*.h5"))
                                          if "checkpoints" not in p.parts]
    bad, n = [], 0
    for x, y in pairs:
        if not y.exists():
            bad.append(f"{y}: missing")
            continue
        d, k = compare_files(x, y, args.skip)
        bad += d
        n += k
    for line in bad:
        print(line)
    print(
        f"{len(pairs)} file(s), {n} dataset(s) compared: "
        f"{'all bit-identical' if not bad else f'{len(bad)} difference(s)'}"
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
