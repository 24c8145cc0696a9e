"""Read LIGGGHTS/LAMMPS text dumps (dump custom / dump local) into Python floats.

Every value is parsed with float(), so numbers printed with %.17g round-trip to the same double.
"""


def read_dump(path):
    """List of snapshots {"step": int, "columns": [names], "rows": [[float, ...], ...]} in file order."""
    snaps = []
    with open(path) as f:
        lines = f.read().split("\n")
    k, n = 0, len(lines)
    while k < n:
        line = lines[k]
        if line.startswith("ITEM: TIMESTEP"):
            step = int(lines[k + 1])
            k += 2
            continue
        if line.startswith("ITEM: NUMBER OF"):
            count = int(lines[k + 1])
            k += 2
            continue
        if line.startswith("ITEM: BOX BOUNDS"):
            k += 4
            continue
        if line.startswith("ITEM: ATOMS") or line.startswith("ITEM: ENTRIES"):
            cols = line.split()[2:]
            rows = [[float(t) for t in lines[k + 1 + r].split()] for r in range(count)]
            snaps.append({"step": step, "columns": cols, "rows": rows})
            k += 1 + count
            continue
        k += 1
    return snaps


def by_id(snap):
    """{atom id: {column: value}} for a dump custom snapshot that has an 'id' column."""
    cols = snap["columns"]
    return {int(r[cols.index("id")]): dict(zip(cols, r)) for r in snap["rows"]}
